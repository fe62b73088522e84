"""Edge errors and chi2 of pose-graph edges, on columns (pure numpy).

The error of an edge ``i -> j`` with measurement ``Z`` at poses ``X_i``, ``X_j`` is the one g2o
computes (``EdgeSE2::computeError``, ``EdgeSE3::computeError``): the pose ``D = Z^-1 (X_i^-1 X_j)``
written as a vector.

* planar (``EDGE_SE2``): ``[D.x, D.y, D.theta]``, the angle wrapped to ``[-pi, pi)``;
* spatial (``EDGE_SE3:QUAT``), convention ``"g2o"``: ``[D.t, D.q.xyz]`` with ``D.q`` normalised to
  ``w >= 0``: the rotation part is the quaternion's vector part, ``sin(theta / 2) * axis``, about
  half the rotation angle;
* spatial, convention ``"rotvec"``: ``[D.t, Log(D.R)]``, the rotation vector (angle times axis), as
  GTSAM's ``BetweenFactor<Pose3>`` measures it (up to GTSAM's own translation/rotation order).

``chi2 = e^T Omega e`` per edge, with ``Omega`` rebuilt from the stored upper triangle; a graph's
chi2 is the sum over its edges (g2o's ``activeChi2``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from studio.core.conventions import DEFAULT_CONVENTION, Convention
from studio.core.errors import GraphError
from studio.core.geometry import normalize_angle, quat_canonical, quat_conj, quat_mul, quat_rotate, upper_to_matrix

__all__ = ["Convention", "DEFAULT_CONVENTION", "edge_errors", "chi2_terms", "chi2_parts", "graph_chi2"]

if TYPE_CHECKING:
    from studio.core.model import PoseGraph


def _errors_se2(xi: np.ndarray, xj: np.ndarray, z: np.ndarray) -> np.ndarray:
    ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
    rx, ry = ci * dx + si * dy - z[:, 0], -si * dx + ci * dy - z[:, 1]
    cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
    return np.column_stack([cz * rx + sz * ry, -sz * rx + cz * ry, normalize_angle(xj[:, 2] - xi[:, 2] - z[:, 2])])


def _errors_se3(xi: np.ndarray, xj: np.ndarray, z: np.ndarray, convention: Convention) -> np.ndarray:
    qi, qj, qz = xi[:, 3:7], xj[:, 3:7], z[:, 3:7]
    qi_inv, qz_inv = quat_conj(qi), quat_conj(qz)
    t_rel = quat_rotate(qi_inv, xj[:, 0:3] - xi[:, 0:3])
    q_rel = quat_mul(qi_inv, qj)
    t_err = quat_rotate(qz_inv, t_rel - z[:, 0:3])
    q_err = quat_canonical(quat_mul(qz_inv, q_rel))
    if convention == "g2o":
        rot = q_err[:, 0:3]
    else:
        v = np.linalg.norm(q_err[:, 0:3], axis=1)
        angle = 2.0 * np.arctan2(v, q_err[:, 3])
        scale = np.where(v > 1e-12, angle / np.where(v > 1e-12, v, 1.0), 2.0)
        rot = q_err[:, 0:3] * scale[:, None]
    return np.column_stack([t_err, rot])


def edge_errors(
    poses_from: np.ndarray, poses_to: np.ndarray, measurements: np.ndarray, *, convention: Convention = "g2o"
) -> np.ndarray:
    """Error vectors ``(m, 3)`` (planar rows ``x y theta``) or ``(m, 6)`` (rows ``x y z qx qy qz qw``)."""
    xi = np.asarray(poses_from, dtype=np.float64)
    xj = np.asarray(poses_to, dtype=np.float64)
    z = np.asarray(measurements, dtype=np.float64)
    if z.shape[1] == 3:
        return _errors_se2(xi, xj, z)
    if convention not in ("g2o", "rotvec"):
        raise ValueError(f"unknown rotation-error convention {convention!r}")
    return _errors_se3(xi, xj, z, convention)


def chi2_terms(errors: np.ndarray, information_upper: np.ndarray) -> np.ndarray:
    """``e^T Omega e`` of every edge."""
    d = errors.shape[1]
    omega = upper_to_matrix(information_upper, d)
    terms: np.ndarray = np.einsum("ni,nij,nj->n", errors, omega, errors)
    return terms


def chi2_parts(errors: np.ndarray, information_upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per edge, the chi2 of the translation block and of the rotation block alone
    (``e_t^T Omega_tt e_t`` and ``e_r^T Omega_rr e_r``; cross terms belong to neither)."""
    d = errors.shape[1]
    k = 2 if d == 3 else 3
    omega = upper_to_matrix(information_upper, d)
    et, er = errors[:, :k], errors[:, k:]
    return (np.einsum("ni,nij,nj->n", et, omega[:, :k, :k], et), np.einsum("ni,nij,nj->n", er, omega[:, k:, k:], er))


def graph_chi2(
    graph: PoseGraph, poses_per_agent: Sequence[np.ndarray] | None = None, *, convention: Convention = "g2o"
) -> dict[str, float]:
    """chi2 of a whole graph at the given poses (one ``(n_a, pose_width)`` array per agent, in the
    graph's pose kind; default: each agent's ground truth), per edge class:
    ``{"odometry", "intra", "inter", "total"}``. ``total`` is what g2o's ``activeChi2`` reports."""
    if poses_per_agent is None:
        poses_per_agent = []
        for agent in graph.agents:
            if agent.ground_truth is None:
                raise GraphError(f"agent {agent.name} has no ground truth; pass poses_per_agent")
            poses_per_agent.append(agent.ground_truth)
    if len(poses_per_agent) != len(graph.agents):
        raise GraphError(f"{len(poses_per_agent)} pose arrays for {len(graph.agents)} agents")
    poses = [np.asarray(p, dtype=np.float64) for p in poses_per_agent]
    out = {"odometry": 0.0, "intra": 0.0, "inter": 0.0}
    for agent, x in zip(graph.agents, poses):
        for name, edges in (("odometry", agent.odometry), ("intra", agent.loop_closures)):
            if len(edges):
                e = edge_errors(x[edges.from_index], x[edges.to_index], edges.measurements, convention=convention)
                out[name] += float(chi2_terms(e, edges.information_upper).sum())
    inter = graph.inter
    if len(inter):
        offsets = np.concatenate([[0], np.cumsum([len(x) for x in poses])])
        stacked = np.concatenate(poses)
        xi = stacked[offsets[inter.from_agent] + inter.from_index]
        xj = stacked[offsets[inter.to_agent] + inter.to_index]
        e = edge_errors(xi, xj, inter.measurements, convention=convention)
        out["inter"] = float(chi2_terms(e, inter.information_upper).sum())
    out["total"] = out["odometry"] + out["intra"] + out["inter"]
    return out
