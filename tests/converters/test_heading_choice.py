"""``--heading-method auto``'s choice (converters/heading_choice.py) on paths whose measures are known:
stops counted between motions only, the metres driven per radian on a circle, the chord's window and
averaging from the rate, and a path that never moves refused as with the fixed methods."""

from __future__ import annotations

import numpy as np
import pytest

from studio.converters import transforms
from studio.converters.heading_choice import STOPS_PER_M, choose_heading_method
from studio.converters.transforms import derive_orientation
from studio.core.errors import FormatError
from studio.core.geometry import yaw_from_quat_xyzw
from studio.core.trajectory import Trajectory


def _path(xy: np.ndarray, rate_hz: float) -> Trajectory:
    n = len(xy)
    stamps = (np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    return Trajectory("a", stamps, np.column_stack([xy, np.zeros(n)]), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))


def _circle(radius_m: float, speed_mps: float, seconds: float, rate_hz: float) -> np.ndarray:
    a = np.arange(int(seconds * rate_hz)) / rate_hz * speed_mps / radius_m
    return radius_m * np.column_stack([np.cos(a), np.sin(a)])


def _drive_and_stop(stops: int, stop_s: float, rate_hz: float = 100.0) -> np.ndarray:
    """Straight 2 m drives at 0.5 m/s, each followed by a stop of ``stop_s`` (none after the last),
    after a 3 s wait at the start."""
    parts = [np.zeros((int(3 * rate_hz), 2))]
    x = 0.0
    for k in range(stops + 1):
        run = x + np.arange(1, int(4 * rate_hz) + 1) / rate_hz * 0.5
        parts.append(np.column_stack([run, np.zeros(len(run))]))
        x = float(run[-1])
        if k < stops:
            parts.append(np.tile([x, 0.0], (int(stop_s * rate_hz), 1)))
    return np.vstack(parts)


@pytest.mark.parametrize(("stop_s", "counted"), [(2.0, 4), (0.3, 0)])
def test_stops_are_counted_between_motions(stop_s, counted):
    # four stops between five 2 m drives; the wait before the first drive is no stop; a pause
    # shorter than the probe's half second is none either
    choice = choose_heading_method(_path(_drive_and_stop(4, stop_s), 100.0))
    assert choice.stops_per_m == pytest.approx(counted / 10.0, rel=0.05)  # probe steps across a stop's ends
    assert choice.method == ("turns" if counted / 10.0 >= STOPS_PER_M else "chord")
    assert choice.speed_mps == pytest.approx(0.5, rel=1e-6) and choice.rate_hz == pytest.approx(100.0)
    assert choice.m_per_rad == float("inf") and choice.to_dict()["m_per_rad"] is None  # straight


@pytest.mark.parametrize(("rate_hz", "smooth_s"), [(50.0, 0.48), (10.0, 0.4), (2.0, 0.0), (1.0, 0.0)])
def test_a_circle_gets_a_chord_of_its_radius_and_averaging_from_its_rate(rate_hz, smooth_s):
    # a circle of radius 3 m turns a radian every 3 m: a chord of 0.4 x 3 m (at 1 Hz, 1.5 m apart,
    # the probe's steps are chords of the circle: slightly shorter than the arc they turn through)
    choice = choose_heading_method(_path(_circle(3.0, 1.5, 120.0, rate_hz), rate_hz))
    assert choice.method == "chord" and choice.stops_per_m == 0.0
    assert choice.m_per_rad == pytest.approx(3.0, rel=0.04)
    assert choice.window_m == pytest.approx(0.4 * choice.m_per_rad)
    assert choice.smooth_s == pytest.approx(smooth_s)
    assert choice.spacing_m == pytest.approx(1.5 / rate_hz, rel=0.02)  # chords of the arcs
    assert f"positions at {rate_hz:g} Hz" in choice.reason and "it turns while it drives" in choice.reason
    # the longest chord is --heading-window-m's
    assert choose_heading_method(_path(_circle(30.0, 1.5, 120.0, rate_hz), rate_hz)).window_m == 2.0
    assert choose_heading_method(_path(_circle(30.0, 1.5, 120.0, rate_hz), rate_hz), 1.0).window_m == 1.0


def test_the_chord_averaged_over_time_follows_a_noisy_circle_better():
    # 100 Hz, 1 cm of noise: the chord's headings jitter; averaged over +-0.49 s they follow the
    # tangent within a few milliradians (the average is centred: no lag)
    rate_hz = 100.0
    xy = _circle(3.0, 1.0, 60.0, rate_hz)
    noisy = xy + np.random.default_rng(0).normal(0, 0.01, xy.shape)
    t = _path(noisy, rate_hz)
    tangent = np.arange(len(xy)) / rate_hz / 3.0 + np.pi / 2
    choice = choose_heading_method(t)
    errors = {}
    for smooth_s in (0.0, choice.smooth_s):
        yaw = yaw_from_quat_xyzw(derive_orientation(t, choice.window_m, "chord", smooth_s=smooth_s).quat_xyzw)
        errors[smooth_s] = np.abs(np.angle(np.exp(1j * (yaw - tangent))))
    assert np.percentile(errors[0.0][100:-100], 95) > 0.03  # the raw chord's jitter
    assert np.percentile(errors[choice.smooth_s][100:-100], 95) < 0.015
    assert np.array_equal(
        derive_orientation(t, 1.2, "chord", smooth_s=0.0).quat_xyzw, derive_orientation(t, 1.2, "chord").quat_xyzw
    )


def test_the_centred_box_mean_narrows_at_the_ends():
    stamps = np.arange(10, dtype=np.int64) * 100_000_000
    xy = np.column_stack([np.arange(10.0) ** 2, np.zeros(10)])
    got = transforms._centred_box_mean(stamps, xy, 300_000_000)
    assert got[0, 0] == 0.0 and got[-1, 0] == 81.0  # nothing on one side: the pose itself
    assert got[1, 0] == pytest.approx((0 + 1 + 4) / 3)  # one either side
    assert got[5, 0] == pytest.approx(np.mean(np.arange(2, 9) ** 2))  # three either side


def test_a_path_that_never_moves_is_refused_with_auto():
    t = _path(np.zeros((50, 2)), 10.0)
    assert choose_heading_method(t).method == "chord"
    with pytest.raises(FormatError, match="moves less than 0.5 m"):
        derive_orientation(t, 2.0, "auto")
