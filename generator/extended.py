"""The studio's modes beside kollagen's: the ``"studio"`` block applied (no I/O).

* ``walk: kollagen`` (default): kollagen's graph, byte-exact, then, per class whose noise model is not
  Gaussian, the measurements re-drawn around the ground truth with that model (kollagen's walk and
  loop-closure choices are kept: only the noise changes; a numpy stream per agent and class); then
  ``information_frame: measurement`` rotates kollagen's Exact odometry information into g2o's error
  frame; then outliers.
* ``walk: grid3d``: :mod:`studio.generator.grid3d`, then outliers.

The walks are the entries of :data:`WALK_MODES` (the generator modes' registry).

Re-drawn planar noise follows kollagen's measurement models: odometry ``l^ = l + s_p n1``,
``dtheta^ = dtheta + s_a n2`` written as ``(l^ cos dtheta^, l^ sin dtheta^, dtheta^)`` and dead
reckoning re-composed from the first ground-truth pose; loop closures ``(dx, dy, dtheta) + (s_p n1,
s_p n2, s_a n3)``; ``n`` unit-variance draws of the class's model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from studio.core.errors import ConfigError
from studio.core.geometry import normalize_angle, relative_planar_pose
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.generator.config import SynthConfig
from studio.generator.extensions import NoiseModel, sample_noise
from studio.generator.grid3d import generate_grid3d
from studio.generator.kollagen import SingleG2oView, SynthOutput, effective_seeds, generate
from studio.generator.outliers import PlantedOutliers, plant_outliers
from studio.generator.seam import GeneratedDataset
from studio.runtime.progress import Progress

__all__ = [
    "StudioOutput",
    "generate_studio",
    "rotate_exact_information",
    "StudioGenerator",
    "STUDIO",
    "WalkMode",
    "WalkTrace",
    "WALK_MODES",
    "walk_mode",
]

_STREAM_ODOMETRY, _STREAM_INTRA, _STREAM_INTER = 31, 32, 33


@dataclass(frozen=True, eq=False)
class StudioOutput:
    output: SynthOutput
    outliers: PlantedOutliers | None


def rotate_exact_information(upper: np.ndarray, theta_z: np.ndarray) -> np.ndarray:
    """``Omega' = D^T Omega D`` with ``D = blkdiag(R(theta_z), 1)`` per row (upper triangles, 6 values).

    kollagen's Exact information is that of ``(dx^, dy^, dtheta^)`` in the ``from`` pose's frame; g2o's
    ``EDGE_SE2`` error ``Z^-1 (X_i^-1 X_j)`` has its translation in the measurement's frame:
    ``e = D^T (truth - Z)``, so ``Cov(e) = D^T Sigma D`` and (D orthogonal) ``Cov(e)^-1 = D^T Omega D``.

    ``theta_z`` is the turn kollagen's table was built for (the true quarter turn). Written out,
    ``e = (l cos n - l^, -l sin n, -n)`` with ``n`` the heading noise: its law does not depend on the
    turn, and kollagen's ``Sigma(theta) = D(theta) Sigma(0) D(theta)^T``, so the rotated information is
    the straight edge's for every turn. Rotating by the *measured* turn instead mis-rotates by ``n``:
    with ``sigma_angle = 0.2`` rad and ``sigma_position = 0.005`` m the chi2 of turning edges came out
    1.28 times its expected value (measured while writing the test).
    """
    from studio.core.geometry import upper_to_matrix

    omega = upper_to_matrix(upper, 3)
    c, s = np.cos(theta_z), np.sin(theta_z)
    d = np.zeros((len(upper), 3, 3))
    d[:, 0, 0], d[:, 0, 1], d[:, 1, 0], d[:, 1, 1], d[:, 2, 2] = c, -s, s, c, 1.0
    rot = np.einsum("nji,njk,nkl->nil", d, omega, d)
    rows, cols = np.triu_indices(3)
    rotated_upper: np.ndarray = rot[:, rows, cols]
    return rotated_upper


def _renoise_planar(graph: PoseGraph, cfg: SynthConfig, seeds: tuple[int, ...]) -> PoseGraph:
    ext = cfg.studio
    assert ext is not None
    odo_m, intra_m, inter_m = (ext.noise_of(c) for c in ("odometry", "intra", "inter"))
    agents = []
    for a, ac, seed in zip(graph.agents, cfg.agents, seeds):
        gt = a.ground_truth
        assert gt is not None
        odo, lc, initial = a.odometry, a.loop_closures, a.initial
        if not odo_m.is_gaussian:
            rng = np.random.default_rng([seed % 2**32, _STREAM_ODOMETRY])
            rx, ry, rt = relative_planar_pose(gt[:-1, 0], gt[:-1, 1], gt[:-1, 2], gt[1:, 0], gt[1:, 1], gt[1:, 2])
            n = sample_noise(odo_m, rng, (len(rx), 2))
            op = np.hypot(rx, ry) + ac.std_dev_position * n[:, 0]
            oa = rt + ac.std_dev_angle * n[:, 1]
            odo = Edges(
                PoseKind.SE2,
                odo.from_index,
                odo.to_index,
                np.column_stack([op * np.cos(oa), op * np.sin(oa), oa]),
                odo.information_upper,
            )
            t = normalize_angle(gt[0, 2] + np.cumsum(oa))
            initial = np.column_stack(
                [
                    gt[0, 0] + np.concatenate([[0.0], np.cumsum(op * np.cos(t))]),
                    gt[0, 1] + np.concatenate([[0.0], np.cumsum(op * np.sin(t))]),
                    np.concatenate([[gt[0, 2]], t]),
                ]
            )
        if not intra_m.is_gaussian and len(lc):
            rng = np.random.default_rng([seed % 2**32, _STREAM_INTRA])
            lc = Edges(
                PoseKind.SE2,
                lc.from_index,
                lc.to_index,
                _planar_lc(
                    gt,
                    gt,
                    lc.from_index,
                    lc.to_index,
                    intra_m,
                    rng,
                    ac.std_dev_intra_loop_closure_position,
                    ac.std_dev_intra_loop_closure_angle,
                ),
                lc.information_upper,
            )
        agents.append(AgentGraph(a.name, a.kind, a.stamps_ns, initial, gt, odo, lc))
    inter = graph.inter
    gts = [a.ground_truth for a in graph.agents]
    if not inter_m.is_gaussian and len(inter):
        rng = np.random.default_rng([cfg.inter.random_number_generator_seed % 2**32, _STREAM_INTER])
        src = np.array([gts[fa][fi] for fa, fi in zip(inter.from_agent.tolist(), inter.from_index.tolist())])
        dst = np.array([gts[ta][ti] for ta, ti in zip(inter.to_agent.tolist(), inter.to_index.tolist())]).reshape(-1, 3)
        idx = np.arange(len(inter))
        meas = _planar_lc(
            src,
            dst,
            idx,
            idx,
            inter_m,
            rng,
            cfg.inter.std_dev_loop_closure_position,
            cfg.inter.std_dev_loop_closure_angle,
        )
        inter = InterAgentEdges(
            PoseKind.SE2,
            inter.from_agent,
            inter.from_index,
            inter.to_agent,
            inter.to_index,
            meas,
            inter.information_upper,
        )
    return PoseGraph(PoseKind.SE2, tuple(agents), inter, dict(graph.metadata))


def _planar_lc(
    gt_from: np.ndarray,
    gt_to: np.ndarray,
    fr: np.ndarray,
    to: np.ndarray,
    model: NoiseModel,
    rng: np.random.Generator,
    sp: float,
    sa: float,
) -> np.ndarray:
    a, b = gt_from[fr], gt_to[to]
    dx, dy, dt = relative_planar_pose(a[:, 0], a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2])
    n = sample_noise(model, rng, (len(fr), 3))
    return np.column_stack([dx + sp * n[:, 0], dy + sp * n[:, 1], dt + sa * n[:, 2]])


@dataclass(frozen=True, eq=False)
class WalkTrace:
    """A walk mode's result: kollagen's output shape, and per agent what the outlier planter needs."""

    output: SynthOutput
    positions: list[np.ndarray]
    """Per agent ``(n, 3)`` true positions [m]."""
    cells: list[np.ndarray]
    """Per agent ``(n, 3)`` integer grid cells, in units of ``stepsize / step_fragment``."""
    headings: list[np.ndarray]
    """Per agent quarter-turn headings ``0..3``."""


class WalkRun(Protocol):
    """Generate ``cfg``'s graph with the walk (``seeds``: the agents' effective seeds)."""

    def __call__(
        self, cfg: SynthConfig, seeds: tuple[int, ...], *, jobs: int | None, progress: Progress | None
    ) -> WalkTrace: ...


@dataclass(frozen=True)
class WalkMode:
    """One generator mode (``"studio": {"walk": NAME}``) as the registry declares it."""

    name: str
    help: str
    """One line for the docs and messages: what the walk is."""
    run: WalkRun
    planar: bool
    """A planar (SE(2)) graph: kollagen's single-g2o view and Exact information apply to it."""
    block: str | None = None
    """Key of the mode's own options in the ``"studio"`` block (parsed by ``studio/io/studio_block.py``)."""


