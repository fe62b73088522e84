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

from studio.core.errors import GraphError
from studio.core.geometry import planar_poses_to_se3, relative_planar_pose, se2_information_to_se3
from studio.core.model import AgentGraph, PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import G2oDocument, write_g2o
from studio.io.multig2o import Records
from studio.io.tum import write_tum

__all__ = ["write_single_g2o", "write_single_tum", "agent_offsets", "connector_measurements"]


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
