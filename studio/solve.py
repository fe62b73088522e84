"""``studio solve`` as a library function: optimize a dataset's pose graph with a back-end of
:mod:`studio.solvers` and write the estimate.

DATASET is a multi-g2o folder (synth, convert or anywhere) or a single g2o file (kollagen's single
view, as the kollagen paper's optimizers read it: every agent's vertices with concatenated ids, and
kollagen's connector edges joining agent k's last pose to agent k+1's first).

* A multi-g2o folder is flattened to global ids (agent k's vertices after agents 0..k-1's); vertex 0
  of the first agent is held fixed. The estimate is written as a multi-g2o folder (the dataset's
  edges, the optimized vertices, no ground truth) with one TUM file per agent in ``tum/``.
* A single g2o file is read as ``studio convert g2o`` reads it (:func:`studio.converters.g2o.read_single_g2o`:
  a file of edges only starts from poses composed along a spanning tree of its edges, quaternions
  within 1e-5 of unit length are normalised, ``FIX`` names the pose held fixed, else the first id),
  solved, and the estimate written as ``<stem>.g2o`` with the file's ids, which
  ``studio evaluate DATASET --estimate`` scores directly.
* A 3D dataset whose poses and measurements are all planar (z, roll and pitch zero, as kollagen's
  3D records of its planar walk) is solved in SE(2) (``dimension="auto"``) and written back in 3D;
  its chi2 is the planar one.

``solve.json`` beside the estimate holds the method, options (the shared ones and the method's
own), iterations, chi2 (g2o convention, sum of e^T Omega e) at the dataset's initial values, after
the initial guess and at the end, the wall time and, for ``gnc``, the loop closures it rejected;
for ``dgs`` (one robot per agent of a multi-g2o folder, ``robots`` contiguous runs of ids of a
single g2o) its rounds and bytes in ``notes`` and, with ground truth, ``ape_per_round``. Outputs
are staged and renamed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from studio.core.errors import ConfigError, FormatError, OutputError
from studio.core.geometry import (
    block_diagonal_where_indefinite,
    is_planar_se3,
    planar_poses_to_se3,
    se3_information_to_se2,
    se3_poses_to_planar,
)
from studio.core.model import AgentGraph, PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE as MAX_COORDINATE_M  # the one bound of every number
from studio.io.estimate import SOLVE_JSON
from studio.io.names import safe_file_name, safe_file_names
from studio.io.strict_json import dumps_strict
from studio.solvers import DEFAULT_METHOD, SolveMethod, method_entry
from studio.solvers.problem import (
    Init,
    Iteration,
    Optimizer,
    Problem,
    Solution,
    SolveOptions,
    VertexPriors,
    graph_chi2,
)
from studio.solvers.validate import check_problem, check_solution

__all__ = ["SolveResult", "solve", "load_problem", "graph_problem", "Dimension", "SOLVE_JSON"]

Dimension = Literal["auto", "2d", "3d"]


@dataclass(frozen=True, eq=False)
class Loaded:
    """A dataset read for solving: the problem and what is needed to write the estimate back."""

    problem: Problem
    source_kind: PoseKind
    """The pose kind of the files (the problem may be planar while the files are 3D)."""
    graph: PoseGraph | None
    """The dataset (multi-g2o input), or None for a single g2o file."""
    offsets: np.ndarray
    """First global id of each agent (multi-g2o), or ``[0, n]`` for a single g2o file."""
    single: Any = None
    """The :class:`~studio.converters.graph_split.SingleGraph` of a single g2o file."""


@dataclass(frozen=True, eq=False)
class SolveResult:
    out_dir: Path
    estimate_path: Path
    """What ``studio evaluate --estimate`` takes: the multi-g2o folder, or the ``.g2o`` file."""
    method: str
    options: SolveOptions
    iterations: int
    chi2_dataset: float
    """chi2 at the dataset's own initial values (dead reckoning)."""
    chi2_initial: float
    """chi2 after the initial guess (what the iterations start from)."""
    chi2_final: float
    seconds: float
    """Wall time of loading, initial guess and iterations (not writing)."""
    planar: bool
    rejected: np.ndarray | None
    """``gnc``: rows ``from_agent from_vertex to_agent to_vertex`` (0-based) of rejected closures."""
    solution: Solution
    rrd_path: Path | None = None
    ape_per_round: dict[str, list[float]] | None = None
    """``dgs`` with ground truth: the round numbers and the translation APE [m] (mean and RMSE,
    ``first-pose`` and ``se3`` aligned) after each of them (round 0: the dataset's values)."""
    gauge: dict[str, Any] | None = None
    """A graph with priors or in several pieces: its pieces, priors and held vertices, and one note
    line (:func:`_gauge`); None for a connected graph without priors (held by its anchor)."""
    outliers: dict[str, Any] | None = None
    """A robust method on a dataset with labelled outliers (``outliers.txt``): the rejected loop
    closures' precision and recall against the labels (:func:`studio.core.outliers.outlier_scores`)."""

    def to_dict(self) -> dict[str, Any]:
        extra: dict[str, Any] = {} if self.ape_per_round is None else {"ape_per_round": self.ape_per_round}
        if self.gauge is not None:
            extra["gauge"] = self.gauge
        if self.outliers is not None:
            extra["outliers"] = self.outliers
        return {
            "method": self.method,
            "options": self.options.to_dict(),
            "planar": self.planar,
            "iterations": self.iterations,
            "chi2_dataset": self.chi2_dataset,
            "chi2_initial": self.chi2_initial,
            "chi2_final": self.chi2_final,
            "chi2_history": list(self.solution.chi2_history),
            "seconds": self.seconds,
            "estimate": self.estimate_path.name,
            "rejected_loop_closures": None if self.rejected is None else self.rejected.tolist(),
            "notes": self.solution.notes,
            **extra,
        }


