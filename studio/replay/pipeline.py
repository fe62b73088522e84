"""``studio replay`` as a library function: a multi-robot dataset lived through in time.

Each measurement gets a time (:mod:`studio.core.timing`), a communication model says when robots
can talk and when each inter-agent closure reaches its robots (:mod:`studio.core.comms`), and each
back-end of :mod:`studio.replay.backends` is advanced through the replay, checkpoint by checkpoint
(every ``every`` ticks of ``step_s`` seconds, and at the end); at each checkpoint every robot's
belief of its own trajectory so far is scored against its ground truth so far
(:mod:`studio.replay.metrics`). Deterministic: the same dataset, model, seed and options give the
same schedule files and the same ``metrics.csv``/``summary.csv`` bytes (solver times, which vary,
are kept apart in ``timings.csv``).

Outputs, one folder (staged, renamed into place; replaced only with ``force``):
``schedule/contacts.csv``, ``schedule/closures.csv`` (:mod:`studio.io.schedule_csv`),
``schedule/rendezvous.txt`` for a rendezvous model (:mod:`studio.io.rendezvous_txt`);
``metrics.csv`` (per back-end, checkpoint and robot), ``summary.csv``/``summary.md`` (final
figures), ``links.csv`` (messages and bytes per link), ``timings.csv``, ``report.md`` (the
communication report and the summary), ``replay.json`` (the effective options), ``ape.png`` (APE
vs time per back-end, when matplotlib is installed), with ``parquet`` each CSV table as Parquet too
(:mod:`studio.io.parquet_table`), and with ``rrd`` a Rerun recording.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.comms import (
    Bandwidth,
    CommsModel,
    CommsReport,
    PartnerCap,
    Rendezvous,
    Schedule,
    comms_report,
    contacts,
    deliver,
    parse_bandwidth,
    parse_comms,
    robot_pairs,
    tick_grid,
)
from studio.core.comms_registry import DEFAULT_COMMS
from studio.core.errors import ConfigError, FormatError, GraphError
from studio.core.model import PoseGraph, PoseKind
from studio.core.option_values import check_count, check_option
from studio.core.timing import MeasurementTimes, measurement_times
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.strict_json import dumps_strict
from studio.replay.metrics import (
    as_se3,
    first_pose_errors,
    gaps_to,
    positions,
    robot_values,
    se3_errors,
    team_optimum,
)
from studio.replay.protocol import Checkpoint, KeptPoses, Setup, Step
from studio.replay.registry import DEFAULT_BACKENDS, get_backend, output_name
from studio.runtime.progress import Progress, report
from studio.solvers.isam_settings import IsamSettings
from studio.solvers.problem import Problem, graph_chi2

__all__ = ["replay", "ReplayResult", "BackendRun", "build_schedule", "DEFAULT_BACKENDS", "REPLAY_JSON"]

REPLAY_JSON = "replay.json"
METRICS_HEADER = "backend,tick,time_s,robot,poses,ape_first_pose_m,ape_se3_m,sve_t_m,sve_r_rad"


@dataclass(frozen=True, eq=False)
class World:
    """What the simulation knows about the dataset and the schedule, as columns over global ids: the
    source of each checkpoint's news (:meth:`news`); the back-ends see only the :class:`Setup` and
    the news."""

    problem: Problem
    agent_of_vertex: np.ndarray
    vertex_ns: np.ndarray
    """When each vertex is visited."""
    edge_ns: np.ndarray
    """When each edge is measured."""
    edge_closure: np.ndarray
    """Per edge, its inter-agent closure index, -1 for a robot's own edge."""
    delivered_tick: np.ndarray
    """Per inter-agent closure, the tick its robots learn it, -1 for never."""
    ticks_ns: np.ndarray
    num_robots: int
    settings: IsamSettings

    def setup(self) -> Setup:
        return Setup(self.problem, self.agent_of_vertex, self.num_robots, self.settings)

    @cached_property
    def closure_tick(self) -> np.ndarray:
        """Per edge, the tick its inter-agent closure is delivered; -1 for a robot's own edge and a
        closure never delivered."""
        inter = self.edge_closure >= 0
        out = np.full(len(inter), -1, dtype=np.int64)  # a team without closures delivers none
        out[inter] = self.delivered_tick[self.edge_closure[inter]]
        return out

    def edges_known(self) -> np.ndarray:
        """Per edge: known to some robot by the end (its own edges, the closures delivered): the
        edges the centralized back-end optimizes over."""
        return np.asarray((self.edge_closure < 0) | (self.closure_tick >= 0))

    def news(self, previous: int, tick: int, groups: list[tuple[int, ...]], contacts: np.ndarray) -> Checkpoint:
        """What happened after tick ``previous`` (-1: the start) up to ``tick``: poses visited and
        own edges measured in that time, the closures delivered in it."""
        t = int(self.ticks_ns[tick])
        before = int(self.ticks_ns[previous]) if previous >= 0 else np.iinfo(np.int64).min
        vertices = np.flatnonzero((self.vertex_ns > before) & (self.vertex_ns <= t))
        own = self.edge_closure < 0
        edges = np.flatnonzero(own & (self.edge_ns > before) & (self.edge_ns <= t))
        closures = np.flatnonzero(~own & (self.closure_tick > previous) & (self.closure_tick <= tick))
        return Checkpoint(
            tick,
            t,
            vertices,
            self.vertex_ns[vertices],
            edges,
            self.edge_ns[edges],
            closures,
            self.edge_ns[closures],
            groups,
            contacts,
        )


