"""Rerun recordings of pose graphs: one ``log_<kind>()`` per kind of data, one blueprint.

A recording shows, per agent and in the agent's colour, the ground-truth and initial-estimate
(dead-reckoning) paths, a current-pose marker that moves along the ``node`` timeline (and along
``time`` when the data has real timestamps), intra- and inter-agent loop closures as thin segments on
the ground truth that appear at the node where they are created, and two time series: the position
error of the initial estimate and the number of loop closures so far. Dataset facts are recording
properties; the default layout is saved inside the file.

Everything bulky goes through ``send_columns`` (never one ``log`` call per row). The content depends
only on the dataset: the application id is fixed, the recording id is derived from the graph's
columns, and no clock or host value is logged. Entity paths and timelines are in
:mod:`studio.recording.entities`; exact checks in :mod:`studio.recording.checks`.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import FormatError, OutputError
from studio.core.model import AgentGraph, PoseGraph, PoseKind
from studio.core.progress import Progress, report
from studio.core.units import NS_PER_S
from studio.io.atomic import staged_outputs
from studio.recording.entities import (
    APPLICATION_ID,
    LOOP_CLOSURES_INTER,
    LOOP_CLOSURES_INTRA,
    METRICS,
    PATH_GROUND_TRUTH,
    PATH_INITIAL,
    POSE_GROUND_TRUTH,
    POSE_INITIAL,
    PROPERTY_CONFIG,
    PROPERTY_DATASET,
    SERIES_INTER_LOOP_CLOSURES,
    SERIES_LOOP_CLOSURES,
    SERIES_POSITION_ERROR,
    TIMELINE_NODE,
    TIMELINE_TIME,
    WORLD,
)

if TYPE_CHECKING:
    import rerun as rr
    import rerun.blueprint as rrb

__all__ = [
    "RecordResult",
    "record_graph",
    "record_dataset",
    "default_blueprint",
    "recording_id_for",
    "has_real_stamps",
]

#: Rows per chunk for time-indexed line strips (``rerun rrd verify`` is quadratic in it).
STRIP_CHUNK_ROWS = 1000

_PALETTE = np.array(
    [  # Tableau 10
        [31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
        [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207],
    ],
    dtype=np.uint8,
)
_INTER_COLOUR = (235, 235, 235, 255)
_PATH_RADIUS = -1.5  # negative: screen-space points
_LOOP_RADIUS = -0.75
_INTER_RADIUS = -1.0
_RECORDING_ID_NAMESPACE = uuid.UUID("6c1b3f0e-2f4c-4a8e-9a59-5f0d8a1c7e21")


def agent_colour(k: int) -> tuple[int, int, int, int]:
    """The colour of the k-th agent (RGBA, 0-255)."""
    r, g, b = (int(v) for v in _PALETTE[k % len(_PALETTE)])
    return (r, g, b, 255)


def _initial_colour(k: int) -> tuple[int, int, int, int]:
    r, g, b, _ = agent_colour(k)
    return (r, g, b, 110)


def _path(template: str, agent: AgentGraph) -> str:
    return template.format(agent=agent.name)


@dataclass(frozen=True, eq=False)
class RecordResult:
    path: Path
    recording_id: str
    num_poses: int
    edge_counts: dict[str, int]
    real_time: bool
    """True when a ``time`` timeline was logged."""


@dataclass(frozen=True)
class _Scene:
    """The derived quantities the blueprint needs."""

    names: tuple[str, ...]
    planar: bool
    centre_xyz: tuple[float, float, float]
    extent_m: float
    num_nodes: int
    real_time: bool
    inter: bool = field(default=True)
    max_position_error_m: float = 1.0
    max_loop_closures: int = 1


# --------------------------------------------------------------------------------------------------
# Determinism


def recording_id_for(graph: PoseGraph) -> str:
    """A UUID derived from the graph's columns (SE3 form): the same dataset gives the same id."""
    g = graph.to_se3()
    h = hashlib.sha256()

    def add(arr: np.ndarray | None) -> None:
        if arr is None:
            h.update(b"none")
        else:
            a = np.ascontiguousarray(arr)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())

    for a in g.agents:
        h.update(a.name.encode() + b"\0")
        for col in (a.stamps_ns, a.initial, a.ground_truth):
            add(col)
        for e in (a.odometry, a.loop_closures):
            add(e.from_index)
            add(e.to_index)
    for col in (g.inter.from_agent, g.inter.from_index, g.inter.to_agent, g.inter.to_index):
        add(col)
    return str(uuid.uuid5(_RECORDING_ID_NAMESPACE, h.hexdigest()))


