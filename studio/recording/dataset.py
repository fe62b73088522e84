"""Rerun recordings of pose graphs: one ``log_<kind>()`` per kind of data, one blueprint.

A recording shows, per agent and in the agent's colour, the ground-truth path (solid) and the
initial-estimate (dead-reckoning) path (same hue, thinner and translucent), a current-pose marker
that moves along the ``node`` timeline (and along ``time`` when the data has real timestamps),
intra-agent loop closures per agent, inter-agent loop closures in one entity per agent pair (a grey
that shows on dark and light themes; thinner and more translucent above
:data:`MANY_INTER_LOOP_CLOSURES`), outlier loop closures (``outliers.txt``) in their own entity and
colour, all as segments on the ground truth that appear at the node where they are created, and
three plots: the position error of the initial estimate, intra-agent loop closures so far per agent,
and inter-agent loop closures so far. Dataset facts are recording properties (``pose_kind`` is
``SE2`` for planar data, whichever way it was read); the default layout is saved inside the file.

Everything bulky goes through ``send_columns`` (never one ``log`` call per row). The content depends
only on the dataset: the application id is fixed, the recording id is derived from the graph's
columns, and no clock or host value is logged. Entity paths and timelines are in
:mod:`studio.recording.entities`; exact checks in :mod:`studio.recording.rrd_checks`.
"""

from __future__ import annotations

import hashlib
import json
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from studio.core.errors import FormatError, OutputError
from studio.core.geometry import is_planar_se3
from studio.core.model import AgentGraph, PoseGraph, PoseKind, RangeBearing
from studio.core.types import PathLike
from studio.core.units import MAX_RECORDED_COORDINATE_M, NS_PER_S
from studio.io.atomic import check_not_overlapping, staged_outputs
from studio.recording.colours import (
    AGENT_PALETTE_RGB,
    INITIAL_ALPHA,
    INTER_ALPHA,
    INTER_DENSITY_RGBA,
    INTER_FAINT_ALPHA,
    INTER_FAINT_RGB,
    INTER_RGB,
    OUTLIER_COLOUR,
)
from studio.recording.entities import (
    APPLICATION_ID,
    INTER_LOOP_CLOSURE_DENSITY,
    LOOP_CLOSURES_INTER,
    LOOP_CLOSURES_INTRA,
    LOOP_CLOSURES_OUTLIERS,
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
    SIGHTINGS,
    TIMELINE_NODE,
    TIMELINE_TIME,
    WORLD,
)
from studio.recording.sink import closing, write_bounded
from studio.runtime.interrupts import interrupts_deferred
from studio.runtime.progress import Progress, report

if TYPE_CHECKING:
    import rerun as rr
    import rerun.blueprint as rrb

__all__ = [
    "MANY_INTER_LOOP_CLOSURES",
    "fixed_id",
    "is_planar_graph",
    "hash_columns",
    "RecordResult",
    "inter_pair_path",
    "inter_style",
    "pose_kind_of",
    "read_outliers",
    "record_graph",
    "record_dataset",
    "log_range_bearing",
    "default_blueprint",
    "recording_id_for",
    "has_real_stamps",
]

#: Rows per chunk for time-indexed line strips (``rerun rrd verify`` is quadratic in it).
STRIP_CHUNK_ROWS = 1000

#: Above this many inter-agent loop closures the segments (hidden by default, one entity per pair)
#: give way to their density (:func:`log_inter_loop_closure_density`).
MANY_INTER_LOOP_CLOSURES = 3000
#: The density's grid: this many cells across the extent of the closures (where the agents meet).
DENSITY_CELLS_ACROSS = 30
#: The density's discs, in cells: the fullest cell's disc has a radius of one cell (neighbouring
#: full cells merge into a patch), an emptier one the area of its share of that count, down to this.
DENSITY_MIN_RADIUS_CELLS = 0.2
_PATH_RADIUS = -1.5  # negative: screen-space points
_INITIAL_RADIUS = -0.75
_LOOP_RADIUS = -0.75
_OUTLIER_RADIUS = -1.5
_RECORDING_ID_NAMESPACE = uuid.UUID("6c1b3f0e-2f4c-4a8e-9a59-5f0d8a1c7e21")