@dataclass(frozen=True, eq=False)
class BackendRun:
    name: str
    checkpoint_ticks: np.ndarray
    ape_robot_m: np.ndarray
    """``(checkpoints, robots)`` first-pose APE mean of each robot's own trajectory so far."""
    ape_team_first_pose_m: np.ndarray
    """Per checkpoint, over all robots' poses (each aligned by its first pose)."""
    ape_team_se3_m: np.ndarray
    """Per checkpoint, all robots' positions under one rigid transform."""
    poses_seen: np.ndarray
    """``(checkpoints, robots)`` poses each robot has visited."""
    chi2_final: float
    """chi2 of the final beliefs over every edge of the dataset."""
    chi2_delivered: float
    """chi2 of the final beliefs over the edges known to anyone by the end (every robot's own edges
    and the inter-agent closures delivered): the objective the centralized back-end minimizes."""
    messages: np.ndarray
    bytes: np.ndarray
    solver_seconds: np.ndarray
    """Per checkpoint, wall time in the solver."""
    seconds: float
    """Wall time of the whole back-end run."""
    final_poses: np.ndarray
    beliefs: tuple[np.ndarray, ...] = ()
    """With a recording: per checkpoint, the ``(num_vertices, 3)`` float32 positions believed."""
    sve: np.ndarray | None = None
    """``(checkpoints, 2)`` jrl's Shared Variable Error (translation [m], rotation [rad]) of the
    poses robots keep of each other, NaN before any is shared; None for a back-end that keeps none."""
    final_kept: KeptPoses | None = None
    """The poses of other robots each robot keeps at the end (swarm, dgs)."""
    sesync_f: float = float("nan")
    """SE-Sync's objective of the final beliefs over every edge of the dataset."""
    gap_to_optimum: float | None = None
    """``(f - f*) / f*`` against the dataset's certified optimum (None without one)."""


@dataclass(frozen=True, eq=False)
class ReplayResult:
    out_dir: Path
    schedule: Schedule
    report: CommsReport
    runs: tuple[BackendRun, ...]
    options: dict[str, Any]
    rrd_path: Path | None = None


def _components(num_robots: int, pairs: np.ndarray, linked: np.ndarray, present: np.ndarray) -> list[tuple[int, ...]]:
    """Connected components (sorted tuples, by lowest member) of the robots ``present``."""
    parent = list(range(num_robots))

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for (a, b), up in zip(pairs.tolist(), linked.tolist()):
        if up:
            ra, rb = find(a), find(b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    groups: dict[int, list[int]] = {}
    for r in range(num_robots):
        if present[r]:
            groups.setdefault(find(r), []).append(r)
    return sorted(tuple(g) for g in groups.values())


def _load(dataset: PathLike, warn: Callable[[str], None] | None = None) -> tuple[Any, PoseGraph]:
    """A multi-g2o folder, or a single g2o file read as ``studio convert g2o`` reads it (one robot,
    its ground truth ``<stem>_GT.tum`` beside it), with the problem over its global ids."""
    from studio.solve import graph_problem, load_problem

    path = Path(dataset)
    if path.is_file():
        from studio.converters.g2o import read_g2o_graph

        loaded = graph_problem(read_g2o_graph([path], warn=warn).graph, path, warn=warn)
    elif path.is_dir():
        loaded = load_problem(path, warn=warn)
    else:
        raise FormatError(f"{path}: no such dataset (a multi-g2o folder or a .g2o file)")
    graph = loaded.graph
    assert graph is not None
    missing = [a.name for a in graph.agents if a.ground_truth is None]
    if missing:
        raise FormatError(f"{path}: agent {missing[0]} has no ground truth; replay scores against it")
    return loaded, graph


def build_schedule(
    graph: PoseGraph,
    times: MeasurementTimes,
    model: CommsModel,
    *,
    step_ns: int,
    seed: int = 0,
    bandwidth: Bandwidth | None = None,
) -> Schedule:
    """The schedule of ``model`` for ``graph`` on ticks of ``step_ns`` (see :mod:`studio.core.comms`)."""
    ticks = tick_grid(times.start_ns, times.end_ns, step_ns)
    positions = tuple(np.asarray(a.se3_poses(ground_truth=True))[:, 0:3] for a in graph.agents)
    n = len(graph.agents)
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(robot_pairs(n).tolist())}
    fa, ta = graph.inter.from_agent, graph.inter.to_agent
    pair = np.array(
        [-1 if a == b else index[(min(a, b), max(a, b))] for a, b in zip(fa.tolist(), ta.tolist())], dtype=np.int64
    )
    contact = contacts(
        model,
        ticks_ns=ticks,
        pose_ns=times.pose_ns,
        positions_xyz=positions,
        seed=seed,
        closure_pair=pair,
        measured_ns=times.inter_ns,
    )
    kind = graph.kind
    closure_bytes = 8 * (4 + kind.pose_width + kind.information_width)
    delivered = deliver(
        contact,
        ticks_ns=ticks,
        closure_pair=pair,
        measured_ns=times.inter_ns,
        bandwidth=bandwidth,
        closure_bytes=closure_bytes,
        step_ns=step_ns,
    )
    return Schedule(
        model.spec(),
        tuple(a.name for a in graph.agents),
        ticks,
        contact,
        fa.copy(),
        ta.copy(),
        times.inter_ns,
        delivered,
        seed,
        "" if bandwidth is None else bandwidth.spec(),
    )


