import math

import numpy as np

from studio.core.geometry import normalize_angle
from studio.generator.kollagen import (
    _libstdcxx_reduce,
    _round_to_int,
    agent_pairs,
    discrete_circle,
    effective_seeds,
)
from studio.generator.walk import _round_half_away


def test_duplicate_seeds_are_replaced_like_kollagen():
    assert effective_seeds([42, 42, 42]) == (42, 43, 44)
    assert effective_seeds([1, 2, 3]) == (1, 2, 3)
    # kollagen's list of used seeds starts with one zero per existing agent
    assert effective_seeds([5, 0]) == (5, 6)
    assert effective_seeds([0, 0, 0]) == (0, 1, 2)
    assert effective_seeds([0, 7]) == (0, 7)
    # the replacement is a C++ int: INT_MAX + 1 wraps to INT_MIN (checked against kollagen's binary)
    assert effective_seeds([2**31 - 1] * 3) == (2**31 - 1, -(2**31), -(2**31))


def test_discrete_circle_order():
    assert discrete_circle(1).tolist() == [[-1, 0], [0, 0], [0, 1], [0, -1], [1, 0]]
    c = discrete_circle(20)
    assert len(c) == 1257
    assert (c[:, 0] ** 2 + c[:, 1] ** 2 <= 400).all()


def test_agent_pairs_are_lexicographic():
    assert agent_pairs(4) == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    assert agent_pairs(1) == []


def test_c_rounding_half_away_from_zero():
    v = np.array([0.5, 1.5, 2.5, -0.5, -2.5, 0.49999999999999994, -1.2])
    assert _round_half_away(v).tolist() == [1, 2, 3, -1, -3, 0, -1]
    assert [_round_to_int(x) for x in v.tolist()] == [1, 2, 3, -1, -3, 0, -1]


def test_normalize_angle_matches_kollagen_formula():
    for a in (0.0, math.pi, -math.pi, 3 * math.pi / 2, -7.0, 1e-3):
        expected = a - math.floor((a + math.pi) / (2 * math.pi)) * 2 * math.pi
        assert normalize_angle(a) == expected
        assert -math.pi <= normalize_angle(a) < math.pi


def test_libstdcxx_reduce_sums_in_blocks_of_four():
    vals = np.array([1e16, 1.0, -1e16, 1.0, 3.0])
    # ((1e16 + 1) + (-1e16 + 1)) then + 3: the block order loses a different amount than a left fold
    assert _libstdcxx_reduce(vals) == 0.0 + ((1e16 + 1.0) + (-1e16 + 1.0)) + 3.0
    assert _libstdcxx_reduce(vals) != ((((1e16 + 1.0) - 1e16) + 1.0) + 3.0)
