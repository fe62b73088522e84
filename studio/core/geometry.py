"""Small SE(2)/SE(3) helpers on numpy columns (pure maths, no I/O).

Conventions: planar poses are ``[x, y, theta]`` (theta in radians); spatial poses are
``[x, y, z, qx, qy, qz, qw]`` (Hamilton, scalar last, the TUM/g2o order). Information matrices are
stored as their upper triangle, row by row.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from studio.core.repeats import distinct_if_repeated

__all__ = [
    "normalize_angle",
    "yaw_to_quat_xyzw",
    "se2_information_to_se3",
    "upper_to_matrix",
    "block_diagonal_where_indefinite",
    "SE3_Z_INFORMATION",
    "planar_poses_to_se3",
    "se3_poses_to_planar",
    "se3_information_to_se2",
    "is_planar_se3",
    "yaw_from_quat_xyzw",
    "libm_cos_sin",
    "relative_planar_pose",
    "quat_mul",
    "quat_conj",
    "quat_rotate",
    "quat_from_rotvec",
    "quat_angle",
    "quat_canonical",
]

#: Information given to z when a planar measurement is written as an SE(3) record (kollagen's choice).
SE3_Z_INFORMATION = 1e6


@overload
def normalize_angle(angle: np.ndarray) -> np.ndarray: ...
@overload
def normalize_angle(angle: float) -> float: ...
def normalize_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Wrap to [-pi, pi) exactly as kollagen: ``a - floor((a + pi) / (2 pi)) * 2 * pi``."""
    if isinstance(angle, float):
        return angle - math.floor((angle + math.pi) / (2 * math.pi)) * 2.0 * math.pi
    angle = np.asarray(angle, dtype=np.float64)
    return angle - np.floor((angle + np.pi) / (2 * np.pi)) * 2.0 * np.pi


def yaw_to_quat_xyzw(theta: np.ndarray) -> np.ndarray:
    """``[0, 0, sin(theta/2), cos(theta/2)]`` per row, with the C library's sin and cos.

    numpy's vectorised sin/cos may differ from libm by an ulp on some CPUs; kollagen's files are made
    with libm, so the values are computed with :mod:`math` to stay bit-exact.
    """
    half = np.asarray(theta, dtype=np.float64) / 2
    cos_half, sin_half = libm_cos_sin(half)
    out = np.zeros((len(half), 4))
    out[:, 2] = sin_half
    out[:, 3] = cos_half
    return out


def upper_to_matrix(upper: np.ndarray, dim: int) -> np.ndarray:
    """Rebuild symmetric ``(n, dim, dim)`` matrices from ``(n, dim*(dim+1)/2)`` upper triangles."""
    upper = np.asarray(upper, dtype=np.float64)
    n = upper.shape[0]
    rows, cols = np.triu_indices(dim)
    out = np.zeros((n, dim, dim))
    out[:, rows, cols] = upper
    out[:, cols, rows] = upper
    return out


def block_diagonal_where_indefinite(upper: np.ndarray, dim: int) -> tuple[np.ndarray, int]:
    """``upper`` with each information matrix that is not positive definite replaced by its
    translation and rotation blocks (the cross block zeroed), where that makes it positive definite;
    and how many were replaced. SE-Sync reads only those blocks (their traces), so files written for
    it may hold cross blocks that break definiteness (its ``cubicle.g2o``: 5021 of 16869 edges)."""
    upper = np.asarray(upper, dtype=np.float64)
    if not len(upper) or not np.isfinite(upper).all():
        return upper, 0
    mats = upper_to_matrix(upper, dim)
    bad = np.flatnonzero(~(np.linalg.eigvalsh(mats)[:, 0] > 0))
    if not bad.size:
        return upper, 0
    k = 2 if dim == 3 else 3
    blocks = mats[bad]
    blocks[:, :k, k:] = 0.0
    blocks[:, k:, :k] = 0.0
    fixed = bad[np.linalg.eigvalsh(blocks)[:, 0] > 0]
    if not fixed.size:
        return upper, 0
    rows, cols = np.triu_indices(dim)
    out = upper.copy()
    out[fixed] = blocks[np.isin(bad, fixed)][:, rows, cols]
    return out, int(fixed.size)


#: Where each planar information entry (xx, xy, xt, yy, yt, tt) goes in the 21 of (x, y, z, rx, ry, rz).
_SE3_FROM_SE2_INFORMATION = [0, 1, 5, 6, 10, 20]
#: The z, roll and pitch diagonal entries of the 21.
_SE3_Z_ENTRY, _SE3_ROLL_PITCH_ENTRIES = 11, [15, 18]


def se2_information_to_se3(upper: np.ndarray) -> np.ndarray:
    """Lift ``(n, 6)`` planar information (x, y, theta) to ``(n, 21)`` for (x, y, z, rx, ry, rz).

    x, y and yaw keep their entries (including cross terms); z gets :data:`SE3_Z_INFORMATION`; roll
    and pitch get the yaw information. With zero cross terms this is exactly what kollagen writes.
    """
    upper = np.asarray(upper, dtype=np.float64)
    out = np.zeros((upper.shape[0], 21))
    out[:, _SE3_FROM_SE2_INFORMATION] = upper
    out[:, _SE3_Z_ENTRY] = SE3_Z_INFORMATION
    out[:, _SE3_ROLL_PITCH_ENTRIES] = upper[:, 5:6]
    return out