def has_real_stamps(graph: PoseGraph) -> bool:
    """False for synthetic stamps (node index in seconds in every agent), True otherwise."""
    return any(not np.array_equal(a.stamps_ns, np.arange(a.num_poses, dtype=np.int64) * NS_PER_S) for a in graph.agents)


def _is_planar(graph: PoseGraph) -> bool:
    if graph.kind is PoseKind.SE2:
        return True
    for a in graph.agents:
        for poses in (a.initial, a.ground_truth):
            if poses is not None and np.any(poses[:, 2] != 0.0):
                return False
    return True


def _reference(agent: AgentGraph) -> np.ndarray:
    """The poses loop closures are drawn on: ground truth, else the initial estimate."""
    return agent.ground_truth if agent.ground_truth is not None else agent.initial


# --------------------------------------------------------------------------------------------------
# Logging, one function per kind of data (the graph is SE3 here)


def _index_columns(agent: AgentGraph, rows: np.ndarray, real_time: bool) -> list:
    import rerun as rr

    cols = [rr.TimeColumn(TIMELINE_NODE, sequence=rows)]
    if real_time:
        cols.append(rr.TimeColumn(TIMELINE_TIME, timestamp=agent.stamps_ns[rows].astype("datetime64[ns]")))
    return cols


def log_properties(rec: rr.RecordingStream, graph: PoseGraph, name: str, config_json: str | None) -> None:
    """Dataset facts (agent count, nodes, edges of each kind, pose kind) and the config that made it."""
    import rerun as rr

    counts = graph.edge_counts()
    rec.send_recording_name(name)
    rec.send_property(
        PROPERTY_DATASET,
        rr.AnyValues(
            name=name,
            pose_kind=graph.kind.value,
            agents=len(graph.agents),
            agent_names=[a.name for a in graph.agents],
            nodes=graph.num_poses,
            nodes_per_agent=np.array([a.num_poses for a in graph.agents], dtype=np.int64),
            odometry_edges=counts["odometry"],
            intra_loop_closures=counts["intra_loop_closures"],
            inter_loop_closures=counts["inter_loop_closures"],
        ),
    )
    if config_json is not None:
        rec.send_property(PROPERTY_CONFIG, rr.AnyValues(json=config_json))


def log_world(rec: rr.RecordingStream) -> None:
    """The world frame: right-handed, z up (planar data lies in z = 0)."""
    import rerun as rr

    rec.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)


def log_paths(rec: rr.RecordingStream, agent: AgentGraph, k: int) -> None:
    """The whole ground-truth and initial-estimate paths, static (one strip each)."""
    import rerun as rr

    if agent.ground_truth is not None:
        rec.log(_path(PATH_GROUND_TRUTH, agent),
                rr.LineStrips3D([agent.ground_truth[:, 0:3]], colors=[agent_colour(k)], radii=_PATH_RADIUS),
                static=True)
    rec.log(_path(PATH_INITIAL, agent),
            rr.LineStrips3D([agent.initial[:, 0:3]], colors=[_initial_colour(k)], radii=_PATH_RADIUS),
            static=True)


def log_current_pose(rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool,
                     axis_length: float) -> None:
    """A marker with axes at the current ground-truth pose and a dot at the current initial estimate."""
    import rerun as rr

    rows = np.arange(agent.num_poses)
    index = _index_columns(agent, rows, real_time)
    targets = [(POSE_INITIAL, agent.initial, _initial_colour(k), False)]
    if agent.ground_truth is not None:
        targets.insert(0, (POSE_GROUND_TRUTH, agent.ground_truth, agent_colour(k), True))
    for template, poses, colour, axes in targets:
        entity = _path(template, agent)
        rec.log(entity, rr.Points3D([[0.0, 0.0, 0.0]], colors=[colour], radii=-5.0 if axes else -4.0), static=True)
        if axes:
            rec.log(entity, rr.TransformAxes3D(axis_length), static=True)
        rec.send_columns(
            entity, index,
            rr.Transform3D.columns(translation=poses[:, 0:3], quaternion=poses[:, 3:7]),
        )


