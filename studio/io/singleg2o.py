"""kollagen's single-file view of a multi-agent dataset: one g2o file and two TUM files.

``NAME.g2o`` holds every agent's vertices with ids concatenated (agent 1 first), then per agent an edge
from the previous agent's last vertex to its first (ground-truth relative pose, so the file is one
connected graph, as kollagen does), followed by its odometry; then all intra-agent loop closures, then
all inter-agent ones. ``NAME_GT.tum`` and ``NAME.tum`` hold ground truth and initial estimate with
the concatenated ids as timestamps.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.core.errors import FormatError, GraphError
from studio.core.geometry import (
    planar_poses_to_se3,
    relative_planar_pose,
    se2_information_to_se3,
    se3_poses_to_planar,
)
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.io.multig2o import Records
from studio.io.tum import read_tum, write_tum

__all__ = [
    "write_single_g2o",
    "write_single_tum",
    "read_single_g2o_dataset",
    "agent_offsets",
    "connector_measurements",
]


def agent_offsets(graph: PoseGraph) -> np.ndarray:
    """The id of each agent's first vertex in the single file (plus the total at the end)."""
    return np.concatenate([[0], np.cumsum([a.num_poses for a in graph.agents])]).astype(np.int64)


def connector_measurements(graph: PoseGraph) -> np.ndarray:
    """``(n_agents - 1, 3)``: ground-truth pose of agent k's first vertex in agent k-1's last frame."""
    truth = [a.ground_truth for a in graph.agents]
    if any(t is None for t in truth):
        raise GraphError("kollagen's connector edges need every agent's ground truth")
    last = np.array([t[-1] for t in truth[:-1]]).reshape(-1, 3)  # type: ignore[index]
    first = np.array([t[0] for t in truth[1:]]).reshape(-1, 3)  # type: ignore[index]
    dx, dy, dt = relative_planar_pose(last[:, 0], last[:, 1], last[:, 2], first[:, 0], first[:, 1], first[:, 2])
    return np.column_stack([dx, dy, dt])


def write_single_g2o(
    graph: PoseGraph,
    path: PathLike,
    *,
    records: Records = "2d",
    connector_information: np.ndarray,
    odometry_information: Sequence[np.ndarray] | None = None,
) -> None:
    """Write the single g2o file. ``graph`` must be planar with ground truth (kollagen's data).

    ``odometry_information`` optionally replaces each agent's odometry information (kollagen's exact
    information matrix is written here only).
    """
    if graph.kind is not PoseKind.SE2:
        raise ValueError("the single g2o layout is defined for planar graphs")
    offsets = agent_offsets(graph)
    conn = connector_measurements(graph)
    kind = PoseKind.SE2
    vid = np.arange(offsets[-1], dtype=np.int64)
    vposes = np.concatenate([a.initial for a in graph.agents])
    fr, to, meas, info = [], [], [], []
    for k, agent in enumerate(graph.agents):
        if k > 0:
            fr.append([offsets[k] - 1])
            to.append([offsets[k]])
            meas.append(conn[k - 1 : k])
            info.append(np.asarray(connector_information, dtype=np.float64).reshape(1, 6))
        odo = agent.odometry
        fr.append(odo.from_index + offsets[k])
        to.append(odo.to_index + offsets[k])
        meas.append(odo.measurements)
        info.append(odo.information_upper if odometry_information is None else odometry_information[k])
    for k, agent in enumerate(graph.agents):
        lc = agent.loop_closures
        fr.append(lc.from_index + offsets[k])
        to.append(lc.to_index + offsets[k])
        meas.append(lc.measurements)
        info.append(lc.information_upper)
    inter = graph.inter
    fr.append(inter.from_index + offsets[inter.from_agent])
    to.append(inter.to_index + offsets[inter.to_agent])
    meas.append(inter.measurements)
    info.append(inter.information_upper)
    doc = G2oDocument(
        kind,
        vid,
        vposes,
        np.concatenate(fr).astype(np.int64),
        np.concatenate(to).astype(np.int64),
        np.concatenate(meas),
        np.concatenate(info),
    )
    if records == "3d":
        doc = G2oDocument(
            PoseKind.SE3,
            doc.vertex_ids,
            planar_poses_to_se3(doc.vertex_poses),
            doc.edge_from,
            doc.edge_to,
            planar_poses_to_se3(doc.edge_measurements),
            se2_information_to_se3(doc.edge_information_upper),
        )
    write_g2o(path, doc)


def _se3_poses(agent: AgentGraph, ground_truth: bool) -> np.ndarray:
    poses = agent.se3_poses(ground_truth)
    if poses is None:
        raise GraphError(f"agent {agent.name} has no ground truth")
    return poses


def write_single_tum(graph: PoseGraph, path: PathLike, *, ground_truth: bool) -> None:
    """Concatenated ground truth (or initial estimate), timestamps = concatenated vertex ids."""
    poses = np.concatenate([_se3_poses(a, ground_truth) for a in graph.agents])
    stamps = np.arange(len(poses), dtype=np.int64) * NS_PER_S
    write_tum(path, Trajectory.from_poses(Path(path).stem, stamps, poses))


def read_single_g2o_dataset(path: PathLike) -> PoseGraph:
    """kollagen's single view as a dataset to score: ``NAME.g2o`` (the initial estimate, ids
    ``0..n-1``) with ``NAME_GT.tum`` beside it (one ground-truth pose per id, in id order).

    The file cannot say where one agent ends (kollagen's connectors are odometry edges), so the
    graph has one agent, named ``NAME``; only the poses are read (no edges). The stamps are the
    ground truth's when they increase, else the id in seconds. Raises :class:`FormatError` naming
    the file for a missing ground truth, or one that does not match the vertices."""
    path = Path(path)
    gt_path = path.with_name(f"{path.stem}_GT.tum")
    if not gt_path.is_file():
        raise FormatError(f"{path}: no ground truth beside it ({gt_path.name}); a dataset is scored against it")
    doc = read_g2o(path, edges=False)
    n = len(doc.vertex_ids)
    order = np.argsort(doc.vertex_ids, kind="stable")
    if n == 0 or not np.array_equal(doc.vertex_ids[order], np.arange(n)):
        raise FormatError(f"{path}: vertex ids must be 0..{max(n - 1, 0)} (kollagen's single view)")
    truth = read_tum(gt_path)
    if len(truth.stamps_ns) != n:
        raise FormatError(f"{gt_path}: {len(truth.stamps_ns)} poses for the {n} vertices of {path.name}")
    stamps = truth.stamps_ns
    if n > 1 and np.any(np.diff(stamps) <= 0):
        stamps = np.arange(n, dtype=np.int64) * NS_PER_S
    gt3 = truth.poses_xyz_quat_xyzw
    planar = doc.kind is PoseKind.SE2
    gt = se3_poses_to_planar(gt3) if planar else gt3
    agent = AgentGraph(
        path.stem,
        doc.kind,
        stamps,
        doc.vertex_poses[order],
        gt,
        Edges.empty(doc.kind),
        Edges.empty(doc.kind),
        ground_truth_se3=gt3 if planar else None,
    )
    return PoseGraph(doc.kind, (agent,), InterAgentEdges.empty(doc.kind), metadata={"source": str(path)})
