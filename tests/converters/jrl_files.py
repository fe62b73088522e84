"""Writes JRL files in the layout jrl's own ``Writer`` gives COSMO-Bench's datasets, for the tests
and the docs (the data is simulated; the layout is jrl's, read from its ``src/Writer.cpp`` and
``include/jrl/IOMeasurements.h``, ``src/IOValues.cpp``):

* ``"robots": [97, 98]``: nlohmann's json writes a ``char`` as a number;
* keys are GTSAM Symbols, ``robot << 56 | index``, written as integers;
* one entry per keyframe of each robot, at its stamp: the first holds the ``PriorFactorPose3`` that
  anchors the robot at its first pose, every other one the odometry into its pose and the loop
  closures found there (an inter-robot closure in the entries of the robot that found it);
* values and measurements as ``serialize<Pose3>`` writes them (``"type": "Pose3"``, translation,
  rotation ``[w, x, y, z]``), covariances as 36 numbers column-major (``serializeCovariance`` of an
  Eigen matrix) over GTSAM's tangent order, rotation first;
* ``groundtruth`` and ``initialization`` per robot, each holding every pose the robot observed: its
  own and copies of the other robots' poses its inter-robot closures touch;
* ``potential_outlier_factors`` (every loop closure) and ``outlier_factors`` per robot, as FactorIds
  ``[entry, measurement]``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

KEY_SHIFT = 56
PRIOR_SIGMAS = (1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4)  # rotation (rad) then translation (m)


def key(robot: str, index: int) -> int:
    return (ord(robot) << KEY_SHIFT) | index


@dataclass
class Team:
    """What the file holds, as the test reads it back: per robot its true poses ``(n, 7)`` (``x y z
    qx qy qz qw``) and stamps, and the loop closures ``(robot that found it, key1, key2, outlier)``."""

    truth: dict[str, np.ndarray]
    initial: dict[str, np.ndarray]
    stamps_ns: dict[str, list[int]]
    closures: list[tuple[str, int, int, bool]] = field(default_factory=list)


def pose3(pose: np.ndarray) -> dict[str, Any]:
    x, y, z, qx, qy, qz, qw = pose.tolist()
    return {"type": "Pose3", "translation": [x, y, z], "rotation": [qw, qx, qy, qz]}


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ra, rb = Rotation.from_quat(a[3:]), Rotation.from_quat(b[3:])
    t = ra.inv().apply(b[:3] - a[:3])
    q = (ra.inv() * rb).as_quat()
    return np.concatenate([t, q / np.linalg.norm(q)])


def dense_covariance(rng: np.random.Generator) -> np.ndarray:
    """A symmetric positive definite 6x6 with every entry non-zero (a LiDAR registration's)."""
    a = rng.normal(size=(6, 6)) * 0.05
    return a @ a.T + np.diag([1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2])


def _factor(k1: int, k2: int, meas: np.ndarray, cov: np.ndarray) -> dict[str, Any]:
    return {
        "type": "BetweenFactorPose3",
        "key1": k1,
        "key2": k2,
        "measurement": pose3(meas),
        "covariance": cov.flatten(order="F").tolist(),
    }


def _walk(rng: np.random.Generator, n: int, start: np.ndarray) -> np.ndarray:
    poses = [start]
    for _ in range(n - 1):
        last = poses[-1]
        step = Rotation.from_rotvec([0.0, 0.0, rng.uniform(-0.4, 0.4)])
        r = Rotation.from_quat(last[3:]) * step
        t = last[:3] + Rotation.from_quat(last[3:]).apply([2.0, 0.0, rng.normal(0, 0.05)])
        poses.append(np.concatenate([t, r.as_quat()]))
    return np.array(poses)


def cosmo_team(seed: int = 3, poses: int = 8) -> tuple[dict[str, Any], Team]:
    """A two-robot JRL document in COSMO-Bench's layout and what it holds. Robot ``a`` finds an
    intra-robot closure ``a7 -> a1`` (an outlier) and an inter-robot closure ``a6 -> b2``; robot
    ``b`` an inter-robot closure ``b7 -> a3`` (an outlier)."""
    rng = np.random.default_rng(seed)
    robots = ["a", "b"]
    truth = {
        "a": _walk(rng, poses, np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])),
        "b": _walk(rng, poses, np.array([1.0, 3.0, 0.2, *Rotation.from_rotvec([0, 0, 0.5]).as_quat()])),
    }
    initial = {r: _dead_reckoning(truth[r], rng) for r in robots}
    stamps = {
        r: [1_700_000_000_000_000_000 + k * 500_000_000 + 100_000_000 * n for k in range(poses)]
        for n, r in enumerate(robots)
    }
    team = Team(truth, initial, stamps)
    closures = {"a": [(7, "a", 1, True), (6, "b", 2, False)], "b": [(7, "a", 3, True)]}
    doc: dict[str, Any] = {"name": "cosmo_like", "robots": [ord(r) for r in robots], "measurements": {}}
    potential: dict[str, list[list[int]]] = {}
    outliers: dict[str, list[list[int]]] = {}
    for r in robots:
        prior = {
            "type": "PriorFactorPose3",
            "key": key(r, 0),
            "prior": pose3(truth[r][0]),
            "covariance": np.diag(np.square(PRIOR_SIGMAS)).flatten(order="F").tolist(),
        }
        entries = [{"stamp": stamps[r][0], "measurements": [prior]}]
        potential[r], outliers[r] = [], []
        for k in range(1, poses):
            odo = _between(truth[r][k - 1], truth[r][k])
            factors = [_factor(key(r, k - 1), key(r, k), odo, dense_covariance(rng))]
            for at, other, j, outlier in closures[r]:
                if at != k:
                    continue
                target = truth[other][j] if not outlier else truth[other][(j + 3) % poses]
                potential[r].append([k, len(factors)])
                if outlier:
                    outliers[r].append([k, len(factors)])
                factors.append(_factor(key(r, k), key(other, j), _between(truth[r][k], target), dense_covariance(rng)))
                team.closures.append((r, key(r, k), key(other, j), outlier))
            entries.append({"stamp": stamps[r][k], "measurements": factors})
        doc["measurements"][r] = entries
    doc["groundtruth"] = _values(robots, truth, closures)
    # a robot's initial estimate of another robot's pose is its own, not the owner's (jrl: "MAY differ")
    doc["initialization"] = _values(robots, initial, closures, copy_offset_m=0.5)
    doc["potential_outlier_factors"] = potential
    doc["outlier_factors"] = outliers
    return doc, team


