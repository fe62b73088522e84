"""Sanity checks of a ``--planar`` conversion: is the planar projection of a trajectory meaningful?

A planar graph keeps x, y and the yaw of the body x axis (ZYX yaw) and drops z, roll and pitch.
That is silently wrong when

* the body x axis is not the heading but points up (EuRoC's IMU: x up, y right, z forward): the yaw
  of a near-vertical axis is noise; checked as the median angle of the x axis from the vertical;
* the world frame is not z up (a camera frame: y down, z forward): the dropped axis then carries
  most of the motion; checked as the spread of z against the spread in x-y.

Each finding is one warning line per agent, naming what to do; nothing is changed.
"""

from __future__ import annotations

import math

import numpy as np

from studio.core.geometry import quat_rotate
from studio.core.trajectory import Trajectory

__all__ = ["planar_warnings", "default_planar_body_frame", "EUROC_IMU_FRAME", "VERTICAL_X_DEG", "MIN_Z_SPREAD_M"]

#: EuRoC's body frame is its IMU's: x up ("X sort-of-up", ethz-asl/dataset_tools issue 7), y right,
#: z forward (cam0 looks along the body z axis: T_BS of cam0's sensor.yaml).
EUROC_IMU_FRAME = "urf"

#: The body x axis within this angle of the vertical (median over the poses) is "near vertical".
VERTICAL_X_DEG = 30.0
#: z is "most of the motion" when its spread exceeds the x-y spread and this many metres.
MIN_Z_SPREAD_M = 0.2


def default_planar_body_frame(source: str, traj: Trajectory) -> str | None:
    """The body frame a ``--planar`` conversion applies by default where the dataset states it:
    EuRoC's ground truth (``state_groundtruth_estimate0``: the IMU) is :data:`EUROC_IMU_FRAME`.
    TUM VI's motion capture (``mocap0``) states none here; the warnings below catch a wrong one."""
    if source == "euroc" and "state_groundtruth_estimate0" in traj.source:
        return EUROC_IMU_FRAME
    return None


def planar_warnings(traj: Trajectory) -> list[str]:
    """The warning lines for ``traj`` about to be projected to SE(2) (empty when it looks planar)."""
    out = []
    ex = np.zeros((len(traj), 3))
    ex[:, 0] = 1.0
    x_up = np.abs(quat_rotate(traj.quat_xyzw, ex)[:, 2])
    from_vertical = math.degrees(math.acos(min(1.0, float(np.median(x_up)))))
    if from_vertical < VERTICAL_X_DEG:
        out.append(
            f"{traj.name}: --planar takes yaw from the body x axis, which points within {from_vertical:.0f} degrees "
            f"of vertical (median): give the body frame, e.g. --body-frame {traj.name}=urf for x up, y right, "
            "z forward"
        )
    p = traj.positions_xyz
    z_spread = float(np.std(p[:, 2]))
    xy_spread = float(np.hypot(np.std(p[:, 0]), np.std(p[:, 1])))
    if z_spread > max(xy_spread, MIN_Z_SPREAD_M):
        out.append(
            f"{traj.name}: --planar drops z, which carries most of the motion (spread {z_spread:.3g} m against "
            f"{xy_spread:.3g} m in x-y): is the world frame z up? (a camera frame is y down, z forward)"
        )
    return out