def _planar_problem(p: Problem) -> Problem:
    priors = p.priors
    if priors is not None:
        priors = VertexPriors(
            priors.vertex, se3_poses_to_planar(priors.poses), se3_information_to_se2(priors.information_upper)
        )
    return Problem(
        PoseKind.SE2,
        se3_poses_to_planar(p.initial),
        p.edge_from,
        p.edge_to,
        se3_poses_to_planar(p.measurements),
        se3_information_to_se2(p.information_upper),
        p.robust,
        p.anchor,
        p.agent_of_vertex,
        priors,
    )


def _dataset_priors(path: Path, graph: PoseGraph, offsets: np.ndarray) -> VertexPriors | None:
    """The dataset folder's pose priors (``priors.txt``, JRL's ``PriorFactorPose2/3``) on global ids."""
    from studio.io.priors_txt import PRIORS_NAME, read_priors_txt

    if not (path / PRIORS_NAME).is_file():
        return None
    priors = read_priors_txt(path / PRIORS_NAME, graph)
    if not len(priors):
        return None
    return VertexPriors(offsets[priors.agent] + priors.index, priors.poses, priors.information_upper)


def _flatten(graph: PoseGraph) -> tuple[Problem, np.ndarray]:
    sizes = np.array([a.num_poses for a in graph.agents])
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    fr, to, meas, info, robust = [], [], [], [], []
    for k, a in enumerate(graph.agents):
        for edges, is_lc in ((a.odometry, False), (a.loop_closures, True)):
            fr.append(edges.from_index + offsets[k])
            to.append(edges.to_index + offsets[k])
            meas.append(edges.measurements)
            info.append(edges.information_upper)
            robust.append(np.full(len(edges), is_lc))
    inter = graph.inter
    fr.append(inter.from_index + offsets[inter.from_agent])
    to.append(inter.to_index + offsets[inter.to_agent])
    meas.append(inter.measurements)
    info.append(inter.information_upper)
    robust.append(np.ones(len(inter), dtype=bool))
    problem = Problem(
        graph.kind,
        np.concatenate([a.initial for a in graph.agents]),
        np.concatenate(fr).astype(np.int64),
        np.concatenate(to).astype(np.int64),
        np.concatenate(meas),
        np.concatenate(info),
        np.concatenate(robust),
        agent_of_vertex=np.repeat(np.arange(len(sizes), dtype=np.int64), sizes),
    )
    return problem, offsets