def agent_colour(k: int) -> tuple[int, int, int, int]:
    """The colour of the k-th agent (RGBA, 0-255)."""
    r, g, b = AGENT_PALETTE_RGB[k % len(AGENT_PALETTE_RGB)]
    return (r, g, b, 255)


def _initial_colour(k: int) -> tuple[int, int, int, int]:
    """The estimate's colour: the agent's hue, translucent (the ground truth is opaque)."""
    r, g, b, _ = agent_colour(k)
    return (r, g, b, INITIAL_ALPHA)


def inter_style(count: int) -> tuple[tuple[int, int, int, int], float]:
    """Colour and radius of inter-agent loop closures: fainter and thinner when there are many."""
    if count > MANY_INTER_LOOP_CLOSURES:
        return (*INTER_FAINT_RGB, INTER_FAINT_ALPHA), -0.5
    return (*INTER_RGB, INTER_ALPHA), -1.0


def _path(template: str, agent: AgentGraph) -> str:
    import rerun as rr

    return template.format(agent=rr.escape_entity_path_part(agent.name))  # spaces, "/", non-ASCII: one part


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
    """Most intra-agent loop closures of one agent."""
    max_inter_loop_closures: int = 1
    many_inter: bool = False
    """More inter-agent loop closures than :data:`MANY_INTER_LOOP_CLOSURES`: drawn as their density."""


# --------------------------------------------------------------------------------------------------
# Determinism


def recording_id_for(graph: PoseGraph) -> str:
    """A UUID derived from the graph's columns (SE3 form): the same dataset gives the same id."""
    g = graph.to_se3()
    h = hashlib.sha256()
    for a in g.agents:
        h.update(a.name.encode() + b"\0")
        hash_columns(h, a.stamps_ns, a.initial, a.ground_truth)
        for e in (a.odometry, a.loop_closures):
            hash_columns(h, e.from_index, e.to_index)
    hash_columns(h, g.inter.from_agent, g.inter.from_index, g.inter.to_agent, g.inter.to_index)
    return str(uuid.uuid5(_RECORDING_ID_NAMESPACE, h.hexdigest()))


def hash_columns(h: Any, *columns: np.ndarray | None) -> None:
    """Feed each column to the hash ``h`` (hashlib): its dtype, shape and bytes, or ``none`` for a
    missing one. The recording ids derived from content (dataset, evaluation, solve) all use it."""
    for col in columns:
        if col is None:
            h.update(b"none")
            continue
        a = np.ascontiguousarray(col)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())


def has_real_stamps(graph: PoseGraph) -> bool:
    """False for synthetic stamps (node index in seconds in every agent), True otherwise."""
    return any(not np.array_equal(a.stamps_ns, np.arange(a.num_poses, dtype=np.int64) * NS_PER_S) for a in graph.agents)


def is_planar_graph(graph: PoseGraph) -> bool:
    """SE2 graphs, and SE3 graphs whose poses all lie in z = 0 and turn about z only."""
    if graph.kind is PoseKind.SE2:
        return True
    return all(
        is_planar_se3(poses, tolerance=0.0)
        for a in graph.agents
        for poses in (a.initial, a.ground_truth)
        if poses is not None
    )


def pose_kind_of(graph: PoseGraph) -> PoseKind:
    """The pose kind a recording states: SE2 for planar data whether it was read from 2D or 3D
    records (kollagen writes its planar graphs as 3D records), SE3 otherwise."""
    return PoseKind.SE2 if is_planar_graph(graph) else PoseKind.SE3


def _edge_keys(
    a_from: np.ndarray, v_from: np.ndarray, a_to: np.ndarray, v_to: np.ndarray, n_agents: int, n_nodes: int
) -> np.ndarray:
    """One int64 per edge, the same whichever way round the edge is written."""
    f = a_from.astype(np.int64) * n_nodes + v_from
    t = a_to.astype(np.int64) * n_nodes + v_to
    lo, hi = np.minimum(f, t), np.maximum(f, t)
    keys: np.ndarray = lo * (n_agents * n_nodes) + hi
    return keys


