"""Synthetic trajectories for converter tests: smooth loops, optionally in UTM-sized coordinates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

UTM_EAST, UTM_NORTH = 500_000.0, 4_649_776.0  # a UTM-sized origin (zone 31 around 42 N)


def loop_trajectory(
    n: int = 400,
    *,
    rate_hz: float = 10.0,
    radius: float = 10.0,
    laps: float = 2.0,
    centre=(0.0, 0.0, 0.0),
    phase: float = 0.0,
    t0_s: float = 1_600_000_000.0,
    climb: float = 0.0,
):
    """``n`` poses on a circle driven ``laps`` times, heading along the motion."""
    k = np.arange(n)
    ang = phase + 2 * np.pi * laps * k / (n - 1)
    pos = np.column_stack(
        [centre[0] + radius * np.cos(ang), centre[1] + radius * np.sin(ang), centre[2] + climb * k / n]
    )
    yaw = ang + np.pi / 2
    quat = np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    stamps_ns = np.int64(round(t0_s * 1e9)) + (k * (1e9 / rate_hz)).astype(np.int64)
    return stamps_ns, pos, quat


def tum_text(stamps_ns, pos, quat, *, sep: str = " ", header: str | None = "# timestamp tx ty tz qx qy qz qw") -> str:
    lines = [header] if header else []
    for s, p, q in zip(stamps_ns.tolist(), pos.tolist(), quat.tolist()):
        sec, ns = divmod(s, 1_000_000_000)
        vals = [f"{sec}.{ns:09d}"] + [repr(v) for v in p + q]
        lines.append(sep.join(vals))
    return "\n".join(lines) + "\n"


def write_tum_file(path: Path, stamps_ns, pos, quat, **kw) -> Path:
    path.write_text(tum_text(stamps_ns, pos, quat, **kw))
    return path


def drifting_estimate(stamps, pos, quat, *, scale: float, yaw_rate: float, seed: int):
    """A VIO-like estimate of a trajectory: its motion scaled by ``scale``, its heading drifting by
    ``yaw_rate`` rad/s, plus 2 mm of noise per step, in its own frame (starting at the origin).
    Returns ``(positions_xyz, quat_xyzw)``."""
    from studio.core.geometry import quat_from_rotvec, quat_mul, quat_rotate

    rng = np.random.default_rng(seed)
    t = (np.asarray(stamps) - stamps[0]) / 1e9
    drift = quat_from_rotvec(np.column_stack([np.zeros((len(t), 2)), yaw_rate * t]))
    steps = np.diff(pos, axis=0) * scale + rng.normal(0, 0.002, (len(pos) - 1, 3))
    steps[:, 2] = 0.0
    p = np.vstack([np.zeros(3), np.cumsum(quat_rotate(drift[1:], steps), axis=0)])
    return p, quat_mul(drift, quat)