def _single_problem(path: Path, warn: Callable[[str], None] | None) -> tuple[Problem, Any]:
    """A single g2o file read as ``studio convert g2o`` reads it; loop closures (robust) are the
    edges between non-consecutive ids."""
    from studio.converters.g2o import read_single_g2o

    single = read_single_g2o(path, ground_truth="none", warn=warn)
    fr, to = single.from_index, single.to_index
    problem = Problem(
        single.kind,
        single.initial,
        fr,
        to,
        single.measurements,
        single.information_upper,
        to != fr + 1,
        single.anchor,
    )
    return problem, single


def load_problem(
    dataset: PathLike, *, dimension: Dimension = "auto", warn: Callable[[str], None] | None = None
) -> Loaded:
    """Read a multi-g2o folder or a single g2o file into a :class:`Problem` (see the module doc);
    ``warn`` gets the reader's warnings (skipped records, normalised quaternions)."""
    from studio.io.multig2o import read_multi_g2o

    path = Path(dataset)
    if dimension not in ("auto", "2d", "3d"):
        raise ConfigError(f"dimension: expected auto, 2d or 3d, got {dimension!r}")
    if path.is_dir():
        return graph_problem(read_multi_g2o(path), path, dimension=dimension, warn=warn)
    if not path.is_file():
        raise FormatError(f"{path}: no such dataset (a multi-g2o folder or a .g2o file)")
    problem, single = _single_problem(path, warn)
    return _loaded(problem, path, None, np.array([0, problem.num_vertices]), single, dimension, warn)


def graph_problem(
    graph: PoseGraph, path: Path, *, dimension: Dimension = "auto", warn: Callable[[str], None] | None = None
) -> Loaded:
    """A dataset's graph (read from ``path``) as a :class:`Problem` over global ids (see the module doc)."""
    problem, offsets = _flatten(graph)
    if path.is_dir():
        problem = dataclasses.replace(problem, priors=_dataset_priors(path, graph, offsets))
    return _loaded(problem, path, graph, offsets, None, dimension, warn)


def _loaded(
    problem: Problem,
    path: Path,
    graph: PoseGraph | None,
    offsets: np.ndarray,
    single: Any,
    dimension: Dimension,
    warn: Callable[[str], None] | None,
) -> Loaded:
    """The problem checked for edges and magnitudes, its information made weighable, and solved in
    SE(2) where its 3D records are planar (``dimension``)."""
    if problem.num_edges == 0:
        raise FormatError(f"{path}: the graph has no edges to optimize")
    _check_magnitudes(problem, path)
    problem = _weighable(problem, path, warn)
    source_kind = problem.kind
    if source_kind is PoseKind.SE2 and dimension == "3d":
        raise ConfigError(f"dimension: {path} is planar (2D records); it cannot be solved in 3D")
    if source_kind is PoseKind.SE3 and dimension != "3d":
        planar = is_planar_se3(problem.initial) and is_planar_se3(problem.measurements)
        if dimension == "2d" and not planar:
            raise ConfigError(f"dimension: {path} is not planar (z, roll or pitch non-zero); use --dimension 3d")
        if planar:
            problem = _planar_problem(problem)
    return Loaded(problem, source_kind, graph, offsets, single)


def _weighable(problem: Problem, path: Path, warn: Callable[[str], None] | None) -> Problem:
    """The problem with each information matrix that is not positive definite weighed by its
    translation and rotation blocks, as SE-Sync reads them (one warning with the count)."""
    d = 3 if problem.kind is PoseKind.SE2 else 6
    upper, count = block_diagonal_where_indefinite(problem.information_upper, d)
    if not count:
        return problem
    if warn is not None:
        warn(
            f"{path}: {count} information matrices are not positive definite; each is weighed by its "
            "translation and rotation blocks (the cross block dropped), as SE-Sync reads them"
        )
    return dataclasses.replace(problem, information_upper=upper)