def _send_segments(rec: rr.RecordingStream, entity: str, segments: np.ndarray, nodes: np.ndarray,
                   stamps_ns: np.ndarray | None) -> None:
    """Time-indexed segments, one per row, in chunks of :data:`STRIP_CHUNK_ROWS` rows."""
    import rerun as rr

    for start in range(0, len(segments), STRIP_CHUNK_ROWS):
        sl = slice(start, start + STRIP_CHUNK_ROWS)
        index = [rr.TimeColumn(TIMELINE_NODE, sequence=nodes[sl])]
        if stamps_ns is not None:
            index.append(rr.TimeColumn(TIMELINE_TIME, timestamp=stamps_ns[sl].astype("datetime64[ns]")))
        rec.send_columns(entity, index, rr.LineStrips3D.columns(strips=segments[sl]))


def log_intra_loop_closures(rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool) -> None:
    """Intra-agent loop closures as segments on the reference poses, at the later of their two nodes."""
    import rerun as rr

    lc = agent.loop_closures
    if len(lc) == 0:
        return
    ref = _reference(agent)[:, 0:3]
    created = np.maximum(lc.from_index, lc.to_index)
    order = np.argsort(created, kind="stable")
    segments = np.stack([ref[lc.from_index[order]], ref[lc.to_index[order]]], axis=1)
    entity = _path(LOOP_CLOSURES_INTRA, agent)
    rec.log(entity, rr.LineStrips3D.from_fields(colors=[agent_colour(k)], radii=_LOOP_RADIUS), static=True)
    _send_segments(rec, entity, segments, created[order], agent.stamps_ns[created[order]] if real_time else None)


def log_inter_loop_closures(rec: rr.RecordingStream, graph: PoseGraph, real_time: bool) -> None:
    """Inter-agent loop closures in a distinct colour, at the later of their two nodes."""
    import rerun as rr

    inter = graph.inter
    if len(inter) == 0:
        return
    refs = [_reference(a)[:, 0:3] for a in graph.agents]
    offsets = np.concatenate([[0], np.cumsum([a.num_poses for a in graph.agents])])
    ref_all = np.concatenate(refs)
    stamps_all = np.concatenate([a.stamps_ns for a in graph.agents])
    g_from = offsets[inter.from_agent] + inter.from_index
    g_to = offsets[inter.to_agent] + inter.to_index
    created = np.maximum(inter.from_index, inter.to_index)
    order = np.argsort(created, kind="stable")
    segments = np.stack([ref_all[g_from[order]], ref_all[g_to[order]]], axis=1)
    # On `time`, the later of the two stamps (rows stay in node order; Rerun sorts each timeline).
    stamps = np.maximum(stamps_all[g_from], stamps_all[g_to])[order] if real_time else None
    rec.log(LOOP_CLOSURES_INTER, rr.LineStrips3D.from_fields(colors=[_INTER_COLOUR], radii=_INTER_RADIUS),
            static=True)
    _send_segments(rec, LOOP_CLOSURES_INTER, segments, created[order], stamps)


def log_position_error(rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool) -> None:
    """|initial - ground truth| position per node (nothing when the agent has no ground truth)."""
    import rerun as rr

    if agent.ground_truth is None:
        return
    entity = _path(SERIES_POSITION_ERROR, agent)
    error = np.linalg.norm(agent.initial[:, 0:3] - agent.ground_truth[:, 0:3], axis=1)
    rec.log(entity, rr.SeriesLines(colors=[agent_colour(k)], names=[agent.name]), static=True)
    rec.send_columns(entity, _index_columns(agent, np.arange(agent.num_poses), real_time),
                     rr.Scalars.columns(scalars=error))


def _count_so_far(created: np.ndarray, n: int) -> np.ndarray:
    return np.cumsum(np.bincount(created, minlength=n)[:n]).astype(np.float64)


