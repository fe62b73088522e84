"""Headings derived from positions only (S3E-style data): ``smoothed`` central differences against the
first ``chord`` method.

The issue asks for increments correlating >= 0.8 with the real ones on real-world ground-robot paths.
No real-world path with orientation could be obtained inside a test here (tests do not touch the
network and no such data is committed), so these tests use simulated paths: a 2 Hz UTM-sized drive
(tests/converters/test_real_layouts.py's ``curved_path``) and the MR.CLAM-like robots of
tests/converters/mrclam_files.py, whose turns on the spot no positions-only method can see.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from studio.converters.transforms import derive_orientation
from studio.core.errors import FormatError
from studio.core.geometry import normalize_angle, yaw_from_quat_xyzw
from studio.core.trajectory import Trajectory
from tests.converters.mrclam_files import simulate
from tests.converters.synthetic import write_tum_file
from tests.converters.test_real_layouts import curved_path, run


def _positions_only(stamps, pos) -> Trajectory:
    return Trajectory("a", stamps, pos, np.tile([0.0, 0.0, 0.0, 1.0], (len(stamps), 1)))


def _increment_correlation(stamps, true_yaw, traj, every: int) -> float:
    got = yaw_from_quat_xyzw(traj.quat_xyzw)[::every]
    return float(np.corrcoef(normalize_angle(np.diff(got)), normalize_angle(np.diff(true_yaw[::every])))[0, 1])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_smoothed_headings_follow_a_2hz_drive(seed):
    stamps, pos, yaw = curved_path(900, seed=seed)
    t = _positions_only(stamps, pos)
    smoothed = _increment_correlation(stamps, yaw, derive_orientation(t, 2.0), 1)
    chord = _increment_correlation(stamps, yaw, derive_orientation(t, 2.0, "chord"), 1)
    assert smoothed >= 0.93 and smoothed > chord


def test_smoothed_headings_gain_on_slow_indoor_robots_but_miss_turns_on_the_spot():
    """The MR.CLAM-like robots (0.05-0.3 m/s, 100 Hz ground truth, 15 % of their commands turns on
    the spot): both methods lose the spot turns, the smoothed one keeps more of the rest."""
    gains = []
    for truth, _, _ in simulate(120.0, 0)[:3]:
        t_s, x, y, th = truth
        stamps = np.round(t_s * 1e9).astype(np.int64)
        t = _positions_only(stamps, np.column_stack([x, y, np.zeros(len(x))]))
        smoothed = _increment_correlation(stamps, th, derive_orientation(t, 2.0), 50)  # at 2 Hz
        chord = _increment_correlation(stamps, th, derive_orientation(t, 2.0, "chord"), 50)
        assert 0.45 < smoothed < 0.8  # measured 0.49-0.58: not the 0.8 the issue asks of real paths
        gains.append(smoothed - chord)
    assert min(gains) > 0.15  # measured 0.19-0.51


def test_the_heading_is_held_while_standing_still():
    n = 700
    stamps = np.arange(n, dtype=np.int64) * 10_000_000  # 100 Hz: 1.5 s east, 4 s still, 1.5 s north
    x = np.concatenate([np.linspace(0, 2, 150), np.full(400, 2.0), 2 + np.zeros(150)])
    y = np.concatenate([np.zeros(150), np.zeros(400), np.linspace(0, 2, 150)])
    rng = np.random.default_rng(0)
    pos = np.column_stack([x, y, np.zeros(n)]) + rng.normal(0, 0.0005, (n, 3))  # 0.5 mm jitter
    yaw = yaw_from_quat_xyzw(derive_orientation(_positions_only(stamps, pos), 2.0).quat_xyzw)
    assert np.abs(yaw[20:140]).max() < 0.05  # east
    still = yaw[300:400]  # a second from either end of the stop: one held value, not the jitter's
    assert np.ptp(still) == 0.0 and abs(still[0]) < 0.05
    assert np.abs(yaw[600:680] - np.pi / 2).max() < 0.05  # then north


def test_a_trajectory_that_never_moves_is_refused():
    stamps = np.arange(50, dtype=np.int64) * 100_000_000
    pos = np.zeros((50, 3))
    with pytest.raises(FormatError, match="never moves faster than 0.02 m/s"):
        derive_orientation(_positions_only(stamps, pos), 2.0)


def test_the_report_names_the_method(tmp_path):
    stamps, pos, _ = curved_path(300, seed=0)
    f = write_tum_file(tmp_path / "alpha_gt.tum", stamps, pos, np.tile([0.0, 0.0, 0.0, 1.0], (len(stamps), 1)))
    res = run("tum", f, "-o", tmp_path / "ds", "--planar", "--no-rrd")
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "ds" / "report.json").read_text())
    assert report["heading_method"].startswith("smoothed: yaw of central differences")
    cfg = json.loads((tmp_path / "ds" / "convert.json").read_text())
    assert "heading_method" not in cfg  # the default is not written (older files stay as they were)
    res = run("tum", f, "-o", tmp_path / "dc", "--planar", "--no-rrd", "--heading-method", "chord")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "dc" / "report.json").read_text())["heading_method"].startswith("chord: ")
    assert json.loads((tmp_path / "dc" / "convert.json").read_text())["heading_method"] == "chord"
    res = run("tum", f, "-o", tmp_path / "dx", "--heading-method", "spline")
    assert res.exit_code == 2 and "--heading-method: expected smoothed or chord, got 'spline'" in res.output