def _outlier_masks(graph: PoseGraph, outliers: np.ndarray | None) -> tuple[list[np.ndarray], np.ndarray]:
    """Per agent, which intra-agent loop closures are outliers; and which inter-agent ones are."""
    intra = [np.zeros(len(a.loop_closures), dtype=bool) for a in graph.agents]
    inter = np.zeros(len(graph.inter), dtype=bool)
    if outliers is None or len(outliers) == 0:
        return intra, inter
    n_agents = len(graph.agents)
    n_nodes = max(a.num_poses for a in graph.agents)
    o = np.asarray(outliers, dtype=np.int64).reshape(-1, 4)
    keys = _edge_keys(o[:, 0], o[:, 1], o[:, 2], o[:, 3], n_agents, n_nodes)
    for k, a in enumerate(graph.agents):
        lc = a.loop_closures
        ka = np.full(len(lc), k, dtype=np.int64)
        intra[k] = np.isin(_edge_keys(ka, lc.from_index, ka, lc.to_index, n_agents, n_nodes), keys)
    e = graph.inter
    inter = np.isin(_edge_keys(e.from_agent, e.from_index, e.to_agent, e.to_index, n_agents, n_nodes), keys)
    return intra, inter


def _reference(agent: AgentGraph) -> np.ndarray:
    """The poses loop closures are drawn on: ground truth, else the initial estimate."""
    return agent.ground_truth if agent.ground_truth is not None else agent.initial


# --------------------------------------------------------------------------------------------------
# Logging, one function per kind of data (the graph is SE3 here)


def _index_columns(agent: AgentGraph, rows: np.ndarray, real_time: bool) -> list[Any]:
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
            pose_kind=pose_kind_of(graph).value,
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
        rec.log(
            _path(PATH_GROUND_TRUTH, agent),
            rr.LineStrips3D([agent.ground_truth[:, 0:3]], colors=[agent_colour(k)], radii=_PATH_RADIUS),
            static=True,
        )
    rec.log(
        _path(PATH_INITIAL, agent),
        rr.LineStrips3D([agent.initial[:, 0:3]], colors=[_initial_colour(k)], radii=_INITIAL_RADIUS),
        static=True,
    )


def log_current_pose(rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool, axis_length: float) -> None:
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
            entity,
            index,
            rr.Transform3D.columns(translation=poses[:, 0:3], quaternion=poses[:, 3:7]),
        )


def _send_segments(
    rec: rr.RecordingStream, entity: str, segments: np.ndarray, nodes: np.ndarray, stamps_ns: np.ndarray | None
) -> None:
    """Time-indexed segments, one per row, in chunks of :data:`STRIP_CHUNK_ROWS` rows."""
    import rerun as rr

    for start in range(0, len(segments), STRIP_CHUNK_ROWS):
        sl = slice(start, start + STRIP_CHUNK_ROWS)
        index = [rr.TimeColumn(TIMELINE_NODE, sequence=nodes[sl])]
        if stamps_ns is not None:
            index.append(rr.TimeColumn(TIMELINE_TIME, timestamp=stamps_ns[sl].astype("datetime64[ns]")))
        rec.send_columns(entity, index, rr.LineStrips3D.columns(strips=segments[sl]))


def log_intra_loop_closures(
    rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool, outlier: np.ndarray | None = None
) -> None:
    """Intra-agent loop closures (inliers: ``outlier`` marks the others) as segments on the reference
    poses, at the later of their two nodes."""
    import rerun as rr

    lc = agent.loop_closures
    keep = np.ones(len(lc), dtype=bool) if outlier is None else ~outlier
    if not keep.any():
        return
    ref = _reference(agent)[:, 0:3]
    created = np.maximum(lc.from_index, lc.to_index)
    order = np.flatnonzero(keep)[np.argsort(created[keep], kind="stable")]
    segments = np.stack([ref[lc.from_index[order]], ref[lc.to_index[order]]], axis=1)
    entity = _path(LOOP_CLOSURES_INTRA, agent)
    rec.log(entity, rr.LineStrips3D.from_fields(colors=[agent_colour(k)], radii=_LOOP_RADIUS), static=True)
    _send_segments(rec, entity, segments, created[order], agent.stamps_ns[created[order]] if real_time else None)


def inter_pair_path(graph: PoseGraph, a: int, b: int) -> str:
    """The entity of the inter-agent loop closures between agents ``a < b``."""
    import rerun as rr

    pair = rr.escape_entity_path_part(f"{graph.agents[a].name}-{graph.agents[b].name}")
    return LOOP_CLOSURES_INTER.format(pair=pair)


