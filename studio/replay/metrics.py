"""Scores of a replay's beliefs against the ground truth (numpy only).

* per robot: APE translation mean [m] of its current estimate of its own trajectory so far against
  its ground truth so far, its first estimated pose put on its first true pose (``first-pose``);
* the team: the same over all robots' poses (each robot aligned by its first pose), and the team's
  map as one piece: one rigid Umeyama transform over all robots' positions (``se3``), which is what
  snaps down when robots meet;
* the team's consensus: jrl's Shared Variable Error (:func:`studio.core.jrl_metrics.sve`) over the
  poses robots keep of each other (swarm, dgs) against their owners' estimates and each other's;
* the final beliefs' distance to the global optimum: SE-Sync's objective ``f`` of each back-end's
  final estimate and ``(f - f*) / f*`` against the dataset's certified optimum ``f*``
  (:func:`team_optimum`, :func:`gaps_to`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from studio.core.errors import ConfigError
from studio.core.geometry import planar_poses_to_se3, quat_rotate
from studio.core.jrl_metrics import RobotValues
from studio.core.model import PoseKind
from studio.solvers.incremental import compose, inverse
from studio.solvers.problem import Problem

if TYPE_CHECKING:  # SE-Sync's modules load scipy's solvers: imported when the optimum is found
    from studio.solvers.sesync import Optimum

__all__ = ["as_se3", "positions", "first_pose_errors", "se3_errors", "robot_values", "team_optimum", "gaps_to"]


def as_se3(poses: np.ndarray, kind: PoseKind) -> np.ndarray:
    return planar_poses_to_se3(poses) if kind is PoseKind.SE2 else poses


def positions(poses: np.ndarray, kind: PoseKind) -> np.ndarray:
    """``(n, 3)`` positions of pose rows, planar ones at height 0 (as :func:`as_se3`'s)."""
    if kind is PoseKind.SE3:
        return poses[:, 0:3]
    return np.column_stack([poses[:, 0:2], np.zeros(len(poses))])


def first_pose_errors(estimate_se3: np.ndarray, truth_se3: np.ndarray) -> np.ndarray:
    """Per pose, the translation error [m] once the first estimated pose is put on the first true one."""
    if not len(estimate_se3):
        return np.zeros(0)
    move = compose(truth_se3[:1], inverse(estimate_se3[:1], PoseKind.SE3), PoseKind.SE3)
    # the translations of ``move * estimate`` (the rotations are not scored)
    moved = move[:, 0:3] + quat_rotate(move[:, 3:7], estimate_se3[:, 0:3])
    return np.linalg.norm(moved - truth_se3[:, 0:3], axis=1)


def se3_errors(estimate_xyz: np.ndarray, truth_xyz: np.ndarray) -> np.ndarray:
    """Per position, the error [m] after the rigid transform (Umeyama, no scale) that fits best."""
    if len(estimate_xyz) < 3:
        return np.linalg.norm(estimate_xyz - truth_xyz, axis=1) if len(estimate_xyz) else np.zeros(0)
    mu_e, mu_t = estimate_xyz.mean(axis=0), truth_xyz.mean(axis=0)
    cov = (truth_xyz - mu_t).T @ (estimate_xyz - mu_e) / len(estimate_xyz)
    u, _, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1.0
    r = u @ s @ vt
    moved = (estimate_xyz - mu_e) @ r.T + mu_t
    return np.linalg.norm(moved - truth_xyz, axis=1)


def robot_values(
    own: np.ndarray,
    visited: np.ndarray,
    agent_of_vertex: np.ndarray,
    kept_robot: np.ndarray,
    kept_vertex: np.ndarray,
    kept_poses: np.ndarray,
    num_robots: int,
) -> list[RobotValues]:
    """Per robot, what it estimates (keys: global vertex ids): its own visited poses (``own`` rows
    where ``visited``) and the poses of other robots it keeps."""
    out = []
    for r in range(num_robots):
        mine = np.flatnonzero(visited & (agent_of_vertex == r))
        k = kept_robot == r
        keys = np.concatenate([mine, kept_vertex[k]]).astype(np.int64)
        poses = np.concatenate([own[mine], kept_poses[k]])
        order = np.argsort(keys, kind="stable")
        out.append(RobotValues(keys[order], poses[order]))
    return out


def team_optimum(problem: Problem) -> Optimum | None:
    """The certified optimum of ``problem`` (SE-Sync's objective,
    :func:`studio.solvers.sesync.certified_optimum`), or None when it is unavailable (pymanopt
    missing) or when no one optimum exists: a team whose robots never close a loop between them
    (each robot's map may move rigidly against the others'). ``studio replay`` computes it before the
    back-ends run, so that its memory is not added to theirs at the peak."""
    from studio.solvers.sesync import certified_optimum
    from studio.solvers.validate import unreached_vertices

    if len(unreached_vertices(problem)):
        return None
    try:
        return certified_optimum(problem)
    except ConfigError:
        return None


def gaps_to(
    problem: Problem, finals: list[np.ndarray], optimum: Optimum | None
) -> tuple[float | None, list[tuple[float, float | None]]]:
    """The certified ``f*`` of ``optimum`` (from :func:`team_optimum`) and, per final estimate
    (rows in ``problem``'s pose kind), its ``f`` and ``(f - f*) / f*`` (None without a certified
    ``f*``). Without one optimum (robots never tied by a closure) ``f`` is NaN and no gap is given."""
    from studio.solvers.sesync import sesync_objective
    from studio.solvers.validate import unreached_vertices

    if len(unreached_vertices(problem)):
        return None, [(float("nan"), None) for _ in finals]
    out = []
    for poses in finals:
        f = sesync_objective(problem, poses)
        out.append((f, None if optimum is None else optimum.gap(f)))
    f_star = optimum.f_star if optimum is not None and optimum.certified else None
    return f_star, out