def log_loop_closure_counts(rec: rr.RecordingStream, graph: PoseGraph, real_time: bool) -> None:
    """Loop closures created so far: intra-agent per agent, and inter-agent over all agents."""
    import rerun as rr

    for k, agent in enumerate(graph.agents):
        lc = agent.loop_closures
        entity = _path(SERIES_LOOP_CLOSURES, agent)
        counts = _count_so_far(np.maximum(lc.from_index, lc.to_index), agent.num_poses)
        rec.log(entity, rr.SeriesLines(colors=[agent_colour(k)], names=[agent.name]), static=True)
        rec.send_columns(entity, _index_columns(agent, np.arange(agent.num_poses), real_time),
                         rr.Scalars.columns(scalars=counts))
    if len(graph.inter):
        n = max(a.num_poses for a in graph.agents)
        counts = _count_so_far(np.maximum(graph.inter.from_index, graph.inter.to_index), n)
        rec.log(SERIES_INTER_LOOP_CLOSURES,
                rr.SeriesLines(colors=[_INTER_COLOUR], names=["inter-agent"]), static=True)
        # The node timeline only: nodes of different agents have different stamps.
        rec.send_columns(SERIES_INTER_LOOP_CLOSURES, [rr.TimeColumn(TIMELINE_NODE, sequence=np.arange(n))],
                         rr.Scalars.columns(scalars=counts))


# --------------------------------------------------------------------------------------------------
# Blueprint


def _scene(graph: PoseGraph, real_time: bool) -> _Scene:
    pts = np.concatenate([p[:, 0:3] for a in graph.agents for p in (a.initial, a.ground_truth) if p is not None])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    extent = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0))
    errors = [float(np.max(np.linalg.norm(a.initial[:, 0:3] - a.ground_truth[:, 0:3], axis=1)))
              for a in graph.agents if a.ground_truth is not None]
    most_lcs = max([len(a.loop_closures) for a in graph.agents] + [len(graph.inter), 1])
    return _Scene(
        names=tuple(a.name for a in graph.agents),
        planar=_is_planar(graph),
        centre_xyz=(float(centre[0]), float(centre[1]), float(centre[2])),
        extent_m=extent,
        num_nodes=max(a.num_poses for a in graph.agents),
        real_time=real_time,
        inter=len(graph.inter) > 0,
        max_position_error_m=max(errors + [1e-3]),
        max_loop_closures=most_lcs,
    )


def _fixed_ids(part, label: str) -> None:
    """Blueprint parts get random ids by default; derive them from their role instead."""
    part.id = uuid.uuid5(_RECORDING_ID_NAMESPACE, f"blueprint/{label}")


def default_blueprint(scene: _Scene) -> rrb.Blueprint:
    """The layout saved in every recording: 3D view of all agents, time series beside it, time panel
    on ``node``, paused. Planar data is seen from straight above."""
    import rerun as rr
    import rerun.blueprint as rrb

    timelines = [TIMELINE_NODE] + ([TIMELINE_TIME] if scene.real_time else [])
    upto_cursor = [
        rrb.VisibleTimeRange(t, start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.cursor_relative())
        for t in timelines
    ]
    cx, cy, cz = scene.centre_xyz
    if scene.planar:
        eye = rrb.EyeControls3D(position=(cx, cy, cz + 1.1 * scene.extent_m), look_target=(cx, cy, cz),
                                eye_up=(0.0, 1.0, 0.0))
    else:
        d = 0.9 * scene.extent_m
        eye = rrb.EyeControls3D(position=(cx - d, cy - d, cz + d), look_target=(cx, cy, cz), eye_up=(0.0, 0.0, 1.0))
    # Everything up to the cursor: loop closures accumulate (paths are static, and transforms are
    # always resolved at the cursor, so the pose markers do not leave a trail).
    space = rrb.Spatial3DView(origin=f"/{WORLD}", name="agents", eye_controls=eye, time_ranges=upto_cursor,
                              line_grid=rrb.LineGrid3D(visible=False))
    whole = rr.TimeRange(start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.infinite())
    # Fixed y ranges: the whole series is visible whatever the cursor (auto-fit follows the view).
    err = rrb.TimeSeriesView(origin=f"/{METRICS}/position_error", name="initial-estimate position error [m]",
                             axis_x=rrb.TimeAxis(view_range=whole),
                             axis_y=rrb.ScalarAxis(range=(0.0, 1.05 * scene.max_position_error_m)))
    lcs = rrb.TimeSeriesView(origin=f"/{METRICS}/loop_closures", name="loop closures so far",
                             axis_x=rrb.TimeAxis(view_range=whole),
                             axis_y=rrb.ScalarAxis(range=(0.0, 1.05 * scene.max_loop_closures)))
    series = rrb.Vertical(err, lcs)
    root = rrb.Horizontal(space, series, column_shares=[2, 1])
    for part, label in ((space, "agents"), (err, "position_error"), (lcs, "loop_closures"),
                        (series, "series"), (root, "root")):
        _fixed_ids(part, label)
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline=TIMELINE_NODE, play_state="paused", expanded=True),
        rrb.BlueprintPanel(expanded=False),
        rrb.SelectionPanel(expanded=False),
        auto_views=False,
    )