def _world(loaded: Any, graph: PoseGraph, times: MeasurementTimes, schedule: Schedule, settings: IsamSettings) -> World:
    problem = loaded.problem
    sizes = [a.num_poses for a in graph.agents]
    agent_of_vertex = np.repeat(np.arange(len(sizes)), sizes).astype(np.int64)
    parts, closure = [], []
    for k in range(len(graph.agents)):
        parts += [times.odometry_ns[k], times.loop_closure_ns[k]]
        closure.append(np.full(len(times.odometry_ns[k]) + len(times.loop_closure_ns[k]), -1, dtype=np.int64))
    parts.append(times.inter_ns)
    closure.append(np.arange(len(times.inter_ns), dtype=np.int64))
    edge_ns = np.concatenate(parts).astype(np.int64)
    assert len(edge_ns) == problem.num_edges
    return World(
        problem,
        agent_of_vertex,
        np.concatenate(times.pose_ns),
        edge_ns,
        np.concatenate(closure),
        schedule.delivered_tick,
        schedule.ticks_ns,
        len(graph.agents),
        settings,
    )


def _checkpoints(num_ticks: int, every: int) -> np.ndarray:
    ticks = np.arange(0, num_ticks, every, dtype=np.int64)
    if ticks[-1] != num_ticks - 1:
        ticks = np.concatenate([ticks, [num_ticks - 1]])
    return ticks


def _run(
    name: str,
    world: World,
    graph: PoseGraph,
    schedule: Schedule,
    checkpoints: np.ndarray,
    *,
    keep_beliefs: bool,
    progress: Progress | None = None,
    time_limit_s: float | None = None,
) -> BackendRun:
    t0 = time.perf_counter()
    backend = get_backend(name, time_limit_s=time_limit_s)(world.setup())
    kind = world.problem.kind
    truth = [np.asarray(a.se3_poses(ground_truth=True)) for a in graph.agents]
    offsets = np.concatenate([[0], np.cumsum([a.num_poses for a in graph.agents])])
    pairs = schedule.pairs
    n = world.num_robots
    ape = np.zeros((len(checkpoints), n))
    seen_count = np.zeros((len(checkpoints), n), dtype=np.int64)
    team_fp = np.zeros(len(checkpoints))
    team_se3 = np.zeros(len(checkpoints))
    solver_s = np.zeros(len(checkpoints))
    previous = -1
    step = None
    beliefs: list[np.ndarray] = []
    sve = np.full((len(checkpoints), 2), np.nan)
    for c, tick in enumerate(checkpoints.tolist()):
        report(progress, f"replay {output_name(name)}", c, len(checkpoints), "checkpoints")
        linked = np.asarray(schedule.contact[previous + 1 : tick + 1].any(axis=0))
        present = np.array([world.vertex_ns[offsets[r]] <= world.ticks_ns[tick] for r in range(n)])
        groups = _components(n, pairs, linked, present)
        step = backend.advance(world.news(previous, tick, groups, pairs[linked]))
        if c == len(checkpoints) - 1:
            last = backend.finish()
            step = dataclasses.replace(last, solver_seconds=step.solver_seconds + last.solver_seconds)
        solver_s[c] = step.solver_seconds
        if keep_beliefs:
            beliefs.append(positions(step.own, kind).astype(np.float32))
        t = world.ticks_ns[tick]
        fp_all, est_all, gt_all = [], [], []
        for r in range(n):
            rows = slice(int(offsets[r]), int(offsets[r + 1]))
            seen = int((world.vertex_ns[rows] <= t).sum())
            seen_count[c, r] = seen
            est, gt = as_se3(step.own[rows][:seen], kind), truth[r][:seen]  # the poses seen by t
            e = first_pose_errors(est, gt)
            ape[c, r] = float(e.mean()) if len(e) else 0.0
            fp_all.append(e)
            est_all.append(est[:, 0:3])
            gt_all.append(gt[:, 0:3])
        fp = np.concatenate(fp_all)
        team_fp[c] = float(fp.mean()) if len(fp) else 0.0
        se3 = se3_errors(np.concatenate(est_all), np.concatenate(gt_all))
        team_se3[c] = float(se3.mean()) if len(se3) else 0.0
        if step.kept is not None:
            sve[c] = _sve(step, world, t)
        previous = tick
    assert step is not None
    final = step.own
    return BackendRun(
        output_name(name),
        checkpoints,
        ape,
        team_fp,
        team_se3,
        seen_count,
        graph_chi2(world.problem, final),
        graph_chi2(world.problem, final, world.edges_known()),
        step.messages.copy(),
        step.bytes.copy(),
        solver_s,
        time.perf_counter() - t0,
        final,
        tuple(beliefs),
        None if step.kept is None else sve,
        step.kept,
    )


