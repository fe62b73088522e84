"""A numpy re-implementation of kollagen's data generator, bit-exact with its C++.

The public entry point is :func:`generate`, which turns a :class:`~generator.config.SynthConfig` into
a planar :class:`~studio.core.model.PoseGraph` and the few extras kollagen's single g2o file needs.

The walk is :mod:`studio.generator.walk`, the loop-closure search :mod:`studio.generator.loop_closures`;
this module runs them in kollagen's order (agents, alignment, pairs), holds kollagen's seed rule and
exact odometry information, and defines kollagen's single-g2o view, the seam's extra
(:class:`SingleG2oView`), which :data:`studio.generator.extended.STUDIO` offers for planar walks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.units import NS_PER_S
from studio.generator.config import AgentConfig, SynthConfig
from studio.generator.loop_closures import (
    _cos_sin,
    _diag_information,
    _grid_cells,
    _InterPairs,
    _intra_loop_closures,
    agent_pairs,
    discrete_circle,
)
from studio.generator.rng import MT19937Stream
from studio.generator.walk import _dead_reckon, _random_walk, _round_to_int, _Walk
from studio.runtime.parallel import parallel_map
from studio.runtime.progress import Progress, report

__all__ = [
    "SingleG2oView",
    "SynthOutput",
    "generate",
    "effective_seeds",
    "discrete_circle",
    "agent_pairs",
]


@dataclass(frozen=True, eq=False)
class SynthOutput:
    """What kollagen's generator produces."""

    graph: PoseGraph
    """Planar graph: per agent ground truth, dead reckoning, odometry (estimated information) and
    intra-agent loop closures; inter-agent loop closures in kollagen's order."""
    exact_odometry_information: tuple[np.ndarray, ...] | None
    """Per agent ``(n-1, 6)`` derived odometry information, when the config asks for it (kollagen
    writes it to the single g2o file only)."""
    connector_information: np.ndarray
    """``(6,)`` information of the edges that chain agents together in the single g2o file."""
    seeds: tuple[int, ...]
    """The agents' seeds after kollagen's replacement of duplicates."""


# --------------------------------------------------------------------------------------------------
# Small kollagen semantics


def _libstdcxx_reduce(values: np.ndarray) -> float:
    """``std::reduce(first, last)`` as libstdc++ evaluates it for random-access iterators: the
    running sum takes ``(v[k] + v[k+1]) + (v[k+2] + v[k+3])`` per block of four, then the rest one
    by one. The blocks' sums are elementwise (numpy rounds each as C does) and ``add.accumulate``
    adds them strictly in order, so the bits are libstdc++'s."""
    v = np.asarray(values, dtype=np.float64)
    n4 = len(v) - len(v) % 4
    blocks = (v[0:n4:4] + v[1:n4:4]) + (v[2:n4:4] + v[3:n4:4])
    init = float(np.add.accumulate(np.concatenate([[0.0], blocks]))[-1])
    for x in v[n4:].tolist():
        init = init + x
    return init


def effective_seeds(seeds: list[int]) -> tuple[int, ...]:
    """kollagen's ``add_walker`` seed rule, quirk included.

    A seed already used is replaced by the largest seed so far plus one. kollagen's list of used seeds
    starts with one zero per existing agent (its vector is sized, then appended to), so seed 0 counts
    as used from the second agent on. The seed is a C++ ``int``, so ``INT_MAX + 1`` wraps around.
    """
    used: list[int] = []
    out = []
    for k, seed in enumerate(seeds):
        pool = [0] * k + used
        if k > 0 and seed in pool:
            seed = (max(pool) + 1 + 2**31) % 2**32 - 2**31  # C++ int: INT_MAX + 1 wraps to INT_MIN
        used.append(seed)
        out.append(seed)
    return tuple(out)


def _exact_odometry_information(walk: _Walk, cfg: SynthConfig, agent: AgentConfig) -> np.ndarray:
    """kollagen's ``set_information_matrix`` (see its doc/information-matrix-derivation.pdf)."""
    d = cfg.stepsize / cfg.step_fragment
    sd = agent.std_dev_position
    st = agent.std_dev_angle
    d2 = math.pow(d, 2)
    sd2 = math.pow(sd, 2)
    st2 = math.pow(st, 2)
    e1 = (d2 + sd2) / 2.0 * (1 - math.exp(-2 * st2))
    e2 = (d2 + sd2) / 2.0 * (1 + math.exp(-2 * st2)) - d2 * math.exp(-st2)
    a = e1 * st2 - d2 * math.pow(st, 4) * math.exp(-st2)
    c = d * st2 * math.exp(-0.5 * st2)
    rows = {}
    for dt in (-1, 0, 1, 2):
        if dt in (0, 2):
            i23 = c / a
            rows[dt] = (1.0 / e2, 0.0, 0.0, st2 / a, -i23 if dt == 0 else i23, e1 / a)
        else:
            i13 = c / a
            rows[dt] = (st2 / a, 0.0, -i13 if dt == -1 else i13, 1.0 / e2, 0.0, e1 / a)
    table = np.array([rows[k] for k in (-1, 0, 1, 2)])
    per_edge: np.ndarray = table[walk.delta_theta + 1]
    return per_edge


# --------------------------------------------------------------------------------------------------