def _kollagen_walk(
    cfg: SynthConfig, seeds: tuple[int, ...], *, jobs: int | None, progress: Progress | None
) -> WalkTrace:
    """kollagen's walk, its noise re-drawn per non-Gaussian class, its Exact information rotated."""
    ext = cfg.studio
    assert ext is not None
    F = cfg.step_fragment
    out = generate(cfg, jobs=jobs, progress=progress)
    graph = out.graph
    if any(not ext.noise_of(c).is_gaussian for c in ("odometry", "intra", "inter")):
        graph = _renoise_planar(graph, cfg, seeds)
    exact = out.exact_odometry_information
    if exact is not None and ext.information_frame == "measurement":
        # the planned (true) turn: kollagen's table is indexed by it, and the error's law in the
        # measurement frame does not depend on it (see rotate_exact_information)
        truths = [a.ground_truth for a in graph.agents]
        assert all(t is not None for t in truths)  # kollagen's agents always have ground truth
        exact = tuple(
            rotate_exact_information(e, normalize_angle(t[1:, 2] - t[:-1, 2]))  # type: ignore[index]
            for e, t in zip(exact, truths)
        )
    out = SynthOutput(graph, exact, out.connector_information, out.seeds)
    gts = [a.ground_truth for a in graph.agents]
    positions = [np.column_stack([g[:, 0], g[:, 1], np.zeros(len(g))]) for g in gts]  # type: ignore[index, arg-type]
    cells = [
        np.column_stack([np.rint(p[:, 0:2] * F / cfg.stepsize), np.zeros(len(p))]).astype(np.int64) for p in positions
    ]
    headings = [np.rint(g[:, 2] / (math.pi / 2)).astype(np.int64) % 4 for g in gts]  # type: ignore[index]
    return WalkTrace(out, positions, cells, headings)