def _global_rows(graph: PoseGraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference positions and stamps of every node, and the row offset of each agent."""
    offsets = np.concatenate([[0], np.cumsum([a.num_poses for a in graph.agents])])
    ref_all = np.concatenate([_reference(a)[:, 0:3] for a in graph.agents])
    stamps_all = np.concatenate([a.stamps_ns for a in graph.agents])
    return ref_all, stamps_all, offsets


def log_inter_loop_closures(
    rec: rr.RecordingStream, graph: PoseGraph, real_time: bool, outlier: np.ndarray | None = None
) -> None:
    """Inter-agent loop closures (inliers), one entity per agent pair so each pair can be hidden, at
    the later of their two nodes; grey, and thin and faint when there are many."""
    import rerun as rr

    inter = graph.inter
    keep = np.ones(len(inter), dtype=bool) if outlier is None else ~outlier
    if not keep.any():
        return
    ref_all, stamps_all, offsets = _global_rows(graph)
    colour, radius = inter_style(int(np.count_nonzero(keep)))
    lo = np.minimum(inter.from_agent, inter.to_agent)
    hi = np.maximum(inter.from_agent, inter.to_agent)
    for a, b in sorted(set(zip(lo[keep].tolist(), hi[keep].tolist()))):
        rows = np.flatnonzero(keep & (lo == a) & (hi == b))
        g_from = offsets[inter.from_agent[rows]] + inter.from_index[rows]
        g_to = offsets[inter.to_agent[rows]] + inter.to_index[rows]
        created = np.maximum(inter.from_index[rows], inter.to_index[rows])
        order = np.argsort(created, kind="stable")
        segments = np.stack([ref_all[g_from[order]], ref_all[g_to[order]]], axis=1)
        # On `time`, the later of the two stamps (rows stay in node order; Rerun sorts each timeline).
        stamps = np.maximum(stamps_all[g_from], stamps_all[g_to])[order] if real_time else None
        entity = inter_pair_path(graph, a, b)
        rec.log(entity, rr.LineStrips3D.from_fields(colors=[colour], radii=radius), static=True)
        _send_segments(rec, entity, segments, created[order], stamps)


def closure_density(
    midpoints_xyz: np.ndarray, extent_m: float, cells_across: int = DENSITY_CELLS_ACROSS
) -> tuple[np.ndarray, np.ndarray]:
    """Bin closure midpoints on a square grid of ``extent_m / cells_across`` cells (x, y; z too for
    spatial data): per occupied cell, the mean position of its closures and their count, in the
    order of the cells' indices (deterministic)."""
    cell_m = max(extent_m, 1e-9) / cells_across
    keys = np.floor(midpoints_xyz / cell_m).astype(np.int64)
    cells, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.zeros((len(cells), 3))
    np.add.at(sums, inverse, midpoints_xyz)
    return sums / counts[:, None], counts


def log_inter_loop_closure_density(
    rec: rr.RecordingStream, graph: PoseGraph, extent_m: float, last_node: int, outlier: np.ndarray | None = None
) -> None:
    """Many inter-agent loop closures (inliers) as their density: a grey disc per grid cell where
    closures are, its area growing with their count, at ``last_node`` (the recording opens there)."""
    import rerun as rr

    inter = graph.inter
    keep = np.ones(len(inter), dtype=bool) if outlier is None else ~outlier
    if not keep.any():
        return
    ref_all, _, offsets = _global_rows(graph)
    g_from = offsets[inter.from_agent[keep]] + inter.from_index[keep]
    g_to = offsets[inter.to_agent[keep]] + inter.to_index[keep]
    mid = 0.5 * (ref_all[g_from] + ref_all[g_to])
    across_m = float(np.max(np.ptp(mid, axis=0))) or 1.0
    centres, counts = closure_density(mid, across_m)
    cell_m = across_m / DENSITY_CELLS_ACROSS
    radii = cell_m * np.maximum(np.sqrt(counts / counts.max()), DENSITY_MIN_RADIUS_CELLS)
    centres = centres + [0.0, 0.0, 0.02 * extent_m]  # above the paths, so the view draws it on top
    rec.set_time(TIMELINE_NODE, sequence=last_node)
    rec.log(
        INTER_LOOP_CLOSURE_DENSITY,
        rr.Points3D(centres, radii=radii.astype(np.float32), colors=[INTER_DENSITY_RGBA]),
    )
    rec.reset_time()


def log_outlier_loop_closures(
    rec: rr.RecordingStream, graph: PoseGraph, real_time: bool, intra: list[np.ndarray], inter: np.ndarray
) -> None:
    """The loop closures ``outliers.txt`` lists, intra- and inter-agent, in magenta in one entity."""
    import rerun as rr

    ref_all, stamps_all, offsets = _global_rows(graph)
    g_from, g_to, created = [], [], []
    for k, a in enumerate(graph.agents):
        lc = a.loop_closures
        g_from.append(offsets[k] + lc.from_index[intra[k]])
        g_to.append(offsets[k] + lc.to_index[intra[k]])
        created.append(np.maximum(lc.from_index, lc.to_index)[intra[k]])
    e = graph.inter
    g_from.append(offsets[e.from_agent[inter]] + e.from_index[inter])
    g_to.append(offsets[e.to_agent[inter]] + e.to_index[inter])
    created.append(np.maximum(e.from_index, e.to_index)[inter])
    f, t, c = (np.concatenate(x).astype(np.int64) for x in (g_from, g_to, created))
    if len(f) == 0:
        return
    order = np.argsort(c, kind="stable")
    segments = np.stack([ref_all[f[order]], ref_all[t[order]]], axis=1)
    stamps = np.maximum(stamps_all[f], stamps_all[t])[order] if real_time else None
    rec.log(
        LOOP_CLOSURES_OUTLIERS, rr.LineStrips3D.from_fields(colors=[OUTLIER_COLOUR], radii=_OUTLIER_RADIUS), static=True
    )
    _send_segments(rec, LOOP_CLOSURES_OUTLIERS, segments, c[order], stamps)


def log_range_bearing(rec: rr.RecordingStream, graph: PoseGraph, rb: RangeBearing, real_time: bool) -> None:
    """Range-bearing sightings, one entity per observing agent in its colour: a segment from the
    observer keyframe's reference pose to the point at the measured range and bearing, at the
    observer's node and (real stamps) the sighting's own stamp."""
    import rerun as rr

    from studio.core.geometry import yaw_from_quat_xyzw

    for k in np.unique(rb.observer_agent).tolist():
        agent = graph.agents[k]
        rows = np.flatnonzero(rb.observer_agent == k)
        rows = rows[np.lexsort((rb.stamps_ns[rows], rb.observer_index[rows]))]
        ref = _reference(agent)
        node = rb.observer_index[rows]
        start = ref[node, 0:3]
        heading = yaw_from_quat_xyzw(ref[node, 3:7]) + rb.bearing_rad[rows]
        end = start + rb.range_m[rows, None] * np.column_stack([np.cos(heading), np.sin(heading), np.zeros(len(rows))])
        entity = _path(SIGHTINGS, agent)
        rec.log(entity, rr.LineStrips3D.from_fields(colors=[agent_colour(k)], radii=_LOOP_RADIUS), static=True)
        _send_segments(rec, entity, np.stack([start, end], axis=1), node, rb.stamps_ns[rows] if real_time else None)


def log_position_error(rec: rr.RecordingStream, agent: AgentGraph, k: int, real_time: bool) -> None:
    """|initial - ground truth| position per node (nothing when the agent has no ground truth)."""
    import rerun as rr

    if agent.ground_truth is None:
        return
    entity = _path(SERIES_POSITION_ERROR, agent)
    error = np.linalg.norm(agent.initial[:, 0:3] - agent.ground_truth[:, 0:3], axis=1)
    rec.log(entity, rr.SeriesLines(colors=[agent_colour(k)], names=[agent.name]), static=True)
    rec.send_columns(
        entity, _index_columns(agent, np.arange(agent.num_poses), real_time), rr.Scalars.columns(scalars=error)
    )


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
        rec.send_columns(
            entity, _index_columns(agent, np.arange(agent.num_poses), real_time), rr.Scalars.columns(scalars=counts)
        )
    if len(graph.inter):
        n = max(a.num_poses for a in graph.agents)
        counts = _count_so_far(np.maximum(graph.inter.from_index, graph.inter.to_index), n)
        rec.log(
            SERIES_INTER_LOOP_CLOSURES,
            rr.SeriesLines(colors=[(*INTER_RGB, 255)], names=["inter-agent, all agents"]),
            static=True,
        )
        # The node timeline only: nodes of different agents have different stamps.
        rec.send_columns(
            SERIES_INTER_LOOP_CLOSURES,
            [rr.TimeColumn(TIMELINE_NODE, sequence=np.arange(n))],
            rr.Scalars.columns(scalars=counts),
        )


# --------------------------------------------------------------------------------------------------
# Blueprint


def _scene(graph: PoseGraph, real_time: bool) -> _Scene:
    pts = np.concatenate([p[:, 0:3] for a in graph.agents for p in (a.initial, a.ground_truth) if p is not None])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    extent = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0))
    errors = [
        float(np.max(np.linalg.norm(a.initial[:, 0:3] - a.ground_truth[:, 0:3], axis=1)))
        for a in graph.agents
        if a.ground_truth is not None
    ]
    most_lcs = max([len(a.loop_closures) for a in graph.agents] + [1])
    return _Scene(
        names=tuple(a.name for a in graph.agents),
        planar=is_planar_graph(graph),
        centre_xyz=(float(centre[0]), float(centre[1]), float(centre[2])),
        extent_m=extent,
        num_nodes=max(a.num_poses for a in graph.agents),
        real_time=real_time,
        inter=len(graph.inter) > 0,
        max_position_error_m=max(errors + [1e-3]),
        max_loop_closures=most_lcs,
        max_inter_loop_closures=max(len(graph.inter), 1),
        many_inter=len(graph.inter) > MANY_INTER_LOOP_CLOSURES,
    )