def _dead_reckoning(truth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The truth drifted: the initial estimate of a robot's own poses."""
    out = truth.copy()
    out[:, :3] += np.cumsum(rng.normal(0, 0.05, size=(len(truth), 3)), axis=0)
    return out


def _values(
    robots: list[str], poses: dict[str, np.ndarray], closures: dict[str, list], copy_offset_m: float = 0.0
) -> dict[str, list]:
    """Each robot's own poses and copies of the other robots' poses its inter-robot closures touch
    (``copy_offset_m`` off the owner's along x)."""
    out = {}
    for r in robots:
        vals = [{"key": key(r, k), **pose3(p)} for k, p in enumerate(poses[r])]
        for _, other, j, _outlier in closures[r]:
            if other != r:
                copy = poses[other][j] + np.array([copy_offset_m, 0, 0, 0, 0, 0, 0])
                vals.append({"key": key(other, j), **pose3(copy)})
        out[r] = vals
    return out


def write_cosmo_jrl(path: Path, doc: dict[str, Any]) -> Path:
    """The document as jrl's ``Writer`` writes it: compact JSON (``output_stream << output_json``), the
    keys of every object in order (nlohmann's json objects are ``std::map``s)."""
    import json

    path.write_text(json.dumps(doc, separators=(",", ":"), sort_keys=True))
    return path
