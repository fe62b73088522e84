"""What the convert pipeline may do to trajectories between reading and building (pure numpy):

* **body frames**: a robot whose body axes are not x forward, y left, z up (AirMuseum's robots are
  ``ufl`` and ``fur``) is re-expressed in FLU, so a planar conversion takes yaw about the true up axis;
* **orientation from motion**: a trajectory whose orientation carries no information (S3E's RTK
  ground truth has the identity quaternion on every line) gets headings from its motion;
* **split**: one long trajectory becomes N agents over consecutive, optionally overlapping, windows.
"""

from __future__ import annotations

import numpy as np

from studio.converters.options import HEADING_METHODS
from studio.converters.spot_turns import decode_spot_turns
from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import quat_angle, quat_conj, quat_mul
from studio.core.trajectory import Trajectory
from studio.core.units import NS_PER_S

__all__ = [
    "body_frame_rotation",
    "apply_body_frame",
    "orientation_is_uninformative",
    "derive_orientation",
    "HEADING_METHODS",
    "split_trajectory",
    "FRAME_LETTERS",
]

#: Directions a body axis may point to, in FLU coordinates.
FRAME_LETTERS = {"f": (1, 0, 0), "b": (-1, 0, 0), "l": (0, 1, 0), "r": (0, -1, 0), "u": (0, 0, 1), "d": (0, 0, -1)}


def body_frame_rotation(code: str) -> np.ndarray:
    """``R_flu_body`` of a frame code such as ``ufl`` (body x points up, y forward, z left)."""
    code = code.lower()
    if len(code) != 3 or any(c not in FRAME_LETTERS for c in code):
        raise ConfigError(f"body frame {code!r}: expected three letters of f, b, l, r, u, d (e.g. flu, ufl, fur)")
    m: np.ndarray = np.array([FRAME_LETTERS[c] for c in code], dtype=np.float64).T  # columns: body axes in FLU
    if abs(np.linalg.det(m) - 1.0) > 1e-9:
        raise ConfigError(f"body frame {code!r}: not a right-handed frame")
    return m


def apply_body_frame(traj: Trajectory, code: str) -> Trajectory:
    """The same motion with FLU body axes: ``q_world_flu = q_world_body * q_body_flu``."""
    from scipy.spatial.transform import Rotation

    r_body_flu = Rotation.from_matrix(body_frame_rotation(code).T).as_quat()
    q = quat_mul(traj.quat_xyzw, np.broadcast_to(r_body_flu, traj.quat_xyzw.shape))
    return Trajectory(
        traj.name, traj.stamps_ns, traj.positions_xyz, q / np.linalg.norm(q, axis=1, keepdims=True), traj.source
    )


def orientation_is_uninformative(traj: Trajectory, tolerance_rad: float = 1e-6) -> bool:
    """True when every orientation is the same (identity included): it says nothing of the motion."""
    q = traj.quat_xyzw
    return bool(np.all(quat_angle(quat_mul(quat_conj(q[:1]), q)) <= tolerance_rad))


#: Half-width [s] of the box filter, applied twice, that smooths positions for ``smoothed`` headings.
SMOOTH_HALF_WIDTH_S = 0.5
#: Half-width [s] of the shorter box filter, applied twice (a 0.5 s triangle), whose speed must also
#: reach :data:`STILL_SPEED_MPS` for the robot to move: the 1 s triangle alone carries a drive's
#: motion up to half a second into each stop (and out of it before the robot drives off).
SHORT_HALF_WIDTH_S = 0.25
#: Below this speed [m/s] of the smoothed positions the robot stands still (no heading of its own).
STILL_SPEED_MPS = 0.02


def _box_mean(stamps_ns: np.ndarray, xy: np.ndarray, half_ns: int) -> np.ndarray:
    """Mean of the rows within ``half_ns`` of each stamp (cumulative sums: linear time)."""
    lo = np.searchsorted(stamps_ns, stamps_ns - half_ns, side="left")
    hi = np.searchsorted(stamps_ns, stamps_ns + half_ns, side="right")
    c = np.vstack([np.zeros((1, xy.shape[1])), np.cumsum(xy, axis=0)])
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def _centred_box_mean(stamps_ns: np.ndarray, xy: np.ndarray, half_ns: int) -> np.ndarray:
    """:func:`_box_mean` with each window narrowed to what both sides hold, so that it stays centred
    on its stamp: near the ends a one-sided mean would lead or lag."""
    half = np.minimum(np.minimum(half_ns, stamps_ns - stamps_ns[0]), stamps_ns[-1] - stamps_ns)
    lo = np.searchsorted(stamps_ns, stamps_ns - half, side="left")
    hi = np.searchsorted(stamps_ns, stamps_ns + half, side="right")
    c = np.vstack([np.zeros((1, xy.shape[1])), np.cumsum(xy, axis=0)])
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def _central_velocity(stamps_ns: np.ndarray, xy: np.ndarray, half_s: float) -> np.ndarray:
    """Velocity [m/s] of the central differences of ``xy`` smoothed by a box filter of half-width
    ``half_s`` applied twice (a triangle of ``2 half_s``)."""
    half = int(round(half_s * 1e9))
    smooth = _box_mean(stamps_ns, _box_mean(stamps_ns, xy, half), half)
    n = len(stamps_ns)
    ahead = np.minimum(np.arange(n) + 1, n - 1)
    behind = np.maximum(np.arange(n) - 1, 0)
    dt_s = (stamps_ns[ahead] - stamps_ns[behind]) / 1e9
    out: np.ndarray = (smooth[ahead] - smooth[behind]) / np.maximum(dt_s, 1e-9)[:, None]
    return out