def fixed_id(part: Any, namespace: uuid.UUID, name: str) -> Any:
    """Blueprint parts get random ids by default; give ``part`` the id of its role instead (``name``
    within the recording kind's ``namespace``), so the same layout gives the same file content."""
    part.id = uuid.uuid5(namespace, name)
    return part


#: A plot with a legend shows its y axis up to this multiple of the largest value: the legend sits
#: in the top-left corner over the empty band above the data (and over its first nodes, where a
#: count or a dead-reckoning error is still small), so eight agents' names fit without hiding it.
LEGEND_HEADROOM = 1.6


def plot_legend() -> Any:
    """The legend of a plot with one series per agent: top left, over :data:`LEGEND_HEADROOM`."""
    import rerun.blueprint as rrb

    return rrb.PlotLegend(corner=rrb.components.Corner2D.LeftTop, visible=True)


def no_plot_legend() -> Any:
    """No legend (a plot whose title names its one series, or whose colours another plot names)."""
    import rerun.blueprint as rrb

    return rrb.PlotLegend(visible=False)


def eye_over(centre_xyz: Sequence[float], extent_m: float, *, planar: bool) -> Any:
    """The view's camera, one rule for every recording: planar data from straight above (at 1.1
    times ``extent_m`` over ``centre_xyz``, north up), 3D data from an oblique corner."""
    import rerun.blueprint as rrb

    cx, cy, cz = (float(v) for v in centre_xyz)
    if planar:
        return rrb.EyeControls3D(
            position=(cx, cy, cz + 1.1 * extent_m), look_target=(cx, cy, cz), eye_up=(0.0, 1.0, 0.0)
        )
    d = 0.9 * extent_m
    return rrb.EyeControls3D(position=(cx - d, cy - d, cz + d), look_target=(cx, cy, cz), eye_up=(0.0, 0.0, 1.0))


