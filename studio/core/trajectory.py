"""The one timed-pose type of the studio: an agent's timestamped SE(3) poses, as columns.

Every source reader returns it, the TUM reader and writer use it, and estimates are read into it.
Pure data: no I/O here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from studio.core.errors import FormatError
from studio.core.units import MAX_MAGNITUDE

__all__ = ["Trajectory", "clean_trajectory", "Warn"]

Warn = Callable[[str], None]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One agent's timed poses: ``stamps_ns`` int64 increasing, ``positions_xyz`` (n, 3) metres,
    ``quat_xyzw`` (n, 4) quaternions body-to-world (Hamilton, scalar last). ``source`` names where
    it came from (a file, a bag topic), for messages.

    The one timed-pose type of the studio: source readers return it, TUM files are read into and
    written from it, estimates are split into one per agent.
    """

    name: str
    stamps_ns: np.ndarray
    positions_xyz: np.ndarray
    quat_xyzw: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamps_ns", np.ascontiguousarray(self.stamps_ns, dtype=np.int64))
        object.__setattr__(self, "positions_xyz", np.asarray(self.positions_xyz, dtype=np.float64))
        object.__setattr__(self, "quat_xyzw", np.asarray(self.quat_xyzw, dtype=np.float64))
        n = len(self.stamps_ns)
        where = self.source or self.name
        if self.stamps_ns.ndim != 1 or self.positions_xyz.shape != (n, 3) or self.quat_xyzw.shape != (n, 4):
            raise FormatError(f"{where}: positions and orientations do not match the {n} stamps")
        if n == 0:
            raise FormatError(f"{where}: agent {self.name!r} has no poses")
        if np.any(np.diff(self.stamps_ns) <= 0):
            raise FormatError(f"{where}: stamps must increase")

    def __len__(self) -> int:
        return len(self.stamps_ns)

    @classmethod
    def from_poses(
        cls, name: str, stamps_ns: np.ndarray, poses_xyz_quat_xyzw: np.ndarray, source: str = ""
    ) -> Trajectory:
        """From ``(n, 7)`` rows ``x y z qx qy qz qw`` (the TUM and g2o column order)."""
        poses = np.asarray(poses_xyz_quat_xyzw, dtype=np.float64)
        if poses.ndim != 2 or poses.shape[1] != 7:
            raise FormatError(f"{source or name}: poses must have shape (n, 7), got {poses.shape}")
        return cls(name, stamps_ns, poses[:, 0:3], poses[:, 3:7], source)

    @property
    def poses_xyz_quat_xyzw(self) -> np.ndarray:
        """``(n, 7)`` rows ``x y z qx qy qz qw``."""
        return np.hstack([self.positions_xyz, self.quat_xyzw])


def clean_trajectory(
    name: str,
    stamps_ns: np.ndarray,
    positions_xyz: np.ndarray,
    quat_xyzw: np.ndarray,
    source: str,
    warn: Warn | None = None,
) -> Trajectory:
    """Sort by time, drop duplicate stamps (keeping the first), normalise quaternions, reject NaN;
    a trajectory to convert needs at least 2 poses.

    Sorting and de-duplication are reported through ``warn`` with their counts.
    """
    stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
    positions_xyz = np.asarray(positions_xyz, dtype=np.float64).reshape(-1, 3)
    quat_xyzw = np.asarray(quat_xyzw, dtype=np.float64).reshape(-1, 4)
    finite = np.isfinite(positions_xyz).all(axis=1) & np.isfinite(quat_xyzw).all(axis=1)
    if not finite.all():
        raise FormatError(f"{source}: pose {int(np.flatnonzero(~finite)[0])} is not finite")
    far = np.abs(positions_xyz).max(axis=1, initial=0.0) > MAX_MAGNITUDE
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise FormatError(
            f"{source}: pose {k} has a coordinate of {np.abs(positions_xyz[k]).max():g} m, "
            f"beyond the {MAX_MAGNITUDE:g} m a trajectory may reach"
        )
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
            warn(
                f"{source}: {unsorted} out-of-order timestamp{'s' if unsorted != 1 else ''} sorted, "
                f"{dups} duplicate timestamp{'s' if dups != 1 else ''} dropped"
            )
    n = len(stamps_ns)
    if n < 2:
        raise FormatError(
            f"{source or name}: agent {name!r} has {n} pose{'s' if n != 1 else ''}; a trajectory needs at least 2"
        )
    return Trajectory(name, stamps_ns, positions_xyz, quat_xyzw, source)
