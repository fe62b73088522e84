"""What every source reader returns: one agent's timestamped SE(3) poses, as columns.

Also the small quaternion algebra the graph builder needs (vectorised numpy, Hamilton convention,
``quat_xyzw`` scalar last as in TUM and g2o) and the rule that turns agent names taken from data into
safe folder names. Pure data and maths: no I/O here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

from studio.errors import ConfigError, FormatError

__all__ = [
    "Trajectory",
    "clean_trajectory",
    "safe_agent_name",
    "check_agent_name",
    "quat_mul",
    "quat_conj",
    "quat_rotate",
    "quat_from_rotvec",
    "quat_angle",
    "quat_canonical",
    "RESERVED_NAMES",
    "MAX_COORDINATE_M",
]

Warn = Callable[[str], None]

#: Names an agent folder may not take: the files written beside the agent folders.
RESERVED_NAMES = frozenset({"convert.json", "report.json", "outliers.txt", "inter_agent_lc.dat"})
#: Largest position coordinate [m] of a trajectory: UTM and ECEF coordinates stay under 1e7 m, and
#: beyond this the graph builder's products overflow.
MAX_COORDINATE_M = 1e9
_SAFE = re.compile(r"[^A-Za-z0-9_.+-]+")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One agent's poses: ``stamps_ns`` int64 increasing, ``positions_xyz`` (n, 3) metres,
    ``quat_xyzw`` (n, 4) unit quaternions body-to-world. ``source`` names where it came from."""

    name: str
    stamps_ns: np.ndarray
    positions_xyz: np.ndarray
    quat_xyzw: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        n = len(self.stamps_ns)
        where = self.source or self.name
        if self.positions_xyz.shape != (n, 3) or self.quat_xyzw.shape != (n, 4):
            raise FormatError(f"{where}: positions and orientations do not match the {n} stamps")
        if n < 2:
            raise FormatError(f"{where}: agent {self.name!r} has {n} pose{'s' if n != 1 else ''}; "
                              "a trajectory needs at least 2")
        if np.any(np.diff(self.stamps_ns) <= 0):
            raise FormatError(f"{where}: stamps must increase")

    def __len__(self) -> int:
        return len(self.stamps_ns)


def clean_trajectory(name: str, stamps_ns: np.ndarray, positions_xyz: np.ndarray, quat_xyzw: np.ndarray,
                     source: str, warn: Warn | None = None) -> Trajectory:
    """Sort by time, drop duplicate stamps (keeping the first), normalise quaternions, reject NaN.

    Sorting and de-duplication are reported through ``warn`` with their counts.
    """
    stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
    positions_xyz = np.asarray(positions_xyz, dtype=np.float64).reshape(-1, 3)
    quat_xyzw = np.asarray(quat_xyzw, dtype=np.float64).reshape(-1, 4)
    finite = np.isfinite(positions_xyz).all(axis=1) & np.isfinite(quat_xyzw).all(axis=1)
    if not finite.all():
        raise FormatError(f"{source}: pose {int(np.flatnonzero(~finite)[0])} is not finite")
    far = np.abs(positions_xyz).max(axis=1, initial=0.0) > MAX_COORDINATE_M
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise FormatError(f"{source}: pose {k} has a coordinate of {np.abs(positions_xyz[k]).max():g} m, "
                          f"beyond the {MAX_COORDINATE_M:g} m a trajectory may reach")
    norms = np.linalg.norm(quat_xyzw, axis=1)
    if np.any(norms < 1e-9):
        raise FormatError(f"{source}: pose {int(np.flatnonzero(norms < 1e-9)[0])} has a zero quaternion")
    quat_xyzw = quat_xyzw / norms[:, None]
    if len(stamps_ns) > 1 and np.any(np.diff(stamps_ns) <= 0):
        unsorted = int(np.count_nonzero(np.diff(stamps_ns) < 0))
        order = np.argsort(stamps_ns, kind="stable")
        stamps_ns, positions_xyz, quat_xyzw = stamps_ns[order], positions_xyz[order], quat_xyzw[order]
        keep = np.ones(len(stamps_ns), dtype=bool)
        keep[1:] = np.diff(stamps_ns) != 0
        dups = int(np.count_nonzero(~keep))
        stamps_ns, positions_xyz, quat_xyzw = stamps_ns[keep], positions_xyz[keep], quat_xyzw[keep]
        if warn is not None:
            warn(f"{source}: {unsorted} out-of-order timestamp{'s' if unsorted != 1 else ''} sorted, "
                 f"{dups} duplicate timestamp{'s' if dups != 1 else ''} dropped")
    return Trajectory(name, stamps_ns, positions_xyz, quat_xyzw, source)


def safe_agent_name(raw: str) -> str:
    """A folder name made from a name found in data: runs of unsafe characters become ``_``.

    The result never holds a path separator, never starts with a dot (so never ``.`` or ``..``) and
    is never empty or one of :data:`RESERVED_NAMES`.
    """
    name = _SAFE.sub("_", re.sub(r"\.{2,}", "_", raw))
    name = re.sub(r"_{2,}", "_", name).strip("_").lstrip(".")
    if not name:
        name = "agent"
    if name in RESERVED_NAMES:
        name = f"agent_{name}"
    return name[:100]


def check_agent_name(name: str, where: str) -> str:
    """Validate a name the user typed (``--agent NAME=SPEC``): it must already be safe."""
    if not name or "/" in name or "\\" in name or ".." in name or name.startswith(".") \
            or name in RESERVED_NAMES or safe_agent_name(name) != name:
        raise ConfigError(f"{where}: agent name {name!r} is not a safe folder name "
                          "(letters, digits, '_', '-', '+', '.'; no '/', no '..', no leading dot)")
    return name


# ---------------------------------------------------------------------------------------------------
# quaternions (x, y, z, w), vectorised over rows


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ], axis=-1)


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
    return 2.0 * np.arctan2(v, np.abs(q[..., 3]))


def quat_canonical(q: np.ndarray) -> np.ndarray:
    """Normalised, with ``w >= 0`` (one representative of each rotation)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)