def default_blueprint(scene: _Scene) -> rrb.Blueprint:
    """The layout saved in every recording: 3D view of all agents, time series beside it, time panel
    on ``node``, following (a viewer opens the file at its last node, with everything shown).
    Planar data is seen from straight above."""
    import rerun as rr
    import rerun.blueprint as rrb

    timelines = [TIMELINE_NODE] + ([TIMELINE_TIME] if scene.real_time else [])
    upto_cursor = [
        rrb.VisibleTimeRange(t, start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.cursor_relative())
        for t in timelines
    ]
    eye = eye_over(scene.centre_xyz, scene.extent_m, planar=scene.planar)
    # Everything up to the cursor: loop closures accumulate (paths are static, and transforms are
    # always resolved at the cursor, so the pose markers do not leave a trail).
    # Many inter-agent closures: their segments (one entity per pair, toggled in the blueprint
    # panel) hidden, their density shown in their place.
    hidden: dict[Any, Any] | None = (
        {"/" + LOOP_CLOSURES_INTER.split("/{pair}")[0]: rrb.EntityBehavior(visible=False)} if scene.many_inter else None
    )
    space = rrb.Spatial3DView(
        origin=f"/{WORLD}",
        name="agents",
        eye_controls=eye,
        time_ranges=upto_cursor,
        line_grid=rrb.LineGrid3D(visible=False),
        overrides=hidden,
    )
    whole = rr.TimeRange(start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.infinite())
    # Fixed y ranges: the whole series is visible whatever the cursor (auto-fit follows the view).
    # One legend, on the first plot (its colours are every plot's and the 3D view's), given room.
    err = rrb.TimeSeriesView(
        origin=f"/{METRICS}/position_error",
        name="initial-estimate position error [m]",
        axis_x=rrb.TimeAxis(view_range=whole),
        axis_y=rrb.ScalarAxis(range=(0.0, LEGEND_HEADROOM * scene.max_position_error_m)),
        plot_legend=plot_legend(),
    )
    lcs = rrb.TimeSeriesView(
        origin=f"/{METRICS}/intra_loop_closures",
        name="intra-agent loop closures so far",
        axis_x=rrb.TimeAxis(view_range=whole),
        axis_y=rrb.ScalarAxis(range=(0.0, 1.05 * scene.max_loop_closures)),
        plot_legend=no_plot_legend(),
    )
    parts = [(space, "agents"), (err, "position_error"), (lcs, "loop_closures")]
    plots = [err, lcs]
    if scene.inter:
        inter = rrb.TimeSeriesView(
            origin=f"/{METRICS}/inter_loop_closures",
            name="inter-agent loop closures so far (all agents)",
            axis_x=rrb.TimeAxis(view_range=whole),
            axis_y=rrb.ScalarAxis(range=(0.0, 1.05 * scene.max_inter_loop_closures)),
            plot_legend=no_plot_legend(),
        )
        plots.append(inter)
        parts.append((inter, "inter_loop_closures"))
    series = rrb.Vertical(*plots, row_shares=[2.0] + [1.0] * (len(plots) - 1))
    root = rrb.Horizontal(space, series, column_shares=[2, 1])
    for part, label in parts + [(series, "series"), (root, "root")]:
        fixed_id(part, _RECORDING_ID_NAMESPACE, f"blueprint/{label}")
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline=TIMELINE_NODE, play_state="following", expanded=True),
        rrb.BlueprintPanel(expanded=False),
        rrb.SelectionPanel(expanded=False),
        auto_views=False,
    )


