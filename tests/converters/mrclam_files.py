"""Writes MR.CLAM-layout dataset folders for the tests and the docs (the data is simulated; the layout
is the dataset's: ``RobotK_Groundtruth.dat``, ``RobotK_Odometry.dat``, ``RobotK_Measurement.dat``,
``Barcodes.dat``, ``Landmark_Groundtruth.dat``, four ``#`` lines then tab-separated columns, Unix
seconds with three decimals).

Five unicycle robots drive piecewise-constant velocity commands (some turns on the spot) logged at
about 67 Hz; the true motion is the command with a scale error and noise (so the "odometry" differs
from the truth as wheel odometry does), the ground truth is sampled at 100 Hz with 1 mm of noise, and
each robot's camera sees the other robots and the landmarks within 5 m and +-30 degrees, range and
bearing with noise. Barcodes are MR.CLAM's own: robots 1-5 carry 5, 14, 41, 32, 23.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

T0_S = 1248272262.841  # a stamp in MR.CLAM's range (July 2009)
ROBOT_BARCODES = (5, 14, 41, 32, 23)
LANDMARK_BARCODES = (72, 27, 54, 70, 36, 18, 25, 9, 81, 16, 90, 61, 45, 7, 63)
RANGE_SIGMA_M = 0.05
BEARING_SIGMA_RAD = 0.02
_HEAD = (
    "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n"
    "# produced by Keith Leung (keith.leung@robotics.utias.utoronto.ca) 2009\n"
    "# (test stand-in written by tests/converters/mrclam_files.py)\n"
)


def _write(path: Path, columns: str, rows: np.ndarray, fmts: list[str], padded: bool = False) -> None:
    """``padded``: as the real files are laid out (the copies in public repositories): each column
    right-aligned and followed by a space, columns joined by a tab, a space before every tab and at
    the end of the line (``1248444175.103 \t 1.41277290 \t -3.89107760 \t 2.26960000 ``)."""
    fmt = " \t ".join(fmts) + " " if padded else "\t".join(fmts)
    lines = [fmt % tuple(r) for r in rows.tolist()]
    path.write_text(_HEAD + "# " + columns + "\n" + "\n".join(lines) + "\n", encoding="utf-8")


def simulate(seconds: float, seed: int, lag_s: float = 0.0):
    """Per robot: (gt_t, gt_x, gt_y, gt_th), (cmd_t, v, w), all numpy arrays, 1 ms integration.
    ``lag_s``: the robots move ``lag_s`` after each command (the real robots follow theirs by
    0.15-0.2 s)."""
    rng = np.random.default_rng(seed)
    robots = []
    n = int(seconds * 1000)
    for k in range(5):
        cmd_t = np.cumsum(rng.uniform(0.010, 0.020, int(seconds / 0.010)))
        cmd_t = cmd_t[cmd_t < seconds]
        seg = (cmd_t // 2.0).astype(int)  # a new command every 2 s
        nseg = seg.max() + 1
        v_seg = rng.uniform(0.05, 0.3, nseg)
        w_seg = rng.uniform(-0.4, 0.4, nseg)
        spot = rng.random(nseg) < 0.15  # turns on the spot
        v_seg[spot] = 0.0
        w_seg[spot] = rng.choice([-0.8, 0.8], int(spot.sum()))
        v_cmd, w_cmd = v_seg[seg], w_seg[seg]
        # the true motion at 1 kHz: the command in force, with a scale error and noise
        t_ms = np.arange(n) / 1000.0
        idx = np.clip(np.searchsorted(cmd_t, t_ms - lag_s, side="right") - 1, 0, len(cmd_t) - 1)
        before = t_ms - lag_s < cmd_t[0]
        v = np.where(before, 0.0, v_cmd[idx]) * (1.03 + 0.02 * k) + rng.normal(0, 0.02, n)
        w = np.where(before, 0.0, w_cmd[idx]) * 0.97 + rng.normal(0, 0.05, n)
        v[before] = w[before] = 0.0
        th = rng.uniform(-np.pi, np.pi) + np.concatenate([[0.0], np.cumsum(w[:-1] / 1000.0)])
        x = 1.2 * k - 2.4 + np.concatenate([[0.0], np.cumsum(v[:-1] * np.cos(th[:-1]) / 1000.0)])
        y = 0.5 * (k % 2) + np.concatenate([[0.0], np.cumsum(v[:-1] * np.sin(th[:-1]) / 1000.0)])
        gt = np.arange(0, n, 10)
        truth = (t_ms[gt], x[gt] + rng.normal(0, 0.001, len(gt)), y[gt] + rng.normal(0, 0.001, len(gt)), th[gt])
        robots.append((truth, (cmd_t, v_cmd, w_cmd), (t_ms, x, y, th)))
    return robots


def write_mrclam_dataset(
    root: Path, *, seconds: float = 60.0, seed: int = 0, lag_s: float = 0.0, padded: bool = False
) -> Path:
    """An ``MRCLAM_DatasetN``-layout folder at ``root``; returns it. ``lag_s``: see :func:`simulate`;
    ``padded``: the real files' column layout (see :func:`_write`)."""
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed + 100)
    robots = simulate(seconds, seed, lag_s)
    landmarks = np.column_stack([rng.uniform(-5, 5, 15), rng.uniform(-4, 4, 15)])
    _write(
        root / "Barcodes.dat",
        "Subject #\tBarcode #",
        np.array([[k + 1, b] for k, b in enumerate(ROBOT_BARCODES + LANDMARK_BARCODES)]),
        ["%d", "%d"],
        padded,
    )
    _write(
        root / "Landmark_Groundtruth.dat",
        "Subject #\tx [m]\ty [m]\tx std-dev [m]\ty std-dev [m]",
        np.column_stack([np.arange(6, 21), landmarks, np.full(15, 0.001), np.full(15, 0.001)]),
        ["%d", "%.4f", "%.4f", "%.6f", "%.6f"],
        padded,
    )
    for k, (truth, cmd, dense) in enumerate(robots):
        gt_t, gx, gy, gth = truth
        th_wrapped = (gth + np.pi) % (2 * np.pi) - np.pi
        _write(
            root / f"Robot{k + 1}_Groundtruth.dat",
            "Time [s]\tx [m]\ty [m]\torientation [rad]",
            np.column_stack([T0_S + gt_t, gx, gy, th_wrapped]),
            ["%.3f", "%.4f", "%.4f", "%.4f"],
            padded,
        )
        _write(
            root / f"Robot{k + 1}_Odometry.dat",
            "Time [s]\tforward velocity [m/s]\tangular velocity [rad/s]",
            np.column_stack([T0_S + cmd[0], cmd[1], cmd[2]]),
            ["%.3f", "%.3f", "%.3f"],
            padded,
        )
        # camera frames every 0.2 s: other robots and landmarks within 5 m and +-30 degrees
        t_ms, x, y, th = dense
        rows = []
        for i in range(0, len(t_ms), 200):
            for code, (tx, ty) in [
                *((ROBOT_BARCODES[j], (robots[j][2][1][i], robots[j][2][2][i])) for j in range(5) if j != k),
                *zip(LANDMARK_BARCODES, landmarks.tolist()),
            ]:
                dx, dy = tx - x[i], ty - y[i]
                r = float(np.hypot(dx, dy))
                b = float((np.arctan2(dy, dx) - th[i] + np.pi) % (2 * np.pi) - np.pi)
                if r < 5.0 and abs(b) < np.radians(30):
                    rows.append(
                        [
                            T0_S + t_ms[i],
                            code,
                            abs(r + rng.normal(0, RANGE_SIGMA_M)),
                            b + rng.normal(0, BEARING_SIGMA_RAD),
                        ]
                    )
        rows.append([T0_S + 1.0, 99, 1.0, 0.0])  # a barcode nobody carries (misread)
        rows.sort(key=lambda r: r[0])
        _write(
            root / f"Robot{k + 1}_Measurement.dat",
            "Time [s]\tSubject #\trange [m]\tbearing [rad]",
            np.array(rows),
            ["%.3f", "%d", "%.4f", "%.4f"],
            padded,
        )
    return root
