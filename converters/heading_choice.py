"""``--heading-method auto``: the way headings are derived from positions, chosen from the path itself.

No fixed method suits every platform and rate. ``turns`` (and ``smoothed``, which it refines) turn
the heading across stops and smooth over about a second: right for a robot that stops and turns on
the spot between short drives (MR.CLAM's iRobot Creates under Vicon at 60 Hz), wrong at 2 Hz, where a
second is two samples, and wrong on a car whose centimetre ground-truth noise, at a standstill,
passes the smoothed method's speed threshold. A chord of path (``chord``) follows a vehicle that
turns while it drives, at any rate, if it is short against the path's turns and not shorter than
its samples are apart.

So the path is probed every :data:`PROBE_STEP_S` (or at every pose where they are sparser) and:

* where it stops at least :data:`STOPS_PER_M` times per metre driven (a stop: the probe's speed
  under :data:`~studio.converters.transforms.STILL_SPEED_MPS` for :data:`MIN_STOP_S` or more between
  two motions), the robot turns on the spot between drives: ``turns``;
* otherwise ``chord``, over :data:`WINDOW_PER_TURN` of the path driven per radian turned (the
  path's turning scale), at most ``max_window_m`` (``--heading-window-m``, 2 m by default), its
  headings then averaged by the smoothed method's box filter (applied twice) narrowed by one sample
  interval: +-0.5 s less the median interval, so that a heading is never averaged with one half a
  second away (none at 2 Hz and sparser, where a chord shorter than the spacing is the central
  difference of the neighbours).

Pure numpy; the constants were chosen on MR.CLAM dataset 6 and KITTI 00 and their subsamples to 1 and
2 Hz (docs/converters.md gives the figures of the paths held out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.converters.transforms import SMOOTH_HALF_WIDTH_S, STILL_SPEED_MPS
from studio.core.trajectory import Trajectory
from studio.core.units import NS_PER_S

__all__ = ["HeadingChoice", "choose_heading_method", "PROBE_STEP_S", "STOPS_PER_M", "WINDOW_PER_TURN"]

#: Interval [s] at which the path is probed for its speed, stops and turns (every pose if sparser).
PROBE_STEP_S = 0.5
#: Shortest stop [s] counted: standing still this long between two motions.
MIN_STOP_S = 0.5
#: Stops per metre driven from which the robot is taken to turn on the spot between drives
#: (MR.CLAM dataset 6: 0.6-3.1 per metre; KITTI 00: none in 3.7 km).
STOPS_PER_M = 0.05
#: The chord's length as a fraction of the metres driven per radian turned.
WINDOW_PER_TURN = 0.4


@dataclass(frozen=True)
class HeadingChoice:
    """The method ``auto`` chose for one trajectory, its chord window and why."""

    method: str
    """``turns`` or ``chord``."""
    window_m: float
    """The chord's length [m] (``chord``), or the ``--heading-window-m`` given (``turns`` uses none)."""
    smooth_s: float
    """Half-width [s] of the box filter applied twice to the chord's headings (0: none)."""
    reason: str
    """One line: what was measured and what it implied."""
    rate_hz: float
    """Median rate of the positions [Hz]."""
    spacing_m: float
    """Median distance between consecutive positions [m]."""
    speed_mps: float
    """Median speed while moving, at the probe's interval [m/s]."""
    stops_per_m: float
    """Stops of :data:`MIN_STOP_S` or more between two motions, per metre driven."""
    m_per_rad: float
    """Metres driven per radian of turning while moving (infinite on a straight path)."""

    def to_dict(self) -> dict[str, object]:
        return {
            "method": self.method,
            "window_m": round(self.window_m, 4),
            "smooth_s": round(self.smooth_s, 4),
            "reason": self.reason,
            "rate_hz": round(self.rate_hz, 3),
            "spacing_m": round(self.spacing_m, 5),
            "speed_mps": round(self.speed_mps, 4),
            "stops_per_m": round(self.stops_per_m, 4),
            "m_per_rad": round(self.m_per_rad, 3) if np.isfinite(self.m_per_rad) else None,
        }


