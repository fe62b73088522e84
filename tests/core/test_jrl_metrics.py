"""jrl's metrics (studio.core.jrl_metrics) against numbers worked out by hand on small cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studio.core.errors import EvaluationError
from studio.core.jrl_metrics import PoseFactors, RobotValues, ate, mean_residual, precision_recall, sve

A, B, C = (ord(c) << 56 for c in "abc")


def values(keys: list[int], poses: list[list[float]]) -> RobotValues:
    return RobotValues(np.array(keys, dtype=np.int64), np.array(poses, dtype=np.float64))


def test_ate_unaligned_is_the_rms_of_translation_and_angle_errors():
    ref = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    est = np.array([[0.0, 1.0, 0.3], [2.0, 0.0, -0.1]])
    # squared errors: translation 1 and 0, angle 0.09 and 0.01
    assert ate(est, ref, align=False) == pytest.approx((math.sqrt(0.5), math.sqrt(0.05)), abs=1e-12)


def test_ate_aligns_positions_then_moves_orientations_too():
    ref = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    # the reference turned by +90 degrees; headings 0.3 and -0.1 off after turning back
    est = np.array([[0.0, -1.0, math.pi / 2 + 0.3], [0.0, 1.0, math.pi / 2 - 0.1]])
    t, r = ate(est, ref)
    assert t == pytest.approx(0.0, abs=1e-12)
    assert r == pytest.approx(math.sqrt((0.09 + 0.01) / 2), abs=1e-12)


def test_ate_aligned_removes_a_shift_in_3d():
    q = [0.0, 0.0, math.sin(0.1), math.cos(0.1)]  # 0.2 rad about z
    ref = np.array([[0, 0, 0, *q], [1, 0, 0, *q], [0, 2, 1, *q]], dtype=float)
    est = ref.copy()
    est[:, 0:3] += [5.0, -2.0, 1.0]
    assert ate(est, ref) == pytest.approx((0.0, 0.0), abs=1e-9)
    assert ate(est, ref, align=False)[0] == pytest.approx(math.sqrt(25 + 4 + 1), abs=1e-12)


def test_sve_divides_by_the_shared_variables_not_the_pairs():
    k, l_, m = A + 0, A + 1, A + 2
    a = values([k, l_, m], [[0, 0, 0], [1, 1, 0], [9, 9, 9]])
    b = values([k, l_], [[3, 4, 0], [1, 1, 0.1]])
    c = values([k], [[0, 0, 0.5]])
    # key k: pairs ab (25, 0), ac (0, 0.25), bc (25, 0.25); key l: ab (0, 0.01); m is not shared
    # jrl's computeSVE divides by 2 shared keys (METRIC_FORMAT.md's formula would divide by 4 pairs)
    assert sve([a, b, c]) == pytest.approx((math.sqrt(50 / 2), math.sqrt(0.51 / 2)), abs=1e-12)


def test_sve_in_3d_and_nan_without_shared_variables():
    z = 0.3
    a = values([B + 4], [[0, 0, 0, 0, 0, 0, 1]])
    b = values([B + 4], [[1, 2, 2, 0, 0, math.sin(z / 2), math.cos(z / 2)]])
    assert sve([a, b]) == pytest.approx((3.0, 0.3), abs=1e-12)
    t, r = sve([a, values([B + 5], [[0, 0, 0, 0, 0, 0, 1]])])
    assert math.isnan(t) and math.isnan(r)


def test_mean_residual_averages_a_factor_over_the_robots_copies():
    # between a0 -> a1, measured (1, 0, 0), unit covariance; robot a holds a0, a1 at the measurement,
    # robot b a copy of a1 at (1, 2, 0): combinations (a, a) error 0 and (a, b) 0.5 * 2^2 = 2, mean 1.
    # prior on a0 at (0, 0, 0.2), covariance 4 I: residual (0, 0, -0.2), error 0.5 * 0.04 / 4 = 0.005
    factors = PoseFactors(
        np.array([A + 0, A + 0]),
        np.array([A + 1, -1]),
        np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.2]]),
        np.array([np.eye(3), np.eye(3) / 4.0]),
    )
    a = values([A + 0, A + 1], [[0, 0, 0], [1, 0, 0]])
    b = values([A + 1], [[1, 2, 0]])
    assert mean_residual(factors, [a, b]) == pytest.approx(1.005, abs=1e-12)


def test_mean_residual_in_3d_is_half_the_mahalanobis_norm_of_the_logmap():
    # GTSAM's Pose3 tangent is rotation first: a pure translation (0, 0, 3) against identity with
    # translation variance 9 gives 0.5 * 9 / 9 = 0.5; a 0.2 rad turn about z with rotation variance
    # 0.01 gives 0.5 * 0.04 / 0.01 = 2
    cov = np.diag([0.01, 0.01, 0.01, 9.0, 9.0, 9.0])
    ident = [0, 0, 0, 0, 0, 0, 1]
    factors = PoseFactors(
        np.array([A + 0, A + 0]),
        np.array([A + 1, A + 2]),
        np.array([ident, ident], dtype=float),
        np.array([np.linalg.inv(cov)] * 2),
    )
    a = values([A + 0, A + 1, A + 2], [ident, [0, 0, 3, 0, 0, 0, 1], [0, 0, 0, 0, 0, math.sin(0.1), math.cos(0.1)]])
    assert mean_residual(factors, [a]) == pytest.approx(2.5, abs=1e-12)


def test_mean_residual_refuses_a_key_no_robot_holds():
    factors = PoseFactors(np.array([A]), np.array([A + 7]), np.zeros((1, 3)), np.array([np.eye(3)]))
    with pytest.raises(EvaluationError, match="a7"):
        mean_residual(factors, [values([A], [[0, 0, 0]])])


def test_precision_recall_counts_inliers_as_the_positive_class():
    measured = [{(0, 0), (0, 1), (1, 0), (1, 1)}, {(0, 0)}, set()]
    potential = [{(0, 1), (1, 0), (1, 1)}, {(0, 0)}, set()]
    outliers = [{(1, 1)}, {(0, 0)}, set()]
    rejected = [{(1, 0), (1, 1)}, set(), set()]
    # a: (0,1) kept inlier tp, (1,0) rejected inlier fn, (1,1) rejected outlier tn -> p 1, r 1/2
    # b: (0,0) kept outlier fp -> p 0, r undefined (-1); c has no measurement, so no entry (as jrl)
    total, per = precision_recall(measured, potential, outliers, rejected)
    assert per == {0: (1.0, 0.5), 1: (0.0, -1.0)}
    assert total == (0.5, 0.5)