def _grid3d_walk(cfg: SynthConfig, seeds: tuple[int, ...], *, jobs: int | None, progress: Progress | None) -> WalkTrace:
    graph, walks = generate_grid3d(cfg, seeds)
    return WalkTrace(
        SynthOutput(graph, None, np.zeros(6), seeds),
        [w.poses[:, 0:3] for w in walks],
        [w.cells for w in walks],
        [w.heading for w in walks],
    )


#: The generator modes: the walks a config's ``"studio"`` block may name. A new mode is one module
#: (its walk, pure numpy) and one entry here; options of its own also go into ``studio_block.py``.
WALK_MODES: dict[str, WalkMode] = {
    mode.name: mode
    for mode in (
        WalkMode("kollagen", "kollagen's planar grid walk (byte-exact), noise models re-drawn", _kollagen_walk, True),
        WalkMode(
            "grid3d", "kollagen's turns plus climbing and descending steps, in SE(3)", _grid3d_walk, False, "grid3d"
        ),
    )
}


def walk_mode(name: str) -> WalkMode:
    try:
        return WALK_MODES[name]
    except KeyError:
        raise ConfigError(f"walk: unknown walk {name!r} (known: {', '.join(WALK_MODES)})") from None


def generate_studio(cfg: SynthConfig, *, jobs: int | None = None, progress: Progress | None = None) -> StudioOutput:
    """Generate ``cfg`` with its ``"studio"`` block (kollagen's :func:`generate` when there is none)."""
    ext = cfg.studio
    if ext is None or not ext.changes_kollagen_bytes:
        return StudioOutput(generate(cfg, jobs=jobs, progress=progress), None)
    seeds = effective_seeds([a.random_number_generator_seed for a in cfg.agents])
    trace = walk_mode(ext.walk).run(cfg, seeds, jobs=jobs, progress=progress)
    out = trace.output
    planted = None
    if ext.outliers is not None:
        planted = plant_outliers(
            out.graph, trace.positions, trace.cells, trace.headings, cfg.step_fragment, ext.outliers
        )
        out = SynthOutput(planted.graph, out.exact_odometry_information, out.connector_information, out.seeds)
    return StudioOutput(out, planted)


class StudioGenerator:
    """kollagen's generator and the studio block beyond it, behind the generator seam: kollagen's
    single-g2o view is offered for planar walks (a 3D ``grid3d`` walk has none), and the planted
    outliers travel with the graph."""

    name = "kollagen+studio"

    def extra_suffixes(self, config: SynthConfig) -> tuple[str, ...]:
        planar = config.studio is None or walk_mode(config.studio.walk).planar
        return ("_singleg2o",) if planar else ()

    def generate(
        self, config: SynthConfig, *, jobs: int | None = None, progress: Progress | None = None
    ) -> GeneratedDataset:
        res = generate_studio(config, jobs=jobs, progress=progress)
        out = res.output
        extras = (
            (SingleG2oView(out.connector_information, out.exact_odometry_information),)
            if out.graph.kind is PoseKind.SE2
            else ()
        )
        return GeneratedDataset(out.graph, extras, res.outliers)


#: The studio's default generator (kollagen's bytes when a config has no studio block).
STUDIO = StudioGenerator()