def _run_all(
    names: list[str],
    world: World,
    graph: PoseGraph,
    schedule: Schedule,
    checkpoints: np.ndarray,
    *,
    keep_beliefs: bool,
    progress: Progress | None,
    limit: dict[str, float],
) -> tuple[BackendRun, ...]:
    """Every back-end's run (``limit``: ``_run``'s ``time_limit_s`` when given), its final beliefs
    scored against the certified optimum. The optimum is found first: its solver's memory is then
    free again when the back-ends' peak comes, not added to it."""
    optimum = team_optimum(world.problem)
    runs = [
        _run(n, world, graph, schedule, checkpoints, keep_beliefs=keep_beliefs, progress=progress, **limit)
        for n in names
    ]
    _, scored = gaps_to(world.problem, [r.final_poses for r in runs], optimum)
    return tuple(dataclasses.replace(r, sesync_f=f, gap_to_optimum=g) for r, (f, g) in zip(runs, scored, strict=True))


def _sve(step: Step, world: World, t: int) -> tuple[float, float]:
    """jrl's SVE of the robots' own poses visited by ``t`` and the poses they keep of each other."""
    from studio.core.jrl_metrics import sve

    kept = step.kept
    assert kept is not None
    visited = world.vertex_ns <= t
    values = robot_values(
        step.own, visited, world.agent_of_vertex, kept.robot, kept.vertex, kept.poses, world.num_robots
    )
    return sve(values)


def _g(x: float) -> str:
    return f"{x:.9g}"


def _metrics_text(runs: tuple[BackendRun, ...], schedule: Schedule) -> str:
    lines = [METRICS_HEADER]
    t0 = int(schedule.ticks_ns[0])
    for run in runs:
        for c, tick in enumerate(run.checkpoint_ticks.tolist()):
            ts = _g((int(schedule.ticks_ns[tick]) - t0) / NS_PER_S)
            for r, robot in enumerate(schedule.robots):
                seen = int(run.poses_seen[c, r])
                lines.append(f"{run.name},{tick},{ts},{robot},{seen},{_g(run.ape_robot_m[c, r])},,,")
            total = int(run.poses_seen[c].sum())
            sve = "," if run.sve is None or np.isnan(run.sve[c, 0]) else f"{_g(run.sve[c, 0])},{_g(run.sve[c, 1])}"
            lines.append(
                f"{run.name},{tick},{ts},all,{total},{_g(run.ape_team_first_pose_m[c])},{_g(run.ape_team_se3_m[c])},"
                + sve
            )
    return "\n".join(lines) + "\n"


SUMMARY_COLUMNS = (
    "backend",
    "ape_first_pose_m",
    "ape_se3_m",
    "chi2",
    "chi2_delivered",
    "sesync_f",
    "gap_to_optimum",
    "messages",
    "bytes",
)


def _summary_rows(runs: tuple[BackendRun, ...]) -> list[list[str]]:
    return [
        [
            r.name,
            _g(r.ape_team_first_pose_m[-1]),
            _g(r.ape_team_se3_m[-1]),
            _g(r.chi2_final),
            _g(r.chi2_delivered),
            _g(r.sesync_f),
            "" if r.gap_to_optimum is None else _g(r.gap_to_optimum),
            str(int(r.messages.sum())),
            str(int(r.bytes.sum())),
        ]
        for r in runs
    ]