def planar_poses_to_se3(poses: np.ndarray) -> np.ndarray:
    """``(n, 3)`` planar poses ``[x, y, theta]`` to ``(n, 7)`` ``[x, y, 0, 0, 0, qz, qw]``."""
    poses = np.asarray(poses, dtype=np.float64)
    out = np.zeros((len(poses), 7))
    out[:, 0:2] = poses[:, 0:2]
    out[:, 3:7] = yaw_to_quat_xyzw(poses[:, 2])
    return out


def yaw_from_quat_xyzw(q: np.ndarray) -> np.ndarray:
    """Yaw [rad] in [-pi, pi] of quaternions ``(n, 4)``: the rotation about z of the ZYX
    (yaw-pitch-roll) decomposition, i.e. the heading of the body x axis projected on the xy plane.
    For a pure yaw ``[0, 0, sin(t/2), cos(t/2)]`` it is ``t`` (to rounding)."""
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    yaw: np.ndarray = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return yaw


def se3_poses_to_planar(poses: np.ndarray) -> np.ndarray:
    """``(n, 7)`` poses ``[x, y, z, qx, qy, qz, qw]`` to ``(n, 3)`` ``[x, y, yaw]``: the one 3D-to-planar
    projection (z, roll and pitch dropped; yaw by :func:`yaw_from_quat_xyzw`), the inverse of
    :func:`planar_poses_to_se3` on planar poses."""
    poses = np.asarray(poses, dtype=np.float64)
    return np.column_stack([poses[:, 0], poses[:, 1], yaw_from_quat_xyzw(poses[:, 3:7])])


#: The (x, y, yaw) entries of a 6x6 information upper triangle over (x, y, z, rx, ry, rz).
_SE2_FROM_SE3_INFORMATION = _SE3_FROM_SE2_INFORMATION


def se3_information_to_se2(upper: np.ndarray) -> np.ndarray:
    """``(n, 21)`` information over (x, y, z, rx, ry, rz) to ``(n, 6)`` over (x, y, yaw): the x, y,
    yaw block (z, roll and pitch dropped), the inverse of :func:`se2_information_to_se3` on it."""
    return np.asarray(upper, dtype=np.float64)[:, _SE2_FROM_SE3_INFORMATION]


def is_planar_se3(poses: np.ndarray, tolerance: float = 1e-9) -> bool:
    """True when every ``(n, 7)`` pose has z, qx and qy within ``tolerance`` of 0 (planar data
    written as 3D records, as kollagen writes its walk)."""
    return bool(np.all(np.abs(np.asarray(poses)[:, [2, 3, 4]]) <= tolerance))


def libm_cos_sin(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """libm's cos and sin of every entry (see :func:`yaw_to_quat_xyzw`), once per distinct value
    where the values repeat (ground-truth headings on a grid)."""
    values, spread = distinct_if_repeated(theta)  # by bit pattern: -0.0 keeps its sign
    lst = values.tolist()
    c = np.fromiter(map(math.cos, lst), dtype=np.float64, count=len(lst))
    s = np.fromiter(map(math.sin, lst), dtype=np.float64, count=len(lst))
    return (c, s) if spread is None else (c[spread], s[spread])


def relative_planar_pose(
    x_from: np.ndarray | float,
    y_from: np.ndarray | float,
    th_from: np.ndarray,
    x_to: np.ndarray | float,
    y_to: np.ndarray | float,
    th_to: np.ndarray | float,
    *,
    cos_sin_from: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar pose ``to`` in the frame of ``from``, columns ``(dx, dy, dtheta)``, evaluated in
    kollagen's order (``calculate_relative_transform``) so the bits match its files.
    ``cos_sin_from``: libm's cos and sin of ``th_from`` where the caller has them already."""
    xdiff = np.asarray(x_to, dtype=np.float64) - x_from
    ydiff = np.asarray(y_to, dtype=np.float64) - y_from
    c, s = libm_cos_sin(th_from) if cos_sin_from is None else cos_sin_from
    dx = xdiff * c + ydiff * s
    dy = -xdiff * s + ydiff * c
    return dx, dy, normalize_angle(np.asarray(th_to, dtype=np.float64) - th_from)


# ---------------------------------------------------------------------------------------------------
# quaternions (x, y, z, w), vectorised over rows


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    out = np.array(q, dtype=np.float64, copy=True)
    out[..., :3] *= -1.0
    return out


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (n, 3) by unit quaternions ``q`` (n, 4)."""
    u = q[..., :3]
    w = q[..., 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_from_rotvec(r: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vectors (n, 3) [rad] to unit quaternions."""
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    small = angle < 1e-12
    scale = np.where(small, 0.5, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate([r * scale, np.cos(half)], axis=-1)


def quat_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle [rad] in [0, pi] of unit quaternions."""
    v = np.linalg.norm(q[..., :3], axis=-1)
    angle: np.ndarray = 2.0 * np.arctan2(v, np.abs(q[..., 3]))
    return angle


def quat_canonical(q: np.ndarray) -> np.ndarray:
    """Normalised, with ``w >= 0`` (one representative of each rotation)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)