def _check_magnitudes(problem: Problem, path: Path) -> None:
    for what, rows in (("vertex", problem.initial), ("edge", problem.measurements)):
        far = np.flatnonzero(
            np.abs(rows[:, 0 : 3 if problem.kind is PoseKind.SE3 else 2]).max(axis=1) > MAX_COORDINATE_M
        )
        if far.size:
            raise FormatError(
                f"{path}: {what} {int(far[0])} (global id order) lies beyond {MAX_COORDINATE_M:g} m: "
                "not a pose graph an optimizer can take"
            )


def _agent_rows(offsets: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    agent = np.searchsorted(offsets, ids, side="right") - 1
    return agent, ids - offsets[agent]


def _write_estimate(loaded: Loaded, poses: np.ndarray, staging: Path, stem: str, tum_names: list[str]) -> str:
    """Write the estimate into ``staging``; return the name of the file or folder evaluate takes."""
    from studio.io.g2o import G2oDocument, write_g2o
    from studio.io.multig2o import write_multi_g2o
    from studio.io.tum import write_tum

    lifted = poses
    if loaded.problem.kind is PoseKind.SE2 and loaded.source_kind is PoseKind.SE3:
        lifted = planar_poses_to_se3(poses)
    if loaded.graph is None:
        single = loaded.single
        ids = single.vertex_ids
        name = f"{stem}.g2o"
        write_g2o(
            staging / name,
            G2oDocument(
                loaded.source_kind,
                ids,
                lifted,
                ids[single.from_index],
                ids[single.to_index],
                single.measurements,
                single.information_upper,
            ),
        )
        return name
    graph = loaded.graph
    agents = []
    for k, a in enumerate(graph.agents):
        est = lifted[loaded.offsets[k] : loaded.offsets[k + 1]]
        agents.append(AgentGraph(a.name, a.kind, a.stamps_ns, est, None, a.odometry, a.loop_closures))
    estimate = PoseGraph(graph.kind, tuple(agents), graph.inter)
    folder = staging / "estimate"
    folder.mkdir()
    write_multi_g2o(estimate, folder, records="3d" if graph.kind is PoseKind.SE3 else "2d", precision="full")
    tum = folder / "tum"
    tum.mkdir()
    lifted3 = estimate.to_se3()
    for a, file_name in zip(lifted3.agents, tum_names, strict=True):
        write_tum(tum / file_name, Trajectory.from_poses(a.name, a.stamps_ns, a.initial))
    return "estimate"


#: The shared options' defaults, for :func:`solve`'s keywords.
_SHARED = SolveOptions()


def solve(
    dataset: PathLike,
    out: PathLike,
    *,
    method: str = DEFAULT_METHOD,
    optimizer: str = _SHARED.optimizer,
    init: str = _SHARED.init,
    max_iterations: int | None = None,
    relative_tolerance: float = _SHARED.relative_tolerance,
    dimension: Dimension = "auto",
    force: bool = False,
    rrd: PathLike | None = None,
    warn: Callable[[str], None] | None = None,
    **method_options: Any,
) -> SolveResult:
    """Optimize ``dataset`` with ``method`` and write the estimate and ``solve.json`` into the folder
    ``out`` (staged, renamed into place; an existing ``out`` is replaced only with ``force``).

    ``rrd`` also writes a Rerun recording of the run (every iteration on an ``iteration`` timeline,
    beside the ground truth, with the cost per iteration).

    ``max_iterations``: None, the method's own default (g2o: 10). ``method_options``: the method's
    own options by name, the fields of its registry entry's ``method_options`` class (dgs:
    :class:`~studio.solvers.options.DgsOptions`, e.g. ``robots=4`` on a single g2o file,
    ``coarse_size=0`` for plain DGS; command: ``command="prog {input} {output}"``); one the method
    does not read is refused. With ground truth, ``dgs`` also scores every round (APE). ``warn``
    gets the reader's warnings (one line each)."""
    entry = method_entry(method)
    options = _solve_options(entry, optimizer, init, max_iterations, relative_tolerance)
    options = dataclasses.replace(options, own=entry.own_options_from(method_options))
    out = Path(out)
    rrd_path = None if rrd is None else Path(rrd)
    if rrd_path is not None and rrd_path.suffix != ".rrd":
        raise ConfigError(f"rrd: {rrd_path} must end in .rrd")
    inputs = dataset_inputs(dataset)
    _check_solve_outputs(out, rrd_path, inputs, force)  # every refusal before any work
    t0 = time.perf_counter()
    loaded, gauge = _gauge(load_problem(dataset, dimension=dimension, warn=warn), entry, dataset, warn)
    tum_names = _tum_names(loaded, dataset)
    problem = loaded.problem
    iterates: list[tuple[int, np.ndarray]] = []
    scorer = _RoundScorer.of(loaded) if entry.scores_rounds else None
    solution = _run_solver(loaded, entry, options, dataset, method, iterates if rrd_path is not None else None, scorer)
    seconds = time.perf_counter() - t0
    chi2_initial = solution.chi2_history[0] if solution.chi2_history else graph_chi2(problem, problem.initial)
    chi2_final = graph_chi2(problem, solution.poses) if np.isfinite(solution.poses).all() else float("nan")
    check_solution(problem, solution, chi2_initial, chi2_final, method=method, where=str(dataset))
    result = SolveResult(
        out,
        out,
        method,
        options,
        solution.iterations,
        graph_chi2(problem, problem.initial),
        chi2_initial,
        chi2_final,
        seconds,
        problem.kind is PoseKind.SE2 and loaded.source_kind is PoseKind.SE3,
        _rejected_rows(loaded, solution),
        solution,
        rrd_path,
        None if scorer is None else scorer.rounds(solution),
        gauge,
        _outlier_scores(loaded, dataset, _rejected_rows(loaded, solution)),
    )
    return _write_solve_outputs(result, loaded, dataset, tum_names, iterates, inputs=inputs, force=force)


def _solve_options(
    entry: SolveMethod, optimizer: str, init: str, max_iterations: int | None, relative_tolerance: float
) -> SolveOptions:
    """The shared options of :func:`solve` checked (each refusal names its option),
    ``max_iterations`` defaulting to the method's own."""
    if optimizer not in get_args(Optimizer):
        raise ConfigError(f"optimizer: expected {' or '.join(get_args(Optimizer))}, got {optimizer!r}")
    if init not in get_args(Init):
        raise ConfigError(f"init: expected {', '.join(get_args(Init)[:-1])} or {get_args(Init)[-1]}, got {init!r}")
    if max_iterations is None:
        max_iterations = entry.default("max_iterations")  # the method's own default (g2o: the paper's 10)
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or not 1 <= max_iterations <= 10_000:
        raise ConfigError(
            f"max_iterations: expected an integer in 1..10000, got {max_iterations!r}", option="max_iterations"
        )
    if not (isinstance(relative_tolerance, (int, float)) and 0 <= relative_tolerance < 1):
        raise ConfigError(f"relative_tolerance: expected a number in [0, 1), got {relative_tolerance!r}")
    return SolveOptions(optimizer, init, max_iterations, float(relative_tolerance))  # type: ignore[arg-type]


def _run_solver(
    loaded: Loaded,
    entry: SolveMethod,
    options: SolveOptions,
    dataset: PathLike,
    method: str,
    iterates: list[tuple[int, np.ndarray]] | None,
    scorer: _RoundScorer | None,
) -> Solution:
    """Check the problem and run the method on it; each iterate is kept in ``iterates`` (for the
    recording) and scored by ``scorer`` when they are given. A back-end's own failure is a FormatError."""
    problem = loaded.problem
    on_iteration: Iteration | None = None
    if iterates is not None or scorer is not None:

        def on_iteration(k: int, poses: np.ndarray) -> None:
            if iterates is not None:
                iterates.append((k, poses.copy()))
            if scorer is not None:
                scorer.add(k, poses)

    check_problem(problem, str(dataset), _vertex_namer(loaded))
    try:
        with native_stdout_silenced():  # GTSAM's notices (gnc's setMaxIterations) are not our output
            return entry.solve(problem, options, on_iteration)
    except RuntimeError as err:  # GTSAM's and g2o's own failures (e.g. an indeterminate system)
        first = next((ln.strip() for ln in str(err).splitlines() if ln.strip()), type(err).__name__)
        raise FormatError(f"{dataset}: method {method} failed: {first} (is the graph connected?)") from None


def _vertex_namer(loaded: Loaded) -> Callable[[int], str]:
    """A global id in the dataset's words: ``agent2 vertex 0``, or a single g2o file's own id."""
    names = [a.name for a in loaded.graph.agents] if loaded.graph is not None else None

    def vertex_name(v: int) -> str:
        if names is None:  # a single g2o file: the file's own id
            return f"vertex {int(loaded.single.vertex_ids[v]) if loaded.single is not None else v}"
        k = int(np.searchsorted(loaded.offsets, v, side="right") - 1)
        return f"{names[k]} vertex {v - int(loaded.offsets[k])}"

    return vertex_name


def _gauge(
    loaded: Loaded, entry: SolveMethod, dataset: PathLike, warn: Callable[[str], None] | None
) -> tuple[Loaded, dict[str, Any] | None]:
    """The problem with the gauge the method takes (:mod:`studio.solvers.gauge`: the dataset's priors
    and one held vertex per piece without one) and what ``solve.json`` says of it (None for a
    connected graph without priors, held by its anchor as always)."""
    from studio.solvers.gauge import gauge_report, with_gauge

    problem = loaded.problem
    if not entry.gauges:
        if problem.priors is not None and warn is not None:
            warn(
                f"{dataset}: method {entry.name} does not take pose priors; the {len(problem.priors)} priors of "
                "priors.txt are left out and the first pose is held"
            )
        return dataclasses.replace(loaded, problem=dataclasses.replace(problem, priors=None)), None
    problem = with_gauge(problem)
    if problem.anchors is None:
        return loaded, None
    name = _vertex_namer(loaded)
    report = gauge_report(problem, name)
    held = [name(int(v)) for v in problem.held]
    report["note"] = (
        f"{report['pieces']} piece{'s' if report['pieces'] != 1 else ''}, {report['priors']} priors; "
        + (f"held at their first pose (no prior reaches them): {', '.join(held[:5])}" if held else "no anchor")
        + (f" and {len(held) - 5} more" if len(held) > 5 else "")
        + (
            f"; {report['isolated_vertices']} isolated vertices keep their initial values"
            if report["isolated_vertices"]
            else ""
        )
    )
    return dataclasses.replace(loaded, problem=problem), report


def _outlier_scores(loaded: Loaded, dataset: PathLike, rejected: np.ndarray | None) -> dict[str, Any] | None:
    """The rejected loop closures' precision and recall against the dataset's labelled outliers
    (``outliers.txt``), where a robust method ran on a dataset that has them."""
    from studio.core.outliers import outlier_scores
    from studio.io.outliers_txt import read_outliers_txt

    path = Path(dataset) / "outliers.txt"
    if rejected is None or loaded.graph is None or not path.is_file():
        return None
    labelled = read_outliers_txt(path, [a.num_poses for a in loaded.graph.agents])[0]
    return outlier_scores(rejected, labelled)


def _rejected_rows(loaded: Loaded, solution: Solution) -> np.ndarray | None:
    """The rows ``from_agent from_vertex to_agent to_vertex`` of the loop closures the method
    rejected (gnc), or None."""
    if solution.rejected is None:
        return None
    problem = loaded.problem
    ids = np.flatnonzero(solution.rejected)
    fa, fv = _agent_rows(loaded.offsets, problem.edge_from[ids])
    ta, tv = _agent_rows(loaded.offsets, problem.edge_to[ids])
    return np.column_stack([fa, fv, ta, tv]).astype(np.int64).reshape(-1, 4)


def _write_solve_outputs(
    result: SolveResult,
    loaded: Loaded,
    dataset: PathLike,
    tum_names: list[str],
    iterates: list[tuple[int, np.ndarray]],
    *,
    inputs: list[Path],
    force: bool,
) -> SolveResult:
    """Stage and write the estimate, ``solve.json`` and the recording (``result.rrd_path``); return
    ``result`` with the estimate's path."""
    from studio.io.atomic import staged_outputs

    out, rrd_path, solution = result.out_dir, result.rrd_path, result.solution
    stem = safe_file_name(Path(dataset).stem, fallback="graph")
    with contextlib.ExitStack() as stack:
        # the recording is staged inside the estimate's guard: a failure of either leaves neither
        staging = stack.enter_context(staged_outputs(out.parent, [out.name], force=force, inputs=inputs))
        if rrd_path is not None:
            from studio.recording.solve import write_solve_recording

            write_solve_recording(
                rrd_path,
                loaded.graph,
                loaded.offsets,
                loaded.problem.kind,
                iterates,
                solution.chi2_history,
                name=f"{stem} ({result.method})",
                force=force,
                inputs=[*inputs, out],
            )
        folder = staging / out.name
        folder.mkdir()
        name = _write_estimate(loaded, solution.poses, folder, stem, tum_names)
        _write_jrr(loaded, result, folder / f"{stem}.jrr", dataset_name=Path(dataset).name)
        result = dataclasses.replace(result, estimate_path=out / name)
        (folder / SOLVE_JSON).write_text(
            dumps_strict(result.to_dict(), str(out / SOLVE_JSON), indent=2, default=_json_default) + "\n",
            encoding="utf-8",
        )
    return result


def _write_jrr(loaded: Loaded, result: SolveResult, path: Path, *, dataset_name: str) -> None:
    """The estimate as JRL results (:mod:`studio.io.jrr`): one robot per agent (a single g2o file:
    one robot), its own poses in the dataset's pose kind; a central solve keeps no copies of other
    robots' poses. A robust method's rejected closures are its ``outliers``, by their FactorIds in
    the studio's JRL export of the dataset (``studio export --format jrl``)."""
    from studio.io.jrr import write_jrr
    from studio.io.symbol_g2o import robot_prefix
    from studio.jrl_evaluate import graph_results

    poses, source = result.solution.poses, loaded.source_kind
    if loaded.problem.kind is PoseKind.SE2 and source is PoseKind.SE3:
        poses = planar_poses_to_se3(poses)
    parts = [poses[loaded.offsets[k] : loaded.offsets[k + 1]] for k in range(len(loaded.offsets) - 1)]
    robots = [robot_prefix(k) for k in range(len(parts))]
    outliers, shared = None, None
    if loaded.graph is not None:
        shared = _shared_copies(loaded.graph, parts, robots)
        if result.rejected is not None:
            outliers = _rejected_factor_ids(loaded.graph, result.rejected, robots, dataset_name)
    results = graph_results(source, robots, parts, dataset_name=dataset_name, method_name=result.method, shared=shared)
    write_jrr(path, dataclasses.replace(results, outliers=outliers))


def _shared_copies(graph: PoseGraph, parts: list[np.ndarray], robots: list[str]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per robot, ``(keys, poses)`` of the other robots' poses its measurements name (an
    inter-robot closure is its ``from`` robot's measurement, as in the JRL export), at the one
    estimate a central solve has: jrl's results hold every value a robot's factors touch."""
    inter = graph.inter
    base = np.array([ord(c) << 56 for c in robots], dtype=np.int64)
    out = []
    for k in range(len(robots)):
        mine = inter.from_agent == k
        keys, first = np.unique(base[inter.to_agent[mine]] + inter.to_index[mine], return_index=True)
        agents, index = inter.to_agent[mine][first], inter.to_index[mine][first]
        width = parts[k].shape[1]
        poses = np.array([parts[a][i] for a, i in zip(agents.tolist(), index.tolist())]).reshape(len(keys), width)
        out.append((keys, poses))
    return out


def _rejected_factor_ids(
    graph: PoseGraph, rejected: np.ndarray, robots: list[str], name: str
) -> tuple[np.ndarray, ...]:
    """Per robot, the FactorIds of the ``rejected`` rows (``from_agent from_vertex to_agent
    to_vertex``) in the studio's JRL export of ``graph``."""
    from studio.io.jrl import jrl_document
    from studio.jrl_evaluate import factor_ids_of_edges

    base = np.array([ord(c) << 56 for c in robots], dtype=np.int64)
    keys = np.column_stack([base[rejected[:, 0]] + rejected[:, 1], base[rejected[:, 2]] + rejected[:, 3]])
    found = factor_ids_of_edges(jrl_document(graph, name=name), keys)
    return tuple(found.get(c, np.zeros((0, 2), np.int64)) for c in robots)


@dataclass(eq=False)
class _RoundScorer:
    """The translation APE of each iterate (``first-pose`` and ``se3``), with evaluate's metric."""

    loaded: Loaded
    ground_truth: list[np.ndarray]
    curve: dict[str, list[float]]

    @classmethod
    def of(cls, loaded: Loaded) -> _RoundScorer | None:
        graph = loaded.graph
        if graph is None or any(a.ground_truth is None for a in graph.agents):
            return None
        gt = [np.asarray(a.ground_truth) for a in graph.to_se3().agents]
        keys = ("round", "first_pose_mean_m", "first_pose_rmse_m", "se3_mean_m", "se3_rmse_m")
        return cls(loaded, gt, {k: [] for k in keys})

    def rounds(self, solution: Solution) -> dict[str, list[float]]:
        """The curve with ``round`` the dgs round of each iteration (iteration i >= 1: pose round i)."""
        skip = int(solution.notes.get("rotation_rounds", 0))  # type: ignore[call-overload]
        return {**self.curve, "round": [k + skip if k else 0 for k in self.curve["round"]]}

    def add(self, k: int, poses: np.ndarray) -> None:
        from studio.evaluate import ape_translation

        if self.loaded.problem.kind is PoseKind.SE2:
            poses = planar_poses_to_se3(poses)
        offsets = self.loaded.offsets
        per_agent = [poses[offsets[a] : offsets[a + 1]] for a in range(len(offsets) - 1)]
        assert self.loaded.graph is not None
        first = ape_translation(self.loaded.graph, self.ground_truth, per_agent, align="first-pose")
        se3 = ape_translation(self.loaded.graph, self.ground_truth, per_agent, align="se3")
        for key, value in zip(self.curve, (k, first.mean, first.rmse, se3.mean, se3.rmse)):
            self.curve[key].append(value)


@contextlib.contextmanager
def native_stdout_silenced() -> Iterator[None]:
    """Send what native code (GTSAM, g2o) prints on the process's stdout (file descriptor 1) to
    /dev/null while the block runs: a command's stdout holds its own output only (``--json``)."""
    import ctypes
    import sys

    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        yield
        return
    libc = ctypes.CDLL(None)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        libc.fflush(None)  # C stdio (std::cout shares it) drained into /dev/null, not into our output
        os.dup2(saved, 1)
        os.close(saved)


def dataset_inputs(dataset: PathLike) -> list[Path]:
    """The paths a solve of ``dataset`` reads or that belong to it: the multi-g2o folder, or the
    single g2o file with the files of kollagen's single view beside it (``<stem>_GT.tum``,
    ``<stem>.tum``), which no output may replace."""
    path = Path(dataset)
    if path.is_dir():
        return [path]
    return [path, path.with_name(f"{path.stem}_GT.tum"), path.with_name(f"{path.stem}.tum")]


def _check_solve_outputs(out: Path, rrd: Path | None, inputs: list[Path], force: bool) -> None:
    from studio.io.atomic import check_outputs

    if out.name in ("", ".", ".."):
        raise OutputError(
            f"{out}: an output cannot be the current folder or one of its parents; name the folder to write"
        )
    check_outputs(out.parent, [out.name], force=force, inputs=inputs)
    if rrd is None:
        return
    real_rrd, real_out = Path(os.path.realpath(rrd)), Path(os.path.realpath(out))
    if real_rrd == real_out or real_out in real_rrd.parents:
        raise OutputError(f"{rrd}: the recording would sit inside {out}, which solve writes; choose another path")
    check_outputs(rrd.parent, [rrd.name], force=force, inputs=[*inputs, out])


def _tum_names(loaded: Loaded, dataset: PathLike) -> list[str]:
    """The estimate's TUM file names, one per agent, made from the agents' names (which come from
    the data: ``agents.json``) by :func:`studio.io.names.safe_file_name`."""
    if loaded.graph is None:
        return []
    return [f"{n}.tum" for n in safe_file_names([a.name for a in loaded.graph.agents], where=str(dataset))]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")