def _markdown(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join([":---"] + ["---:"] * (len(header) - 1)) + "|"]
    out += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(out) + "\n"


def _links_text(runs: tuple[BackendRun, ...], schedule: Schedule) -> str:
    lines = ["backend,robot_a,robot_b,closures_delivered,messages,bytes"]
    pairs = schedule.pairs
    got = schedule.delivered_tick >= 0
    for run in runs:
        for p, (a, b) in enumerate(pairs.tolist()):
            on = got & (
                ((schedule.closure_from == a) & (schedule.closure_to == b))
                | ((schedule.closure_from == b) & (schedule.closure_to == a))
            )
            lines.append(
                f"{run.name},{schedule.robots[a]},{schedule.robots[b]},{int(on.sum())},"
                f"{int(run.messages[p])},{int(run.bytes[p])}"
            )
    return "\n".join(lines) + "\n"


def _report_text(schedule: Schedule, report: CommsReport, runs: tuple[BackendRun, ...]) -> str:
    n_ticks = len(schedule.ticks_ns)
    total = len(schedule.measured_ns)
    delivered = int((schedule.delivered_tick >= 0).sum())
    out = [
        f"# Replay: {schedule.model}",
        "",
        f"{len(schedule.robots)} robots, {n_ticks} ticks, seed {schedule.seed}"
        + (f", bandwidth {schedule.bandwidth} per link" if schedule.bandwidth else ""),
        f"inter-agent closures: {total} detected, {delivered} delivered, {total - delivered} never",
        "",
        "## Robots",
        "",
    ]
    rows = [
        [name, f"{100 * report.connected_fraction[k]:.1f}", str(int(report.disconnections[k]))]
        for k, name in enumerate(schedule.robots)
    ]
    out.append(_markdown(["robot", "% time connected", "disconnections"], rows))
    pairs = schedule.pairs
    rows = [
        [f"{schedule.robots[a]}-{schedule.robots[b]}", str(int(report.contacts_per_pair[p]))]
        for p, (a, b) in enumerate(pairs.tolist())
    ]
    out += ["## Contacts per pair", "", _markdown(["pair", "contact windows"], rows)]
    if runs:
        out += ["## Back-ends (final)", "", _markdown(list(SUMMARY_COLUMNS), _summary_rows(runs))]
    return "\n".join(out)


def _model_title(model: str) -> str:
    """The comms model as a plot names it: a rendezvous file by its name, not its folder."""
    kind, sep, arg = model.partition(":")
    return f"{kind}:{Path(arg).name}" if sep and kind == "rendezvous" else model


def _two_or_five(value: float, _pos: object = None) -> str:
    """A log axis' minor label: 0.2, 0.5, 2, 5, 20 ... written plainly, the others left out."""
    if value <= 0:
        return ""
    lead = value / 10 ** np.floor(np.log10(value))
    return f"{value:g}" if round(lead) in (2, 5) and abs(lead - round(lead)) < 1e-6 else ""


def _plot(path: Path, runs: tuple[BackendRun, ...], schedule: Schedule, title: str) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.ticker import FuncFormatter, MaxNLocator
    except ImportError:
        return False
    t0 = int(schedule.ticks_ns[0])
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, layout="constrained")
    for k, run in enumerate(runs):
        ts = (schedule.ticks_ns[run.checkpoint_ticks] - t0) / NS_PER_S
        # the first checkpoints (one pose per robot) score 0 or rounding noise: not on a log axis
        few = run.poses_seen.sum(axis=1) <= 3 * len(schedule.robots)
        se3 = np.where(few, np.nan, run.ape_team_se3_m)
        fp = np.where(few, np.nan, run.ape_team_first_pose_m)
        colour = f"C{k % 10}"  # one colour per back-end: solid se3, dashed first-pose
        axes[0].plot(ts, se3, color=colour, label=f"{run.name} (se3)")
        axes[0].plot(ts, fp, color=colour, linestyle="--", linewidth=1.0, label=f"{run.name} (first-pose)")
    axes[0].set_ylabel("team APE mean [m]")
    axes[0].set_yscale("log")
    # decades and their 2s and 5s, as plain numbers (0.2, 5: not 2 x 10^-1, 5 x 10^0)
    axes[0].yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axes[0].yaxis.set_minor_formatter(FuncFormatter(_two_or_five))
    axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the curves, not on them
    axes[0].set_title(title)
    report = comms_report(schedule)
    ts_all = (schedule.ticks_ns - t0) / NS_PER_S
    axes[1].plot(ts_all, report.robots_in_contact, color="tab:purple", label="robots in contact")
    ax2 = axes[1].twinx()
    ax2.plot(ts_all, report.detected, color="grey", linestyle=":", label="closures detected")
    ax2.plot(ts_all, report.delivered, color="black", label="closures delivered")
    axes[1].set_ylabel("robots in contact")
    axes[1].yaxis.set_major_locator(MaxNLocator(integer=True))
    axes[1].set_ylim(bottom=0)  # a count: from zero, so 6 of 8 does not read as none
    ax2.set_ylabel("inter-agent closures")
    axes[1].set_xlabel("time [s]")
    ax2.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.12, 1.0))  # beside the twin axis
    fig.savefig(path, dpi=100, metadata={"Software": None})
    plt.close(fig)
    return True