# --------------------------------------------------------------------------------------------------
# Library entry points


def record_graph(
    graph: PoseGraph,
    path: PathLike,
    *,
    name: str,
    config_json: str | None = None,
    outliers: np.ndarray | None = None,
    progress: Progress | None = None,
    range_bearing: RangeBearing | None = None,
) -> RecordResult:
    """Log ``graph`` to a new ``.rrd`` at ``path`` (written in place; see :func:`record_dataset`).

    ``outliers``: (k, 4) rows ``agent_from vertex_from agent_to vertex_to`` (0-based) of the loop
    closures that are outliers, drawn apart from the inliers. ``range_bearing``: agent-to-agent
    sightings (``range_bearing.txt``), drawn per observing agent.
    """
    import rerun as rr

    path = Path(path)
    g = graph.to_se3()
    real_time = has_real_stamps(g)
    scene = _scene(g, real_time)
    rid = recording_id_for(g)  # the id is computed on the SE3 form anyway: lift once
    steps = len(g.agents) + 1

    def write(target: Path) -> None:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid, send_properties=False)
        with closing(rec, target, shown=path):
            rec.save(target, default_blueprint=default_blueprint(scene))
            log_properties(rec, graph, name, config_json)
            log_world(rec)
            axis_length = 0.04 * scene.extent_m
            intra_out, inter_out = _outlier_masks(g, outliers)
            for k, agent in enumerate(g.agents):
                log_paths(rec, agent, k)
                log_current_pose(rec, agent, k, real_time, axis_length)
                log_intra_loop_closures(rec, agent, k, real_time, intra_out[k])
                log_position_error(rec, agent, k, real_time)
            log_inter_loop_closures(rec, g, real_time, inter_out)
            if scene.many_inter:
                log_inter_loop_closure_density(rec, g, scene.extent_m, scene.num_nodes - 1, inter_out)
            log_outlier_loop_closures(rec, g, real_time, intra_out, inter_out)
            log_loop_closure_counts(rec, g, real_time)
            if range_bearing is not None and len(range_bearing):
                log_range_bearing(rec, g, range_bearing, real_time)

    # written by a separate process (write_bounded): a stuck writer (a full disk) is one OutputError,
    # never a hang, and the parts' progress is reported around it (the writer's own is not seen here)
    report(progress, "recording", 0, steps, "parts")
    with interrupts_deferred():  # Ctrl-C waits for the writer (a few tenths of a second)
        write_bounded(write, path, shown=path)
    report(progress, "recording", steps, steps, "parts")
    return RecordResult(path, rid, graph.num_poses, graph.edge_counts(), real_time)