def _probe(stamps_ns: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path every :data:`PROBE_STEP_S` (the first pose at or after each tick): each step's
    displacement, its duration [s] and whether it moves."""
    grid = np.arange(stamps_ns[0], stamps_ns[-1] + 1, int(PROBE_STEP_S * NS_PER_S))
    at = np.unique(np.minimum(np.searchsorted(stamps_ns, grid), len(stamps_ns) - 1))
    step = np.diff(xy[at], axis=0)
    dt_s = np.diff(stamps_ns[at]) / NS_PER_S
    moving = np.linalg.norm(step, axis=1) >= STILL_SPEED_MPS * dt_s
    return step, dt_s, moving


def _stops(dt_s: np.ndarray, moving: np.ndarray) -> int:
    """Runs of still steps lasting :data:`MIN_STOP_S` or more with motion before and after."""
    edges = np.flatnonzero(np.diff(moving.astype(np.int8)))  # the last step before each change
    count = 0
    for first in (int(e) + 1 for e in edges if moving[e]):  # a stop's first still step
        after = np.flatnonzero(moving[first:])
        if len(after) and dt_s[first : first + int(after[0])].sum() >= MIN_STOP_S - 1e-9:
            count += 1
    return count


def choose_heading_method(traj: Trajectory, max_window_m: float = 2.0) -> HeadingChoice:
    """The heading method and chord window for ``traj``'s positions (its orientation is not read)."""
    st = traj.stamps_ns
    xy = traj.positions_xyz[:, 0:2] - traj.positions_xyz[0, 0:2]
    dt_all = np.diff(st)
    interval_s = float(np.median(dt_all)) / NS_PER_S if len(dt_all) else 0.0
    rate_hz = 1 / interval_s if interval_s > 0 else 0.0
    spacing_m = float(np.median(np.linalg.norm(np.diff(xy, axis=0), axis=1))) if len(xy) > 1 else 0.0
    step, dt_s, moving = _probe(st, xy)
    length = np.linalg.norm(step[moving], axis=1)
    driven_m = float(length.sum())
    speed = float(np.median(length / dt_s[moving])) if moving.any() else 0.0
    stops = _stops(dt_s, moving)
    stops_per_m = stops / driven_m if driven_m > 0 else 0.0
    heading = np.arctan2(step[:, 1], step[:, 0])
    both = moving[1:] & moving[:-1]  # turning while moving: consecutive moving steps
    turned = np.abs(np.angle(np.exp(1j * (heading[1:] - heading[:-1]))))[both].sum()
    m_per_rad = driven_m / turned if turned > 0 else float("inf")
    facts = (
        f"positions at {rate_hz:.3g} Hz, {spacing_m:.3g} m apart; {speed:.3g} m/s while moving; "
        f"{stops} stops in {driven_m:.4g} m ({stops_per_m:.3g} per m)"
    )
    if stops_per_m >= STOPS_PER_M:
        reason = f"{facts}: the robot stops and turns on the spot between drives (>= {STOPS_PER_M:g} stops per m)"
        return HeadingChoice("turns", max_window_m, 0.0, reason, rate_hz, spacing_m, speed, stops_per_m, m_per_rad)
    window = min(max_window_m, WINDOW_PER_TURN * m_per_rad)
    smooth_s = max(0.0, SMOOTH_HALF_WIDTH_S - interval_s)
    reason = (
        f"{facts}, {m_per_rad:.3g} m driven per radian turned: it turns while it drives "
        f"(< {STOPS_PER_M:g} stops per m); a chord of {WINDOW_PER_TURN:g} x that, at most {max_window_m:g} m, "
        f"its headings averaged over +-{smooth_s:.3g} s (+-{SMOOTH_HALF_WIDTH_S:g} s less the interval)"
    )
    return HeadingChoice("chord", window, smooth_s, reason, rate_hz, spacing_m, speed, stops_per_m, m_per_rad)