def _check_backends(backends: tuple[str, ...] | list[str]) -> list[str]:
    names = list(backends)
    if not names:
        raise ConfigError("backend: give at least one back-end")
    for name in names:
        get_backend(name)
    if len(set(names)) != len(names):
        raise ConfigError(f"backend: {names} names one back-end twice")
    outputs = [output_name(n) for n in names]
    if len(set(outputs)) != len(outputs):
        raise ConfigError(f"backend: {names}: two back-ends would write the same outputs {outputs}")
    return names


def _check_numbers(
    *,
    step_s: float,
    every: int,
    period_s: float | None,
    seed: int,
    relinearize_skip: int,
    relinearize_threshold: float,
    final_updates: int,
    time_limit_s: float | None = None,
) -> None:
    """Refuse a bad number among the options (ConfigError naming the option)."""
    if time_limit_s is not None:
        check_option("time_limit", time_limit_s, allow_zero=False)
    check_option("step", step_s, allow_zero=False)
    check_count("every", every)
    if period_s is not None:
        check_option("period", period_s, allow_zero=False)
    check_count("seed", seed, low=0, high=2**63 - 1)
    check_count("relinearize_skip", relinearize_skip)
    check_option("relinearize_threshold", relinearize_threshold)
    check_count("final_updates", final_updates, low=0)


def _rrd_target(rrd: PathLike | None, *, parquet: bool) -> Path | None:
    """The recording's path (``rrd`` must end in ``.rrd``); with ``parquet``, pyarrow must import."""
    rrd_path = None if rrd is None else Path(rrd)
    if rrd_path is not None and rrd_path.suffix != ".rrd":
        raise ConfigError(f"rrd: {rrd_path} must end in .rrd")
    if parquet:
        from studio.io.parquet_table import require_pyarrow

        require_pyarrow()
    return rrd_path


def _model(
    parsed: CommsModel | str, num_robots: int, inputs: list[PathLike], warn: Callable[[str], None] | None = None
) -> CommsModel:
    """The parsed ``--comms``; a rendezvous file (a path, alone or under iMESA's partner cap) is read
    and added to ``inputs``; its lines for robots the dataset does not have are one warning."""
    if isinstance(parsed, PartnerCap) and isinstance(parsed.base, str):
        return dataclasses.replace(parsed, base=_model(parsed.base, num_robots, inputs, warn))
    if not isinstance(parsed, str):
        return parsed
    from studio.io.rendezvous_txt import read_rendezvous

    windows = read_rendezvous(parsed, num_robots, warn=warn)
    inputs.append(parsed)
    return Rendezvous(windows, parsed)


def _times(graph: PoseGraph, dataset: PathLike, period_s: float | None) -> MeasurementTimes:
    try:
        return measurement_times(graph, period_ns=None if period_s is None else round(period_s * NS_PER_S))
    except GraphError as err:
        raise FormatError(f"{dataset}: {err}") from None


def _refuse_existing(targets: list[Path], *, force: bool, inputs: list[PathLike]) -> None:
    """Refuse a bad output before any work."""
    from studio.io.atomic import check_distinct_outputs, check_outputs

    check_distinct_outputs(targets)
    for target in targets:
        absolute = Path(os.path.abspath(target))  # "-o ." is the current folder, named as such
        check_outputs(absolute.parent, [absolute.name], force=force, inputs=inputs)


def _timings_text(runs: tuple[BackendRun, ...]) -> str:
    timing = ["backend,tick,solver_s"] + [
        f"{r.name},{t},{s:.6f}" for r in runs for t, s in zip(r.checkpoint_ticks.tolist(), r.solver_seconds)
    ]
    timing += [f"{r.name},total,{r.seconds:.6f}" for r in runs]
    return "\n".join(timing) + "\n"


