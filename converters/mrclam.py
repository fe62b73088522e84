"""UTIAS MR.CLAM (Multi-Robot Cooperative Localization and Mapping, Leung et al. 2011) as it ships.

A dataset folder ``MRCLAM_DatasetN/`` holds, for robots K = 1..5, ``RobotK_Groundtruth.dat``
(``time [s]  x [m]  y [m]  orientation [rad]``, Vicon, about 60 Hz in the real files), ``RobotK_Odometry.dat``
(``time [s]  forward velocity [m/s]  angular velocity [rad/s]``: the commanded velocities of the
iRobot Create, about 100 Hz), ``RobotK_Measurement.dat`` (``time [s]  barcode #  range [m]
bearing [rad]``: barcodes seen by the robot's camera), and ``Barcodes.dat`` (``subject #  barcode #``:
subjects 1-5 are the robots, 6-20 the landmarks) and ``Landmark_Groundtruth.dat``. Each file starts
with four ``#`` lines; columns are separated by tabs or spaces (the real files: right-aligned
columns, each followed by a space, joined by tabs); times are Unix seconds with millisecond digits
(read to the nearest microsecond).

* :func:`read_mrclam`: one planar trajectory per robot, ``Robot1`` .. ``Robot5``, at the ground
  truth's own rate, z = 0, yaw = the file's orientation.
* :func:`read_mrclam_odometry` (``--odometry real``): each robot's velocities integrated exactly as
  arcs (a command holds until the next; before the first one the robot stands still, after the last
  one the last command holds to the end of the ground truth), shifted by the robot's lag behind its
  commands (:func:`command_lag_ns`, 0.15-0.2 s on the real files), a dead-reckoned trajectory that
  :mod:`studio.converters.odometry_source` turns into odometry edges between the keyframes.
* :func:`read_mrclam_sightings`: the measurements whose barcode is another robot's, as range-bearing
  sightings (:mod:`studio.converters.sightings`). Landmark sightings are left out (counted): the
  studio's model has no landmarks.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.converters.sightings import Sightings
from studio.converters.text import read_text_bounded
from studio.core.errors import FormatError
from studio.core.geometry import yaw_from_quat_xyzw, yaw_to_quat_xyzw
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike
from studio.core.units import MAX_STAMP_S

__all__ = [
    "MRCLAM_ROBOTS",
    "mrclam_files",
    "read_mrclam",
    "read_mrclam_odometry",
    "read_mrclam_sightings",
    "integrate_unicycle",
]

#: Robots of every MR.CLAM dataset.
MRCLAM_ROBOTS = 5
_US = 1000  # nanoseconds per microsecond


def _name(k: int) -> str:
    return f"Robot{k}"


def mrclam_files(root: Path, kind: str) -> list[Path]:
    """``RobotK_<kind>.dat`` of K = 1..5 (those present)."""
    return [p for k in range(1, MRCLAM_ROBOTS + 1) if (p := root / f"Robot{k}_{kind}.dat").is_file()]


def _read_dat(path: Path, columns: int, what: str) -> np.ndarray:
    """The numeric rows of an MR.CLAM ``.dat`` file (``#`` lines skipped), errors naming ``file:line``."""
    text = read_text_bounded(path)
    fast = _read_fast(text, columns)
    if fast is not None:
        return fast
    lines = text.splitlines()
    data = [(n, line) for n, line in enumerate(lines, start=1) if line.strip() and not line.lstrip().startswith("#")]
    if not data:
        raise FormatError(f"{path}: no data rows ({what})")
    out = []
    for n, line in data:  # the slow path finds the bad line
        parts = line.split()
        if len(parts) != columns:
            raise FormatError(f"{path}:{n}: expected {columns} columns ({what}), found {len(parts)}")
        for p in parts:
            try:
                v = float(p)
            except ValueError:
                raise FormatError(f"{path}:{n}: {p[:40]!r} is not a number ({what})") from None
            if not np.isfinite(v):
                raise FormatError(f"{path}:{n}: value is not finite")
        out.append([float(p) for p in parts])
    return np.array(out, dtype=np.float64)


def _read_fast(text: str, columns: int) -> np.ndarray | None:
    """pandas' C parser on a regular file (``#`` only at line starts, every row ``columns`` finite
    numbers); None for anything else, so that the line parser names the offending line."""
    import io
    import re

    if re.search(r"^[ \t]*[^#\s][^#\n]*#", text, re.MULTILINE) or not text.strip():
        return None  # a '#' after data on a line: the line parser says where

    import pandas as pd

    exact = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
    try:
        df = pd.read_csv(io.StringIO(text), sep=r"\s+", header=None, comment="#", engine="c", dtype=np.float64, **exact)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError):
        return None
    values = df.to_numpy(dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != columns or not len(values) or not np.isfinite(values).all():
        return None
    return values


def _data_line(path: Path, row: int) -> int:
    """The 1-based line number of data row ``row`` (0-based, ``#`` and blank lines skipped) of a
    file :func:`_read_dat` has read (for error messages only)."""
    n = -1
    for lineno, line in enumerate(path.read_text(encoding="utf-8-sig").splitlines(), start=1):
        if line.strip() and not line.lstrip().startswith("#"):
            n += 1
            if n == row:
                return lineno
    return 0


def _stamps_ns(seconds: np.ndarray, path: Path, rows: np.ndarray | None = None) -> np.ndarray:
    """``seconds`` in ns; ``rows``: each value's data row in ``path`` (default: its position), so
    the error names the file's line (a stamp on line 6 was once reported as "row 1")."""
    far = np.flatnonzero(~(np.abs(seconds) <= MAX_STAMP_S))
    if far.size:
        row = int(far[0]) if rows is None else int(rows[far[0]])
        raise FormatError(
            f"{path}:{_data_line(path, row)}: time {seconds[far[0]]:g} s is beyond the int64 nanosecond range"
        )
    return np.round(seconds * 1e6).astype(np.int64) * _US


def _root(inputs: Sequence[PathLike]) -> Path:
    root = Path(inputs[0])
    if not root.is_dir():
        raise FormatError(f"{root}: not a folder (expected an MR.CLAM dataset folder, MRCLAM_DatasetN/)")
    return root


_GT_WHAT = "MR.CLAM ground truth: time [s], x [m], y [m], orientation [rad]"


def read_mrclam(
    inputs: Sequence[PathLike], *, agents: Sequence[str] = (), warn: Warn | None = None, progress: object = None
) -> list[Trajectory]:
    """``studio convert mrclam MRCLAM_DatasetN/``: Robot1..Robot5 from ``RobotK_Groundtruth.dat``."""
    root = _root(inputs)
    out = []
    for k in range(1, MRCLAM_ROBOTS + 1):
        path = root / f"Robot{k}_Groundtruth.dat"
        if not path.is_file():
            raise FormatError(f"{path}: missing (an MR.CLAM dataset has RobotK_Groundtruth.dat for K = 1..5)")
        rows = _read_dat(path, 4, _GT_WHAT)
        pos = np.column_stack([rows[:, 1], rows[:, 2], np.zeros(len(rows))])
        out.append(
            clean_trajectory(_name(k), _stamps_ns(rows[:, 0], path), pos, yaw_to_quat_xyzw(rows[:, 3]), str(path), warn)
        )
    return out


def integrate_unicycle(
    stamps_ns: np.ndarray, v_mps: np.ndarray, w_radps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses ``(x, y, yaw)`` at ``stamps_ns`` from ``(0, 0, 0)``, command ``k`` holding from stamp
    ``k`` to stamp ``k + 1`` (exact arcs; straight segments where the turn is below 1e-9 rad)."""
    dt = np.diff(stamps_ns).astype(np.float64) / 1e9
    v, w = v_mps[:-1], w_radps[:-1]
    dth = w * dt
    yaw = np.concatenate([[0.0], np.cumsum(dth)])
    th0, th1 = yaw[:-1], yaw[1:]
    arc = np.abs(dth) > 1e-9
    safe_w = np.where(arc, w, 1.0)
    dx = np.where(arc, v / safe_w * (np.sin(th1) - np.sin(th0)), v * dt * np.cos(th0 + dth / 2))
    dy = np.where(arc, -v / safe_w * (np.cos(th1) - np.cos(th0)), v * dt * np.sin(th0 + dth / 2))
    return np.concatenate([[0.0], np.cumsum(dx)]), np.concatenate([[0.0], np.cumsum(dy)]), yaw


def read_mrclam_odometry(
    inputs: Sequence[PathLike], ground_truth: Sequence[Trajectory], *, warn: Warn | None = None
) -> dict[str, Trajectory]:
    """Each robot's dead-reckoned trajectory from ``RobotK_Odometry.dat`` over the span of its
    ground truth (``ground_truth``: :func:`read_mrclam`'s trajectories), keyed by robot name."""
    root = _root(inputs)
    spans = {t.name: (int(t.stamps_ns[0]), int(t.stamps_ns[-1])) for t in ground_truth}
    out: dict[str, Trajectory] = {}
    for k in range(1, MRCLAM_ROBOTS + 1):
        name = _name(k)
        if name not in spans:
            continue
        path = root / f"Robot{k}_Odometry.dat"
        if not path.is_file():
            raise FormatError(f"{path}: missing (--odometry real integrates RobotK_Odometry.dat)")
        rows = _read_dat(path, 3, "MR.CLAM odometry: time [s], forward velocity [m/s], angular velocity [rad/s]")
        stamps = _stamps_ns(rows[:, 0], path)
        order = np.argsort(stamps, kind="stable")
        if np.any(np.diff(stamps) < 0) and warn is not None:
            warn(f"{path}: {int(np.count_nonzero(np.diff(stamps) < 0))} out-of-order timestamps sorted")
        stamps, v, w = stamps[order], rows[order, 1], rows[order, 2]
        keep = np.ones(len(stamps), dtype=bool)
        keep[:-1] = np.diff(stamps) != 0  # a repeated stamp: the last command of it holds
        stamps, v, w = stamps[keep], v[keep], w[keep]
        gt = next(t for t in ground_truth if t.name == name)
        lag_ns = command_lag_ns(stamps, w, gt)
        stamps = stamps + lag_ns
        first, last = spans[name]
        if first < stamps[0]:  # standing still before the first command
            stamps, v, w = np.concatenate([[first], stamps]), np.concatenate([[0.0], v]), np.concatenate([[0.0], w])
        if last > stamps[-1]:  # the last command holds to the end
            stamps, v, w = np.concatenate([stamps, [last]]), np.concatenate([v, v[-1:]]), np.concatenate([w, w[-1:]])
        x, y, yaw = integrate_unicycle(stamps, v, w)
        pos = np.column_stack([x, y, np.zeros(len(x))])
        source = f"{path} (commands shifted by {lag_ns / 1e9:+.2f} s: {LAG_TEXT})"
        out[name] = Trajectory(name, stamps, pos, yaw_to_quat_xyzw(yaw), source)
    return out


#: How far [s] the robots' motion may follow their velocity commands (searched in 10 ms steps).
MAX_COMMAND_LAG_S = 1.0
LAG_TEXT = "the lag of the ground truth's yaw rate behind the angular velocity commands"


def command_lag_ns(stamps_ns: np.ndarray, w_radps: np.ndarray, ground_truth: Trajectory) -> int:
    """How long after its angular velocity command the robot turns: the shift in 0..1 s (10 ms steps)
    that best correlates the commands (each holding until the next) with the ground truth's yaw rate
    on a 20 Hz grid. 0 where the robot never turns or the spans do not overlap by 10 s."""
    st = ground_truth.stamps_ns
    lo, hi = max(int(st[0]), int(stamps_ns[0])), min(int(st[-1]), int(stamps_ns[-1]))
    step = 50_000_000
    if hi - lo < 10 * 1_000_000_000:
        return 0
    grid = np.arange(lo + 1_000_000_000, hi - 1_000_000_000, step)
    yaw = np.unwrap(yaw_from_quat_xyzw(ground_truth.quat_xyzw))
    rate = np.gradient(np.interp(grid.astype(np.float64), st.astype(np.float64), yaw), step / 1e9)
    if not np.std(rate) > 0 or not np.std(w_radps) > 0:
        return 0
    best, best_lag = -np.inf, 0
    for lag in range(0, int(MAX_COMMAND_LAG_S * 1e9) + 1, 10_000_000):
        cmd = w_radps[np.clip(np.searchsorted(stamps_ns, grid - lag, side="right") - 1, 0, len(stamps_ns) - 1)]
        if np.std(cmd) > 0 and (c := float(np.corrcoef(cmd, rate)[0, 1])) > best:
            best, best_lag = c, lag
    return best_lag


def read_mrclam_sightings(inputs: Sequence[PathLike], *, warn: Warn | None = None) -> Sightings:
    """The robot-to-robot measurements of ``RobotK_Measurement.dat`` (barcodes from ``Barcodes.dat``)."""
    root = _root(inputs)
    bpath = root / "Barcodes.dat"
    if not bpath.is_file():
        raise FormatError(f"{bpath}: missing (it maps MR.CLAM's barcodes to robots and landmarks)")
    table = _read_dat(bpath, 2, "MR.CLAM barcodes: subject #, barcode #")
    robot_of: dict[int, int] = {}
    landmarks: set[int] = set()
    for row, (subject, barcode) in enumerate(table.tolist()):
        where = f"{bpath}:{_data_line(bpath, row)}"
        if not (abs(subject) < 2**31 and abs(barcode) < 2**31) or subject != int(subject) or barcode != int(barcode):
            raise FormatError(f"{where}: subject and barcode must be integers, got {subject:g} {barcode:g}")
        if int(barcode) in robot_of or int(barcode) in landmarks:  # two subjects, one barcode: one was lost
            raise FormatError(f"{where}: barcode {int(barcode)} is given to a second subject ({int(subject)})")
        if 1 <= subject <= MRCLAM_ROBOTS:
            robot_of[int(barcode)] = int(subject) - 1
        else:
            landmarks.add(int(barcode))
    stamps, observer, observed, rng, brg = [], [], [], [], []
    counts = {"landmark_sightings": 0, "unknown_barcodes": 0, "self_sightings": 0}
    for k in range(1, MRCLAM_ROBOTS + 1):
        path = root / f"Robot{k}_Measurement.dat"
        if not path.is_file():
            raise FormatError(f"{path}: missing (an MR.CLAM dataset has RobotK_Measurement.dat for K = 1..5)")
        try:
            rows = _read_dat(path, 4, "MR.CLAM measurements: time [s], barcode #, range [m], bearing [rad]")
        except FormatError as err:
            if "no data rows" not in str(err):
                raise
            continue
        # a fractional barcode (5.7) was truncated to another subject's (5)
        odd = np.flatnonzero(~(np.abs(rows[:, 1]) < 2**31) | (rows[:, 1] != np.round(rows[:, 1])))
        if odd.size:
            raise FormatError(
                f"{path}:{_data_line(path, int(odd[0]))}: barcode {rows[odd[0], 1]:g} is not a barcode (an integer)"
            )
        codes = rows[:, 1].astype(np.int64)
        target = np.array([robot_of.get(int(c), -1) for c in codes], dtype=np.int64)
        counts["landmark_sightings"] += int(np.count_nonzero(np.isin(codes, list(landmarks))))
        counts["unknown_barcodes"] += int(np.count_nonzero((target < 0) & ~np.isin(codes, list(landmarks))))
        counts["self_sightings"] += int(np.count_nonzero(target == k - 1))
        bad = np.flatnonzero(rows[:, 2] < 0)
        if bad.size:
            raise FormatError(f"{path}:{_data_line(path, int(bad[0]))}: a negative range ({rows[bad[0], 2]:g} m)")
        sel = (target >= 0) & (target != k - 1)
        stamps.append(_stamps_ns(rows[sel, 0], path, np.flatnonzero(sel)))
        observer.append(np.full(int(sel.sum()), k - 1, dtype=np.int64))
        observed.append(target[sel])
        rng.append(rows[sel, 2])
        brg.append(rows[sel, 3])
    if counts["unknown_barcodes"] and warn is not None:
        warn(f"{root}: {counts['unknown_barcodes']} measurements of barcodes not in Barcodes.dat left out")
    cat = np.concatenate
    st = cat(stamps) if stamps else np.zeros(0, dtype=np.int64)
    order = np.argsort(st, kind="stable")
    return Sightings(
        tuple(_name(k) for k in range(1, MRCLAM_ROBOTS + 1)),
        st[order],
        (cat(observer) if observer else np.zeros(0, np.int64))[order],
        (cat(observed) if observed else np.zeros(0, np.int64))[order],
        (cat(rng) if rng else np.zeros(0))[order],
        (cat(brg) if brg else np.zeros(0))[order],
        counts,
    )