def _smoothed_headings(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Yaw of the central differences of the positions smoothed by a box filter of half-width
    :data:`SMOOTH_HALF_WIDTH_S` applied twice (a triangle of 1 s), and where the robot moves: the
    speed of those smoothed positions, and of the positions smoothed over the shorter
    :data:`SHORT_HALF_WIDTH_S`, both at least :data:`STILL_SPEED_MPS`."""
    st = traj.stamps_ns
    xy = traj.positions_xyz[:, 0:2] - traj.positions_xyz[0, 0:2]  # UTM-sized sums lose digits
    v = _central_velocity(st, xy, SMOOTH_HALF_WIDTH_S)
    v_short = _central_velocity(st, xy, SHORT_HALF_WIDTH_S)
    moving = (np.linalg.norm(v, axis=1) >= STILL_SPEED_MPS) & (np.linalg.norm(v_short, axis=1) >= STILL_SPEED_MPS)
    return np.arctan2(v[:, 1], v[:, 0]), moving


def derive_orientation(
    traj: Trajectory, window_m: float, method: str = "smoothed", *, smooth_s: float = 0.0
) -> Trajectory:
    """Headings from the motion; roll and pitch are zero. Positions cannot show a turn on the spot.

    ``smoothed``: the yaw of the central differences of lightly smoothed positions
    (:func:`_smoothed_headings`); while the robot stands still between two motions the heading turns
    evenly from the one before the stop to the one after it (a turn on the spot spread over the stop;
    a full turn, or a turn and back, stays invisible), and before the first and after the last motion
    it is held. ``turns``: ``smoothed``, with the turns on the spot of stops of 1.5 s or more decoded
    from the tracked point's motion where it shows them (:mod:`studio.converters.spot_turns`).
    ``chord``: the yaw of the chord from ``window_m / 2`` of path behind
    each pose to ``window_m / 2`` ahead (clipped at the ends), held while the robot moves less than a
    quarter of the window; with ``smooth_s`` > 0, those headings' unit vectors are then averaged by a
    box filter of half-width ``smooth_s`` applied twice, narrowed near the ends to stay centred. ``auto``: the
    method and window :func:`studio.converters.heading_choice.choose_heading_method` chooses for
    ``traj`` (``window_m`` its longest chord)."""
    if not window_m > 0:
        raise ConfigError(f"heading_window_m: expected a positive length, got {window_m!r}")
    if method not in HEADING_METHODS:
        raise ConfigError(f"heading_method: expected {' or '.join(HEADING_METHODS)}, got {method!r}")
    if method == "auto":
        from studio.converters.heading_choice import choose_heading_method

        choice = choose_heading_method(traj, window_m)
        return derive_orientation(traj, choice.window_m, choice.method, smooth_s=choice.smooth_s)
    p = traj.positions_xyz
    if method in ("smoothed", "turns"):
        yaw, moving = _smoothed_headings(traj)
        if not moving.any():
            raise FormatError(
                f"{traj.source or traj.name}: the trajectory never moves faster than {STILL_SPEED_MPS:g} m/s: "
                "no heading can be derived from its motion"
            )
        yaw = _held_yaw(traj, yaw, moving, spread_stops=True)
        if method == "turns":
            turned, decoded = decode_spot_turns(traj.stamps_ns, p[:, 0:2], np.unwrap(yaw), moving)
            if decoded:  # (where no stop was decoded, the smoothed headings as they are, bit for bit)
                yaw = np.arctan2(np.sin(turned), np.cos(turned))
        return _with_yaw(traj, yaw)
    xy = p[:, 0:2]
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    ahead = np.minimum(np.searchsorted(s, s + window_m / 2, side="left"), len(s) - 1)
    behind = np.maximum(np.searchsorted(s, s - window_m / 2, side="right") - 1, 0)
    chord = xy[ahead] - xy[behind]
    moving = np.linalg.norm(chord, axis=1) >= window_m / 4
    if not moving.any():
        raise FormatError(
            f"{traj.source or traj.name}: the trajectory moves less than {window_m / 4:g} m: "
            "no heading can be derived from its motion"
        )
    yaw = _held_yaw(traj, np.arctan2(chord[:, 1], chord[:, 0]), moving)
    if smooth_s > 0:  # the headings' unit vectors averaged: no lag, no pull towards a curve's centre
        half = int(round(smooth_s * NS_PER_S))
        u = np.column_stack([np.cos(yaw), np.sin(yaw)])
        u = _centred_box_mean(traj.stamps_ns, _centred_box_mean(traj.stamps_ns, u, half), half)
        yaw = np.arctan2(u[:, 1], u[:, 0])
    return _with_yaw(traj, yaw)


def _held_yaw(traj: Trajectory, yaw: np.ndarray, moving: np.ndarray, *, spread_stops: bool = False) -> np.ndarray:
    """``yaw`` where ``moving``; elsewhere the last moving heading (the first one before the first
    motion, the last one after the last). With ``spread_stops``, a stop between two motions instead
    turns evenly, by the shorter way, from the heading before it to the heading after it (in time):
    a turn on the spot is spread over the stop instead of jumping when the robot drives off."""
    moving_at = np.flatnonzero(moving)
    if spread_stops:
        unwrapped = np.unwrap(yaw[moving_at])
        yaw = np.interp(traj.stamps_ns.astype(np.float64), traj.stamps_ns[moving_at].astype(np.float64), unwrapped)
        yaw = np.arctan2(np.sin(yaw), np.cos(yaw))
    else:
        idx = np.where(moving, np.arange(len(yaw)), 0)
        np.maximum.accumulate(idx, out=idx)  # hold the last heading
        idx[: int(moving_at[0])] = int(moving_at[0])  # and before the first motion, the first heading
        yaw = yaw[idx]
    return yaw


def _with_yaw(traj: Trajectory, yaw: np.ndarray) -> Trajectory:
    """``traj``'s positions with headings ``yaw`` (roll and pitch zero)."""
    q = np.zeros((len(yaw), 4))
    q[:, 2], q[:, 3] = np.sin(yaw / 2), np.cos(yaw / 2)
    return Trajectory(traj.name, traj.stamps_ns, traj.positions_xyz, q, traj.source)


def time_windows(
    stamps_ns: np.ndarray, parts: int, overlap_s: float, where: str, *, label: str = "overlap"
) -> list[np.ndarray]:
    """Boolean selections of ``stamps_ns`` (sorted) in ``parts`` consecutive windows of equal length,
    each overlapping the next by ``overlap_s`` (half-open, the last closed at the last stamp): the
    one window rule of ``--split`` on trajectories and of the g2o ``time`` partition. An overlap not
    shorter than a window is a ConfigError starting ``label:`` and naming ``where``."""
    t0, t1 = int(stamps_ns[0]), int(stamps_ns[-1])
    overlap_ns = int(round(overlap_s * NS_PER_S))
    length = (t1 - t0 + (parts - 1) * overlap_ns) / parts
    if length <= overlap_ns:
        raise ConfigError(
            f"{label}: {overlap_s:g} s is not shorter than each of the {parts} windows "
            f"({length / NS_PER_S:.3g} s) of {where}"
        )
    out = []
    for k in range(parts):
        start = t0 + k * (length - overlap_ns)
        end = start + length
        out.append((stamps_ns >= start) & (stamps_ns <= end if k == parts - 1 else stamps_ns < end))
    return out


def split_trajectory(traj: Trajectory, parts: int, overlap_s: float) -> list[Trajectory]:
    """``parts`` agents over consecutive windows of equal length overlapping by ``overlap_s``, named
    ``<name>_1 .. <name>_N``; each keeps its own slice of the poses (its own ground truth)."""
    if isinstance(parts, bool) or not isinstance(parts, int) or parts < 2:
        raise ConfigError(f"split: expected an integer of at least 2, got {parts!r}")
    if not (overlap_s >= 0):
        raise ConfigError(f"overlap: expected a non-negative number of seconds, got {overlap_s!r}")
    out = []
    for k, sel in enumerate(time_windows(traj.stamps_ns, parts, overlap_s, traj.name, label="overlap")):
        if sel.sum() < 2:
            raise FormatError(
                f"{traj.source or traj.name}: window {k + 1} of {parts} holds {int(sel.sum())} poses; "
                "a trajectory needs at least 2"
            )
        out.append(
            Trajectory(
                f"{traj.name}_{k + 1}", traj.stamps_ns[sel], traj.positions_xyz[sel], traj.quat_xyzw[sel], traj.source
            )
        )
    return out