def _options(
    dataset: PathLike,
    schedule: Schedule,
    names: list[str],
    settings: IsamSettings,
    kind: str,
    step_s: float,
    every: int,
    period_s: float | None,
) -> dict[str, Any]:
    """The effective options, as ``replay.json`` records them."""
    return {
        "dataset": str(dataset),
        "comms": schedule.model,
        "bandwidth": schedule.bandwidth or None,
        "seed": schedule.seed,
        "step_s": step_s,
        "every": every,
        "period_s": period_s,
        "clock": "pose index x period" if period_s is not None else "dataset stamps",
        "backends": names,
        "isam2": dataclasses.asdict(settings),
        "planar": kind,
    }


def _write_folder(
    folder: Path,
    *,
    dataset: PathLike,
    graph: PoseGraph,
    model: CommsModel,
    schedule: Schedule,
    report: CommsReport,
    runs: tuple[BackendRun, ...],
    options: dict[str, Any],
    parquet: bool = False,
) -> None:
    """Every file of the output folder (module doc) into ``folder``, a new folder in the staging;
    with ``parquet`` each CSV table as Parquet beside it."""
    from studio.io.schedule_csv import write_schedule

    folder.mkdir()
    sched = folder / "schedule"
    sched.mkdir()
    write_schedule(sched, schedule, graph.inter.from_index, graph.inter.to_index)
    windows = model.base if isinstance(model, PartnerCap) else model
    if isinstance(windows, Rendezvous):
        from studio.io.rendezvous_txt import write_rendezvous

        write_rendezvous(sched / "rendezvous.txt", windows.windows_s)
    (folder / "metrics.csv").write_text(_metrics_text(runs, schedule), encoding="utf-8")
    summary = _summary_rows(runs)
    (folder / "summary.csv").write_text(
        "\n".join([",".join(SUMMARY_COLUMNS)] + [",".join(r) for r in summary]) + "\n", encoding="utf-8"
    )
    (folder / "summary.md").write_text(_markdown(list(SUMMARY_COLUMNS), summary), encoding="utf-8")
    _write_results(folder, graph, runs, dataset_name=Path(dataset).name)
    (folder / "links.csv").write_text(_links_text(runs, schedule), encoding="utf-8")
    (folder / "timings.csv").write_text(_timings_text(runs), encoding="utf-8")
    (folder / "report.md").write_text(_report_text(schedule, report, runs), encoding="utf-8")
    (folder / REPLAY_JSON).write_text(
        dumps_strict(options, f"{folder.name}/{REPLAY_JSON}", indent=2) + "\n", encoding="utf-8"
    )
    _plot(folder / "ape.png", runs, schedule, f"{Path(dataset).name}: {_model_title(schedule.model)}")
    if parquet:
        from studio.io.parquet_table import write_parquet_from_csv

        for table in sorted(folder.rglob("*.csv")):
            write_parquet_from_csv(table.with_suffix(".parquet"), table.read_text(encoding="utf-8"))


def _write_results(folder: Path, graph: PoseGraph, runs: tuple[BackendRun, ...], *, dataset_name: str) -> None:
    """``<backend>.jrr`` per back-end (:mod:`studio.io.jrr`): each robot's final estimate of its own
    poses and, for swarm and dgs, of the other robots' poses it keeps, as Symbols of their owners."""
    from studio.core.geometry import planar_poses_to_se3
    from studio.io.jrr import write_jrr
    from studio.io.symbol_g2o import robot_prefix
    from studio.jrl_evaluate import graph_results

    def in_graph_kind(poses: np.ndarray) -> np.ndarray:
        lift = graph.kind is PoseKind.SE3 and poses.shape[1] == 3
        return planar_poses_to_se3(poses) if lift else poses

    sizes = [a.num_poses for a in graph.agents]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    robots = [robot_prefix(k) for k in range(len(sizes))]
    base = np.array([ord(c) << 56 for c in robots], dtype=np.int64)
    for run in runs:
        final = in_graph_kind(run.final_poses)
        own = [final[offsets[k] : offsets[k + 1]] for k in range(len(sizes))]
        shared = None
        if run.final_kept is not None:
            kept = run.final_kept
            owner = np.searchsorted(offsets, kept.vertex, side="right") - 1
            keys = base[owner] + kept.vertex - offsets[owner]
            poses = in_graph_kind(kept.poses)
            shared = [(keys[kept.robot == k], poses[kept.robot == k]) for k in range(len(sizes))]
        results = graph_results(
            graph.kind, robots, own, dataset_name=dataset_name, method_name=f"replay {run.name}", shared=shared
        )
        write_jrr(folder / f"{run.name}.jrr", results)