def _sibling_config(dataset: Path) -> str | None:
    cfg = dataset.parent / f"{dataset.name}.config.json"
    if not cfg.is_file():
        return None
    try:
        return json.dumps(json.loads(cfg.read_text(encoding="utf-8")), sort_keys=True)
    except (OSError, ValueError) as err:
        raise FormatError(f"{cfg}: not a readable JSON config ({err})") from None


def read_outliers(path: PathLike, graph: PoseGraph) -> np.ndarray:
    """``outliers.txt`` (:func:`studio.io.outliers_txt.read_outliers_txt`, checked against the graph's
    agents and vertices). Returns (k, 4) int64 rows with 0-based agents."""
    from studio.io.outliers_txt import read_outliers_txt

    return read_outliers_txt(path, [a.num_poses for a in graph.agents])[0]


def check_extent(graph: PoseGraph, dataset: Path) -> None:
    """Refuse, naming the file and vertex, a pose whose position leaves ±MAX_RECORDED_COORDINATE_M."""
    for a in graph.agents:
        for what, poses, rel in (
            ("vertex", a.initial, "posegraph.g2o"),
            ("ground-truth pose", a.ground_truth, "GT.tum"),
        ):
            if poses is None or not len(poses):
                continue
            xyz = np.asarray(poses)[:, : (2 if poses.shape[1] == 3 else 3)]
            bad = np.flatnonzero(~(np.abs(xyz) <= MAX_RECORDED_COORDINATE_M).all(axis=1))
            if len(bad):
                raise FormatError(
                    f"{dataset}: agent {a.name}: {what} {int(bad[0])} ({rel}) lies beyond {MAX_RECORDED_COORDINATE_M:g} m"
                )


def record_dataset(
    dataset: PathLike, out: PathLike, *, force: bool = False, progress: Progress | None = None
) -> RecordResult:
    """Read a multi-g2o folder (ours or kollagen's) and write its recording to ``out`` atomically.

    The config beside the dataset (``<dataset>.config.json``, as ``studio synth`` writes it) becomes
    the ``config`` property when present. Bad input raises before anything is written.
    """
    from studio.io.multig2o import read_multi_g2o

    dataset, out = Path(dataset), Path(out)
    if out.suffix != ".rrd":
        raise OutputError(f"{out}: a recording must end in .rrd")
    check_not_overlapping([out], [dataset])
    report(progress, "reading", 0, 1, "datasets")
    graph = read_multi_g2o(dataset)
    report(progress, "reading", 1, 1, "datasets")
    check_extent(graph, dataset)
    config_json = _sibling_config(dataset)
    outliers = read_outliers(dataset / "outliers.txt", graph) if (dataset / "outliers.txt").is_file() else None
    from studio.io.range_bearing import RANGE_BEARING_NAME, read_range_bearing

    rb_file = dataset / RANGE_BEARING_NAME
    range_bearing = read_range_bearing(rb_file, graph) if rb_file.is_file() else None
    name = dataset.resolve().name
    with staged_outputs(out.parent, [out.name], force=force, inputs=[dataset]) as staging:
        res = record_graph(
            graph,
            staging / out.name,
            name=name,
            config_json=config_json,
            outliers=outliers,
            progress=progress,
            range_bearing=range_bearing,
        )
    return RecordResult(out, res.recording_id, res.num_poses, res.edge_counts, res.real_time)
