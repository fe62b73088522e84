"""JRL's metrics (DanMcGann/jrl ``include/jrl/Metrics-inl.h``, ``src/Metrics.cpp``) on columns.

Each function reproduces the jrl function its docstring names, to the rounding of the arithmetic;
where jrl's code and its ``format/METRIC_FORMAT.md`` disagree the code is followed (SVE's
denominator). Poses are rows ``x y theta`` (``Pose2``) or ``x y z qx qy qz qw`` (``Pose3``, Hamilton,
``xyzw`` inside the studio; JRL files hold ``[w, x, y, z]``). Keys are GTSAM ``Symbol`` integers
(``robot char << 56 | index``) as int64. Rotation errors are in radians, as jrl reports them.

* :func:`squared_pose_errors`: ``internal::squaredPoseError`` (``ref^-1 * est``: squared translation
  norm, squared rotation angle).
* :func:`umeyama_rigid`: ``Eigen::umeyama(src, dst, false)`` as ``alignment::align`` calls it.
* :func:`ate`: ``computeATE`` (aligned by default, every reference key scored).
* :func:`sve`: ``computeSVE``.
* :func:`gtsam_factor_errors` / :func:`mean_residual`: ``computeMeanResidual`` for
  ``BetweenFactorPose2/3`` and ``PriorFactorPose2/3`` with Gaussian noise (GTSAM's
  ``NoiseModelFactor::error``: ``0.5 r^T Sigma^-1 r``).
* :func:`precision_recall`: ``computePrecisionRecall`` (inliers are the positive class).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from studio.core.errors import EvaluationError
from studio.core.geometry import normalize_angle, quat_angle, quat_conj, quat_mul
from studio.core.residuals import edge_errors

__all__ = [
    "PoseError",
    "RobotValues",
    "PoseFactors",
    "squared_pose_errors",
    "umeyama_rigid",
    "apply_rigid",
    "ate",
    "sve",
    "gtsam_factor_errors",
    "mean_residual",
    "precision_recall",
]

PoseError = tuple[float, float]
"""``(translation, rotation)``: metres and radians (jrl's ``metrics::PoseError``)."""


@dataclass(frozen=True, eq=False)
class RobotValues:
    """One robot's values: ``keys`` (int64, ascending, unique) and their ``poses`` rows."""

    keys: np.ndarray
    poses: np.ndarray

    def take(self, keys: np.ndarray) -> np.ndarray:
        """The rows of ``keys`` (each must be held: see :meth:`missing`)."""
        rows: np.ndarray = self.poses[np.searchsorted(self.keys, keys)]
        return rows

    def missing(self, keys: np.ndarray) -> np.ndarray:
        """The ``keys`` this robot holds no value of."""
        at = np.minimum(np.searchsorted(self.keys, keys), max(len(self.keys) - 1, 0))
        held = (self.keys[at] == keys) if len(self.keys) else np.zeros(len(keys), dtype=bool)
        out: np.ndarray = keys[~held]
        return out


def squared_pose_errors(est: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """jrl ``internal::squaredPoseError<Pose2/Pose3>``: per row, with ``E = ref^-1 * est``, the squared
    norm of ``E``'s translation (``|t_est - t_ref|^2``) and the square of its rotation angle
    (``Rot3::axisAngle``'s angle in ``[0, pi]``; ``Pose2::theta`` in ``(-pi, pi]``)."""
    if est.shape[1] == 3:
        t2 = np.sum((est[:, 0:2] - ref[:, 0:2]) ** 2, axis=1)
        angle = normalize_angle(est[:, 2] - ref[:, 2])
    else:
        t2 = np.sum((est[:, 0:3] - ref[:, 0:3]) ** 2, axis=1)
        angle = quat_angle(quat_mul(quat_conj(ref[:, 3:7]), est[:, 3:7]))
    r2: np.ndarray = angle * angle
    return t2, r2


def umeyama_rigid(src_xyz: np.ndarray, dst_xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` minimising ``sum |R src + t - dst|^2``: Eigen's ``umeyama(src, dst, false)``
    (Umeyama 1991, eqs. 38-42; a reflection turned into a rotation by flipping the last singular
    direction; no rank check, as Eigen's)."""
    n = len(src_xyz)
    mean_src, mean_dst = src_xyz.mean(axis=0), dst_xyz.mean(axis=0)
    sigma = (dst_xyz - mean_dst).T @ (src_xyz - mean_src) / n
    u, _, vt = np.linalg.svd(sigma)
    s = np.ones(src_xyz.shape[1])
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[-1] = -1.0
    r: np.ndarray = (u * s) @ vt
    return r, mean_dst - r @ mean_src


def _quat_of_matrix(r: np.ndarray) -> np.ndarray:
    """The unit quaternion ``xyzw`` of a 3x3 rotation matrix (Shepperd's method)."""
    m = r
    tr = np.trace(m)
    cands = np.array([tr, m[0, 0], m[1, 1], m[2, 2]])
    k = int(np.argmax(cands))
    if k == 0:
        w = 0.5 * np.sqrt(1.0 + tr)
        q = [(m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w), w]
    else:
        i, j, h = (k - 1, k % 3, (k + 1) % 3)
        v = np.zeros(3)
        v[i] = 0.5 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[h, h])
        v[j] = (m[j, i] + m[i, j]) / (4 * v[i])
        v[h] = (m[h, i] + m[i, h]) / (4 * v[i])
        q = [v[0], v[1], v[2], (m[h, j] - m[j, h]) / (4 * v[i])]
    out: np.ndarray = np.array(q) / np.linalg.norm(q)
    return out


def apply_rigid(poses: np.ndarray, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``T * pose`` for every row (jrl ``alignment::internal::transform``: ``Pose(T).compose``)."""
    out = np.array(poses, dtype=np.float64, copy=True)
    if poses.shape[1] == 3:
        out[:, 0:2] = poses[:, 0:2] @ r.T + t
        out[:, 2] = normalize_angle(poses[:, 2] + np.arctan2(r[1, 0], r[0, 0]))
        return out
    q = np.broadcast_to(_quat_of_matrix(r), (len(poses), 4))
    out[:, 0:3] = poses[:, 0:3] @ r.T + t
    out[:, 3:7] = quat_mul(q, poses[:, 3:7])
    return out


def _position_width(poses: np.ndarray) -> int:
    return 2 if poses.shape[1] == 3 else 3


def ate(est: np.ndarray, ref: np.ndarray, *, align: bool = True) -> PoseError:
    """jrl ``computeATE`` (and ``computeJointAlignedATE``) on matched rows: the estimate moved by
    :func:`umeyama_rigid` of its positions onto the reference's (``align``), then
    ``(sqrt(mean t^2), sqrt(mean r^2))`` of :func:`squared_pose_errors`; ``(0, 0)`` with no pose."""
    if not len(ref):
        return 0.0, 0.0
    if align:
        d = _position_width(ref)
        r, t = umeyama_rigid(est[:, 0:d], ref[:, 0:d])
        est = apply_rigid(est, r, t)
    t2, r2 = squared_pose_errors(est, ref)
    return float(np.sqrt(t2.sum() / len(ref))), float(np.sqrt(r2.sum() / len(ref)))


def sve(solutions: Sequence[RobotValues]) -> PoseError:
    """jrl ``computeSVE``: for every key held by more than one robot, the squared errors of every
    pair of its holders' estimates (:func:`squared_pose_errors`) summed; the sums divided by the
    number of such keys (not of pairs, whatever ``format/METRIC_FORMAT.md`` writes), square roots
    taken. NaN when no key is shared, as jrl's ``0 / 0`` (written ``null`` in a ``.jrm``)."""
    nonempty = [s for s in solutions if len(s.keys)]
    if not nonempty:
        return float("nan"), float("nan")
    keys = np.concatenate([s.keys for s in nonempty])
    poses = np.concatenate([s.poses for s in nonempty])
    order = np.argsort(keys, kind="stable")
    keys, poses = keys[order], poses[order]
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    counts = np.diff(np.r_[starts, len(keys)])
    t_sum = r_sum = 0.0
    for c in np.unique(counts[counts > 1]).tolist():
        first = starts[counts == c]
        for i, j in combinations(range(c), 2):
            t2, r2 = squared_pose_errors(poses[first + i], poses[first + j])
            t_sum += float(t2.sum())
            r_sum += float(r2.sum())
    shared = int(np.count_nonzero(counts > 1))
    if shared == 0:
        return float("nan"), float("nan")
    return float(np.sqrt(t_sum / shared)), float(np.sqrt(r_sum / shared))


def _pose3_logmap(d: np.ndarray) -> np.ndarray:
    """GTSAM ``Pose3::Logmap`` of rows ``(translation, rotation vector)`` of a relative pose ``D``:
    ``[w, u]`` with ``w = Log(R)`` and ``u = t - (theta/2) W t + (1 - theta / (2 tan(theta/2))) W^2 t``
    (``W`` the skew matrix of ``w / theta``; Agrawal 2006, eq. 14, as ``Pose3.cpp`` writes it)."""
    t, w = d[:, 0:3], d[:, 3:6]
    theta = np.linalg.norm(w, axis=1)
    big = theta >= 1e-10
    axis = np.where(big[:, None], w / np.where(big, theta, 1.0)[:, None], 0.0)
    wt = np.cross(axis, t)
    half = np.where(big, 0.5 * theta, 1.0)
    c = np.where(big, 1.0 - theta / (2.0 * np.tan(half)), 0.0)
    u = t - (0.5 * theta)[:, None] * wt + c[:, None] * np.cross(axis, wt)
    return np.column_stack([w, np.where(big[:, None], u, t)])


@dataclass(frozen=True, eq=False)
class PoseFactors:
    """A dataset's ``BetweenFactorPose2/3`` and ``PriorFactorPose2/3`` as columns: ``key2`` is -1 for
    a prior (its one key is ``key1``); ``measurements`` pose rows; ``information`` the inverse of
    each factor's covariance, in GTSAM's tangent order (``x y theta``; ``rx ry rz x y z``)."""

    key1: np.ndarray
    key2: np.ndarray
    measurements: np.ndarray
    information: np.ndarray

    def __len__(self) -> int:
        return len(self.key1)


def gtsam_factor_errors(x1: np.ndarray, x2: np.ndarray | None, measurements: np.ndarray) -> np.ndarray:
    """GTSAM's whitening-free residual ``r`` of each factor: ``Local(z, x1^-1 x2)`` for a between
    factor, ``Local(z, x1)`` for a prior (``x2`` None). ``Pose2``: ``(x, y, theta)`` of ``z^-1 h``
    (GTSAM's default Pose2 chart); ``Pose3``: ``Pose3::Logmap(z^-1 h)``, rotation first (GTSAM
    built with ``POSE3_EXPMAP``, its default)."""
    if x2 is None:
        x1, x2 = np.zeros_like(x1), x1
        if x1.shape[1] == 7:
            x1[:, 6] = 1.0
    if measurements.shape[1] == 3:
        return edge_errors(x1, x2, measurements)
    return _pose3_logmap(edge_errors(x1, x2, measurements, convention="rotvec"))


def _owner_table(solutions: Sequence[RobotValues]) -> tuple[np.ndarray, np.ndarray]:
    """Every ``(key, pose)`` of every robot's solution, sorted by key (robots in order within a key)."""
    keys = np.concatenate([s.keys for s in solutions])
    poses = np.concatenate([s.poses for s in solutions])
    order = np.argsort(keys, kind="stable")
    return keys[order], poses[order]


def _holders(all_keys: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    start = np.searchsorted(all_keys, keys, side="left")
    stop = np.searchsorted(all_keys, keys, side="right")
    return start, stop - start


def mean_residual(factors: PoseFactors, solutions: Sequence[RobotValues]) -> float:
    """jrl ``computeMeanResidual``: for every factor, the mean of GTSAM's error ``0.5 r^T Omega r``
    over every combination of the robots' estimates of its keys (the Cartesian product of each key's
    holders), summed over factors. A key no robot holds raises (jrl's product would be empty)."""
    if not len(factors):
        return 0.0
    all_keys, all_poses = _owner_table(solutions)
    s1, c1 = _holders(all_keys, factors.key1)
    prior = factors.key2 < 0
    s2, c2 = _holders(all_keys, np.where(prior, factors.key1, factors.key2))
    c2 = np.where(prior, 1, c2)
    for keys, counts in ((factors.key1, c1), (factors.key2, np.where(prior, 1, c2))):
        if np.any(counts == 0):
            bad = int(keys[np.flatnonzero(counts == 0)[0]])
            raise EvaluationError(f"no robot's solution holds key {bad} ({_symbol(bad)}), which a measurement names")
    combos = c1 * c2
    fidx = np.repeat(np.arange(len(factors)), combos)
    m = np.arange(len(fidx)) - np.repeat(np.cumsum(combos) - combos, combos)
    i1 = s1[fidx] + m // c2[fidx]
    i2 = s2[fidx] + m % c2[fidx]
    z = factors.measurements[fidx]
    x1 = all_poses[i1]
    r = np.empty((len(fidx), factors.information.shape[1]))
    p = prior[fidx]
    if p.any():
        r[p] = gtsam_factor_errors(x1[p], None, z[p])
    if (~p).any():
        r[~p] = gtsam_factor_errors(x1[~p], all_poses[i2[~p]], z[~p])
    err = 0.5 * np.einsum("ni,nij,nj->n", r, factors.information[fidx], r)
    per_factor = np.bincount(fidx, weights=err, minlength=len(factors)) / combos
    return float(per_factor.sum())


def _symbol(key: int) -> str:
    c = key >> 56
    return f"{chr(c) if 32 < c < 127 else '?'}{key & ((1 << 56) - 1)}"


def precision_recall(
    measured: Sequence[set[tuple[int, int]]],
    potential: Sequence[set[tuple[int, int]]],
    outliers: Sequence[set[tuple[int, int]]],
    rejected: Sequence[set[tuple[int, int]]],
) -> tuple[PoseError, dict[int, PoseError]]:
    """jrl ``computePrecisionRecall``: over every robot's measurements (``measured``: its FactorIds
    ``(entry, measurement)``) that are potential outliers, inliers are the positive class: a kept
    inlier is a true positive, a rejected inlier a false negative, a kept outlier a false positive.
    ``precision = tp / (tp + fp)``, ``recall = tp / (tp + fn)``, -1 where the denominator is 0; per
    robot (by position; only robots with a measurement, as jrl sets them inside its loop) and in all."""
    total = np.zeros(3)
    per_robot: dict[int, PoseError] = {}
    for k, ids in enumerate(measured):
        scored = ids & potential[k]
        pred = [(f in outliers[k], f in rejected[k]) for f in scored]
        tp = sum(1 for o, p in pred if not o and not p)
        fn = sum(1 for o, p in pred if not o and p)
        fp = sum(1 for o, p in pred if o and not p)
        if ids:
            per_robot[k] = _pr(tp, fp, fn)
        total += (tp, fp, fn)
    return _pr(*total.tolist()), per_robot


def _pr(tp: float, fp: float, fn: float) -> PoseError:
    precision = tp / (tp + fp) if tp + fp > 0 else -1.0
    recall = tp / (tp + fn) if tp + fn > 0 else -1.0
    return float(precision), float(recall)