def _write_recording(
    rrd_path: Path,
    dataset: PathLike,
    graph: PoseGraph,
    schedule: Schedule,
    report: CommsReport,
    runs: tuple[BackendRun, ...],
    vertex_ns: np.ndarray,
    inputs: list[PathLike],
    *,
    force: bool,
) -> None:
    from studio.recording.replay import write_replay_recording

    write_replay_recording(
        rrd_path,
        graph,
        inputs=inputs,
        name=f"{Path(dataset).name} replay ({schedule.model})",
        force=force,
        ticks_ns=schedule.ticks_ns,
        contact=schedule.contact,
        pairs=schedule.pairs,
        closure_from=schedule.closure_from,
        closure_from_index=graph.inter.from_index,
        closure_to=schedule.closure_to,
        closure_to_index=graph.inter.to_index,
        delivered_tick=schedule.delivered_tick,
        robots_in_contact=report.robots_in_contact,
        runs=[(r.name, r.checkpoint_ticks, r.ape_team_se3_m, r.beliefs) for r in runs],
        vertex_ns=vertex_ns,
        sve=[(r.name, r.sve[:, 0]) for r in runs if r.sve is not None],
    )


#: ISAM2's defaults, declared once on :class:`IsamSettings`.
_ISAM = IsamSettings()


def replay(
    dataset: PathLike,
    out: PathLike,
    *,
    comms: str = DEFAULT_COMMS,
    backends: tuple[str, ...] | list[str] = DEFAULT_BACKENDS,
    step_s: float = 1.0,
    every: int = 50,
    period_s: float | None = None,
    seed: int = 0,
    bandwidth: str | None = None,
    relinearize_skip: int = _ISAM.relinearize_skip,
    relinearize_threshold: float = _ISAM.relinearize_threshold,
    final_updates: int = _ISAM.final_updates,
    polish: bool = _ISAM.polish,
    force: bool = False,
    rrd: PathLike | None = None,
    parquet: bool = False,
    time_limit_s: float | None = None,
    progress: Progress | None = None,
    warn: Callable[[str], None] | None = None,
) -> ReplayResult:
    """Replay ``dataset`` (a multi-g2o folder or a g2o file, with ground truth) under the comms model
    ``comms`` through each of ``backends`` and write the outputs into the folder ``out`` (module doc).

    ``step_s``: the tick [s] contacts are evaluated on; ``every``: ticks between checkpoints (the
    metrics' interval and the back-ends' batch of updates); ``period_s``: replace the dataset's
    stamps by pose index x this period (None: the dataset's stamps; kollagen's are 1 s apart);
    ``parquet``: each CSV table as Parquet too (pyarrow; ConfigError before any work without it);
    ``time_limit_s``: the seconds a ``command:`` back-end may take per checkpoint (None: 60)."""
    from studio.io.atomic import staged_outputs

    out, names = Path(out), _check_backends(backends)
    _check_numbers(
        step_s=step_s,
        every=every,
        period_s=period_s,
        seed=seed,
        relinearize_skip=relinearize_skip,
        relinearize_threshold=relinearize_threshold,
        final_updates=final_updates,
        time_limit_s=time_limit_s,
    )
    rrd_path = _rrd_target(rrd, parquet=parquet)
    parsed, band = parse_comms(comms), None if bandwidth is None else parse_bandwidth(bandwidth)
    loaded, graph = _load(dataset, warn)
    inputs: list[PathLike] = [dataset]
    model = _model(parsed, len(graph.agents), inputs, warn)
    times = _times(graph, dataset, period_s)
    settings = IsamSettings(float(relinearize_threshold), relinearize_skip, 0, final_updates, bool(polish))
    _refuse_existing([out] + ([rrd_path] if rrd_path is not None else []), force=force, inputs=inputs)
    schedule = build_schedule(graph, times, model, step_ns=round(step_s * NS_PER_S), seed=seed, bandwidth=band)
    report = comms_report(schedule)
    world = _world(loaded, graph, times, schedule, settings)
    checkpoints = _checkpoints(len(schedule.ticks_ns), every)
    limit = {"time_limit_s": time_limit_s} if time_limit_s is not None else {}
    runs = _run_all(
        names, world, graph, schedule, checkpoints, keep_beliefs=rrd_path is not None, progress=progress, limit=limit
    )
    options = _options(dataset, schedule, names, settings, loaded.problem.kind.value, step_s, every, period_s) | limit
    with staged_outputs(out.parent, [out.name], force=force, inputs=inputs) as staging:
        _write_folder(
            staging / out.name,
            dataset=dataset,
            graph=graph,
            model=model,
            schedule=schedule,
            report=report,
            runs=runs,
            options=options,
            parquet=parquet,
        )
    if rrd_path is not None:
        _write_recording(rrd_path, dataset, graph, schedule, report, runs, world.vertex_ns, inputs, force=force)
    return ReplayResult(out, schedule, report, runs, options, rrd_path)
