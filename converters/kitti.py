"""KITTI odometry ground truth: ``poses/<seq>.txt``, one pose per line as the 12 numbers of a 3x4
matrix ``[R | t]`` (row major), the camera's pose in the first camera frame, and optionally the
sequence's ``times.txt`` (seconds, one per line; without it the poses are stamped at 10 Hz, with
a warning).

The camera frame is x right, y down, z forward; the studio's frames are z up. Each pose is turned
into the z-up frame ``x forward, y left, z up`` for both the world and the body:
``T' = A T A^T`` with ``A = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]`` (a position ``(x, y, z)``
becomes ``(z, -x, -y)``), so a car driving on flat ground moves in the x-y plane with yaw about z.
Inputs are pose files; a ``times.txt`` is taken from beside the file or from
``sequences/<seq>/times.txt`` of the usual layout. Agents are named after the file (``00``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.converters.names import safe_agent_name
from studio.converters.text import read_table
from studio.core.errors import FormatError
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike
from studio.core.units import MAX_STAMP_S

__all__ = ["read_kitti", "kitti_times_for", "CAMERA_TO_Z_UP"]

#: Rotation from KITTI's camera frame (x right, y down, z forward) to x forward, y left, z up.
CAMERA_TO_Z_UP = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_WHAT = "KITTI poses: 12 numbers per line, a 3x4 matrix [R | t] row by row"
KITTI_RATE_HZ = 10.0


def kitti_times_for(poses: Path) -> Path | None:
    for cand in (poses.with_name("times.txt"), poses.parent.parent / "sequences" / poses.stem / "times.txt"):
        if cand.is_file():
            return cand
    return None


def read_kitti(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: object = None,
) -> list[Trajectory]:
    """``studio convert kitti POSES.txt...``: one agent per pose file."""
    from scipy.spatial.transform import Rotation

    out = []
    for raw in inputs:
        path = Path(raw)
        if not path.is_file():
            raise FormatError(f"{path}: no such KITTI poses file")
        table, _ = read_table(path, 12, what=_WHAT, header=False)
        m = table.reshape(-1, 3, 4)
        rot = np.einsum("ij,njk,lk->nil", CAMERA_TO_Z_UP, m[:, :, 0:3], CAMERA_TO_Z_UP)
        det = np.linalg.det(rot)
        bad = np.flatnonzero(np.abs(det - 1.0) > 1e-3)
        if bad.size:
            raise FormatError(f"{path}: pose {int(bad[0])} is not a rotation (determinant {det[bad[0]]:.6g})")
        pos = m[:, :, 3] @ CAMERA_TO_Z_UP.T
        times = kitti_times_for(path)
        if times is None:
            if warn is not None:
                warn(
                    f"{path}: no times.txt beside it or in sequences/{path.stem}/; "
                    f"poses stamped at {KITTI_RATE_HZ:g} Hz"
                )
            stamps = np.round(np.arange(len(m)) * (1e9 / KITTI_RATE_HZ)).astype(np.int64)
        else:
            t, _ = read_table(times, 1, what="KITTI times.txt: one time in seconds per line", header=False)
            if len(t) != len(m):
                raise FormatError(f"{times}: {len(t)} times for the {len(m)} poses of {path}")
            far = np.flatnonzero(~(np.abs(t[:, 0]) <= MAX_STAMP_S))  # beyond it, nanoseconds leave int64
            if far.size:
                raise FormatError(
                    f"{times}: time {int(far[0]) + 1} ({t[far[0], 0]:g} s) is beyond the int64 nanosecond range "
                    f"({MAX_STAMP_S:.4g} s)"
                )
            stamps = np.round(t[:, 0] * 1e9).astype(np.int64)
        quat = Rotation.from_matrix(rot).as_quat()  # x y z w
        out.append(clean_trajectory(safe_agent_name(path.stem), stamps, pos, quat, str(path), warn))
    return out