# --------------------------------------------------------------------------------------------------
# Library entry points


def record_graph(graph: PoseGraph, path: str | os.PathLike, *, name: str,
                 config_json: str | None = None, progress: Progress | None = None) -> RecordResult:
    """Log ``graph`` to a new ``.rrd`` at ``path`` (written in place; see :func:`record_dataset`)."""
    import rerun as rr

    path = Path(path)
    g = graph.to_se3()
    real_time = has_real_stamps(g)
    scene = _scene(g, real_time)
    rid = recording_id_for(g)  # the id is computed on the SE3 form anyway: lift once
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid, send_properties=False)
    try:
        rec.save(path, default_blueprint=default_blueprint(scene))
        log_properties(rec, graph, name, config_json)
        log_world(rec)
        axis_length = 0.04 * scene.extent_m
        steps = len(g.agents) + 1
        report(progress, "recording", 0, steps, "parts")
        for k, agent in enumerate(g.agents):
            log_paths(rec, agent, k)
            log_current_pose(rec, agent, k, real_time, axis_length)
            log_intra_loop_closures(rec, agent, k, real_time)
            log_position_error(rec, agent, k, real_time)
            report(progress, "recording", k + 1, steps, "parts")
        log_inter_loop_closures(rec, g, real_time)
        log_loop_closure_counts(rec, g, real_time)
        report(progress, "recording", steps, steps, "parts")
    finally:
        rec.disconnect()
    return RecordResult(path, rid, graph.num_poses, graph.edge_counts(), real_time)


def _sibling_config(dataset: Path) -> str | None:
    cfg = dataset.parent / f"{dataset.name}.config.json"
    if not cfg.is_file():
        return None
    try:
        return json.dumps(json.loads(cfg.read_text(encoding="utf-8")), sort_keys=True)
    except (OSError, ValueError) as err:
        raise FormatError(f"{cfg}: not a readable JSON config ({err})") from None


def record_dataset(dataset: str | os.PathLike, out: str | os.PathLike, *, force: bool = False,
                   progress: Progress | None = None) -> RecordResult:
    """Read a multi-g2o folder (ours or kollagen's) and write its recording to ``out`` atomically.

    The config beside the dataset (``<dataset>.config.json``, as ``studio synth`` writes it) becomes
    the ``config`` property when present. Bad input raises before anything is written.
    """
    from studio.io.multig2o import read_multi_g2o

    dataset, out = Path(dataset), Path(out)
    if out.suffix != ".rrd":
        raise OutputError(f"{out}: a recording must end in .rrd")
    report(progress, "reading", 0, 1, "datasets")
    graph = read_multi_g2o(dataset)
    report(progress, "reading", 1, 1, "datasets")
    config_json = _sibling_config(dataset)
    name = dataset.resolve().name
    with staged_outputs(out.parent, [out.name], force=force) as staging:
        res = record_graph(graph, staging / out.name, name=name, config_json=config_json, progress=progress)
    return RecordResult(out, res.recording_id, res.num_poses, res.edge_counts, res.real_time)
