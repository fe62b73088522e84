"""Work once per distinct value: -0.0 and 0.0 are different values."""

from __future__ import annotations

import math

import numpy as np

from studio.core.geometry import yaw_to_quat_xyzw
from studio.core.repeats import distinct_if_repeated


def test_repeated_column_spreads_back_bit_for_bit():
    values = np.tile([0.0, -0.0, 1.5, -math.pi], 50)
    distinct, spread = distinct_if_repeated(values)
    assert spread is not None and len(distinct) == 4
    assert distinct[spread].view(np.int64).tolist() == values.view(np.int64).tolist()


def test_distinct_column_is_left_alone():
    values = np.arange(300) * 0.1
    distinct, spread = distinct_if_repeated(values)
    assert spread is None and distinct.tolist() == values.tolist()


def test_yaw_quaternions_keep_the_sign_of_zero_on_a_repeated_column():
    theta = np.tile([0.0, -0.0, math.pi / 2], 40)
    q = yaw_to_quat_xyzw(theta)
    assert np.signbit(q[:, 2]).tolist() == np.signbit([math.sin(t / 2) for t in theta]).tolist()
    assert q[:, 3].tolist() == [math.cos(t / 2) for t in theta]