def generate(cfg: SynthConfig, *, jobs: int | None = None, progress: Progress | None = None) -> SynthOutput:
    """Run kollagen's generator: walk, intra-agent loop closures, alignment, inter-agent loop closures.

    ``jobs`` processes share the agents' and the agent pairs' loop closures (default: the cores other
    work leaves idle, see :func:`studio.runtime.parallel.default_jobs`); the output does not depend on it.
    """
    seeds = effective_seeds([a.random_number_generator_seed for a in cfg.agents])
    # the walks first (a tenth of the time; in a team every process makes them), so that one parallel
    # step takes both the agents' intra-agent loop closures and the pairs' inter-agent ones: no
    # second step to wait for, and no process idle while the last agents finish
    streams = [MT19937Stream(seed) for seed in seeds]
    walks = [_random_walk(stream, cfg, agent) for stream, agent in zip(streams, cfg.agents)]
    aligned, shifts = _align(walks) if cfg.align else (walks, [(0, 0)] * len(walks))
    cells = [_grid_cells(w.x, w.y, cfg) for w in aligned]
    pairs = _InterPairs(aligned, cells, cfg) if len(walks) > 1 else None
    n_agents, n_pairs = len(walks), len(pairs) if pairs is not None else 0

    def task(i: int) -> tuple[Any, ...]:
        if i < n_agents:  # the agents' streams go on from where their walks left them
            lcs = _intra_loop_closures(streams[i], walks[i], cfg, cfg.agents[i])
            return lcs, _odometry_measurements(aligned[i]), _initial_estimate(walks[i], shifts[i])
        assert pairs is not None
        return pairs(i - n_agents)

    def on_done(done: int, _total: int) -> None:
        if done <= n_agents:
            report(progress, "synth: walks and intra-agent loop closures", done, n_agents, "agents")
        if done >= n_agents and n_pairs:
            report(progress, "synth: inter-agent loop closures", done - n_agents, n_pairs, "pairs")

    try:
        done = parallel_map(task, n_agents + n_pairs, jobs, on_done=on_done)
    finally:  # every draw is made: the generators go back for the next dataset
        for stream in streams:
            stream.release()
        if pairs is not None:
            pairs.release()
    per_agent = done[:n_agents]  # (intra-agent loop closures, odometry measurements, initial estimate)
    inter = pairs.edges(done[n_agents:]) if pairs is not None else InterAgentEdges.empty(PoseKind.SE2)
    walks = aligned

    agents = []
    exact = []
    for idx, (walk, agent, (lcs, odo, initial)) in enumerate(zip(walks, cfg.agents, per_agent)):
        n = len(walk.x)
        odometry = Edges(
            PoseKind.SE2,
            np.arange(n - 1),
            np.arange(1, n),
            odo.reshape(-1, 3),
            _diag_information(n - 1, agent.estimated_information_position, agent.estimated_information_angle),
        )
        agents.append(
            AgentGraph(
                name=f"agent{idx + 1}",
                kind=PoseKind.SE2,
                stamps_ns=np.arange(n, dtype=np.int64) * NS_PER_S,
                initial=initial,
                ground_truth=_rows(walk.x, walk.y, walk.theta),
                odometry=odometry,
                loop_closures=lcs,
            )
        )
        if cfg.exact_information_matrix:
            exact.append(_exact_odometry_information(walk, cfg, agent))

    graph = PoseGraph(PoseKind.SE2, tuple(agents), inter, {"generator": "kollagen", "name": cfg.name})
    p = cfg.inter
    connector = np.array(
        [
            p.estimated_information_position,
            0.0,
            0.0,
            p.estimated_information_position,
            0.0,
            p.estimated_information_angle,
        ]
    )
    return SynthOutput(graph, tuple(exact) if cfg.exact_information_matrix else None, connector, seeds)


def _rows(x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``(n, 3)`` rows ``(x, y, theta)`` (``np.column_stack`` without its per-call conversions)."""
    out = np.empty((len(x), 3))
    out[:, 0], out[:, 1], out[:, 2] = x, y, theta
    return out


def _odometry_measurements(walk: _Walk) -> np.ndarray:
    """``(n - 1, 3)`` odometry edges (dx, dy, dtheta) of a walk: its noisy step along its noisy turn."""
    c, s = _cos_sin(walk.odom_ang)
    return _rows(walk.odom_pos * c, walk.odom_pos * s, walk.odom_ang)


def _initial_estimate(walk: _Walk, shift: tuple[int, int]) -> np.ndarray:
    """``(n, 3)`` dead reckoning of a walk (before alignment), moved by its alignment shift."""
    x, y, theta = _dead_reckon(walk.odom_pos, walk.odom_ang)
    sx, sy = shift
    if sx != 0 or sy != 0:
        x, y = x + sx, y + sy
    return _rows(x, y, theta)


def _align(walks: list[_Walk]) -> tuple[list[_Walk], list[tuple[int, int]]]:
    """kollagen's ``align_center_of_masses``: integer shifts (in metres) towards agent 1's centre;
    the moved walks and each one's shift (the dead reckoning, made later, moves by it too)."""

    def centre(w: _Walk) -> tuple[int, int]:
        n = len(w.x)
        return _round_to_int(_libstdcxx_reduce(w.x) / n), _round_to_int(_libstdcxx_reduce(w.y) / n)

    centres = [centre(w) for w in walks]
    x0, y0 = centres[0]
    out, shifts = [], []
    for w, (xc, yc) in zip(walks, centres):
        sx, sy = x0 - xc, y0 - yc
        shifts.append((sx, sy))
        if sx == 0 and sy == 0:
            out.append(w)
            continue
        out.append(_Walk(w.x + sx, w.y + sy, w.theta, w.delta_theta, w.odom_pos, w.odom_ang))
    return out, shifts


@dataclass(frozen=True, eq=False)
class SingleG2oView:
    """kollagen's extra: the single g2o file and its two TUM files, in ``OUT/<name>_singleg2o``."""

    connector_information: np.ndarray
    """``(6,)`` information of the edges that chain agents together."""
    exact_odometry_information: tuple[np.ndarray, ...] | None
    """Per agent ``(n-1, 6)`` derived odometry information, or None."""
    suffix: str = "_singleg2o"
