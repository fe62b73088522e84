"""The numpy number formatter writes exactly what C's printf (and Python's ``%``) writes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.io.textfmt import (
    TextColumn,
    concat,
    float_columns,
    float_rows,
    format_float,
    int_column,
    join_array,
    join_columns,
    literal,
)


def _texts(values: np.ndarray, fmt: str) -> list[str]:
    col = float_columns(np.asarray(values, dtype=np.float64).reshape(-1, 1), [fmt])[0]
    texts = col.tolist()
    return texts * len(values) if len(texts) == 1 else texts


def _edge_values() -> np.ndarray:
    """Powers of ten and their neighbours, ties, zeros, extremes, non-finite values."""
    p = 10.0 ** np.arange(-13, 19)
    near = np.concatenate([np.nextafter(p, 0), p, np.nextafter(p, np.inf), np.nextafter(np.nextafter(p, 0), 0)])
    special = np.array(
        [
            0.0,
            -0.0,
            1.0,
            0.5,
            0.25,
            1e-5,
            1e-4,
            9.999999999999999e16,
            123456789012345678.0,
            5e-324,
            2.2250738585072014e-308,
            1.7976931348623157e308,
            np.inf,
            -np.inf,
            np.nan,
            1890.359168241966,
            1000000.0,
            5e-7,
            2.5e-7,
            1.5e-6,
            0.0000004999999999999999,
        ]
    )
    ties = np.arange(1, 2000) * 2.0**-21  # exact binary ties for %f's sixth decimal
    values = np.concatenate([near, special, ties, ties * 1e3])
    return np.concatenate([values, -values])


@pytest.fixture(autouse=True, params=["numpy", "python"])
def _format_path(request, monkeypatch):
    """Every test on both paths of ``_format_block``: the numpy passes (forced for every size) and
    Python's ``%`` (which small blocks take)."""
    big = 1 << 60
    limit = {"%.17g": 0, "%f": 0} if request.param == "numpy" else {"%.17g": big, "%f": big}
    monkeypatch.setattr("studio.io.textfmt._PYTHON_FORMAT_MAX", limit)


def test_edge_values_match_printf():
    values = _edge_values()
    for fmt in ("%.17g", "%f"):
        assert _texts(values, fmt) == [fmt % v for v in values.tolist()]


def test_random_magnitudes_match_printf():
    rng = np.random.default_rng(7)
    values = np.concatenate(
        [
            rng.normal(size=20000) * 10.0 ** rng.integers(-20, 25, size=20000),
            rng.integers(-(2**53), 2**53, 20000).astype(np.float64) * 2.0 ** rng.integers(-90, 20, 20000),
            rng.integers(-4000, 4000, 20000) * 0.25,  # grid positions: the repeated-values path
        ]
    )
    for fmt in ("%.17g", "%f"):
        assert _texts(values, fmt) == [fmt % v for v in values.tolist()]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True), min_size=1, max_size=80))
def test_any_double_matches_printf(values):
    arr = np.array(values, dtype=np.float64)
    for fmt in ("%.17g", "%f"):
        assert _texts(arr, fmt) == [fmt % v for v in arr.tolist()]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(2**63) + 1, 2**63 - 1), min_size=1, max_size=50))
def test_integers_match_str(values):
    assert int_column(np.array(values, dtype=np.int64)).tolist() == [str(v) for v in values]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 10**8 - 1), min_size=1, max_size=50))
def test_small_non_negative_integers_match_str_and_are_nul_padded(values):
    # ids and whole-second stamps: the one-word layout (below 10**8, no sign)
    col = int_column(np.array(values, dtype=np.int64))
    assert col.tolist() == [str(v) for v in values]
    assert not col.chars[np.arange(col.chars.shape[1])[None, :] >= col.lengths[:, None]].any()


def test_integers_at_the_one_word_bounds():
    values = [0, 9, 10, 99, 100, 10**7 - 1, 10**7, 10**8 - 1, 10**8, 10**8 + 1, -1, 12345678]
    for chunk in (values, values[:8], values[7:]):
        assert int_column(np.array(chunk, dtype=np.int64)).tolist() == [str(v) for v in chunk]
    assert join_columns([literal("V"), int_column(np.arange(12))]) == b"".join(b"V %d\n" % k for k in range(12))


def test_zero_literal_only_for_positive_zero():
    values = np.array([[0.0, -0.0, 1.5], [0.0, 2.0, -0.0]])
    cols = float_columns(values, ["%.17g"] * 3, ["0.0", "0.0", None])
    assert cols[0].tolist() == ["0.0"]  # constant column: one row, repeated by join_columns
    assert cols[1].tolist() == ["-0", "2"]
    assert cols[2].tolist() == ["1.5", "-0"]


def test_join_columns_lays_out_lines_and_repeats_one_row_columns():
    ids = int_column(np.array([3, -12, 100]))
    vals = float_columns(np.array([[0.1, 7.0], [2.5, 7.0], [-1e-7, 7.0]]), ["%.17g", "%.17g"])
    text = join_columns([literal("TAG"), ids, *vals])
    assert text == b"TAG 3 0.10000000000000001 7\nTAG -12 2.5 7\nTAG 100 -9.9999999999999995e-08 7\n"
    assert join_columns([literal("x"), int_column(np.zeros(0, dtype=np.int64))]) == b""


def test_float_rows_groups_repeated_rows():
    rows = np.array([[1.0, 0.0], [2.0, 0.0], [1.0, 0.0], [1.0, 0.0]] * 50)
    cols = float_rows(rows, ["%.17g", "%.17g"], [None, "0.0"])
    assert join_columns(cols) == b"".join(b"%s 0.0\n" % (b"1" if r[0] == 1 else b"2") for r in rows)


def test_concat_joins_without_separator():
    sign = TextColumn(np.array([[45], [0]], dtype=np.uint8), np.array([1, 0]))
    assert concat([sign, int_column(np.array([0, 12])), literal("."), int_column(np.array([5, 7]))]).tolist() == [
        "-0.5",
        "12.7",
    ]


def test_format_float_single_values():
    assert format_float(0.1) == "0.10000000000000001"
    assert format_float(-2.0, "%f") == "-2.000000"
    assert format_float(1e300) == "1.0000000000000001e+300"


def _padding_is_nul(col: TextColumn) -> bool:
    beyond = np.arange(col.chars.shape[1])[None, :] >= np.asarray(col.lengths)[:, None]
    return not col.chars[beyond].any()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True), min_size=1, max_size=60),
    st.lists(st.integers(-(2**63) + 1, 2**63 - 1), min_size=1, max_size=30),
)
def test_every_column_is_nul_padded(floats, ints):
    # join_array takes the lines' characters to be the non-NUL bytes of the laid-out fields
    values = np.array(floats + [1.0, 0.5, 100.0, 0.0, 1e-3], dtype=np.float64)  # trailing zeros cut in fixed notation
    for fmt in ("%.17g", "%f"):
        for zero in (None, "0.0"):
            (col,) = float_columns(values.reshape(-1, 1), [fmt], [zero])
            assert _padding_is_nul(col), (fmt, zero)
    (rows,) = float_rows(np.tile(values[:3], (4, 1)), ["%.17g"] * 3)
    assert _padding_is_nul(rows)
    ints_col = int_column(np.array(ints, dtype=np.int64))
    assert _padding_is_nul(ints_col)
    sign = TextColumn(np.array([[45], [0]], dtype=np.uint8), np.array([1, 0]))
    assert _padding_is_nul(
        concat([sign, int_column(np.array([0, 123456])), literal("."), int_column(np.array([5, 7]))])
    )


def test_join_array_matches_line_by_line_formatting():
    rng = np.random.default_rng(3)
    values = np.column_stack(
        [rng.normal(size=500) * 10.0 ** rng.integers(-6, 8, 500), rng.integers(-40, 40, 500) * 0.25]
    )
    ids = rng.integers(-(10**6), 10**6, 500)
    text = join_array([literal("EDGE"), int_column(ids), *float_columns(values, ["%.17g", "%f"])]).tobytes()
    assert text == b"".join(b"EDGE %d %.17g %f\n" % (i, a, b) for i, (a, b) in zip(ids.tolist(), values.tolist()))


# ---------------------------------------------------------------------------------------------------
# format_lines: Python's % for few lines, numpy columns for many, the same bytes


def _line_fields(rng: np.random.Generator, n: int) -> list:
    from studio.io.textfmt import Floats, Ints

    values = rng.normal(size=(n, 7)) * 10.0 ** rng.integers(-12, 18, size=(n, 7))
    values[:, 2] = 0.0  # a constant zero with a literal
    values[rng.random(n) < 0.2, 3] = 0.0  # zeros among other values, a literal for the positive ones
    values[rng.random(n) < 0.1, 3] = -0.0
    values[rng.random(n) < 0.05, 4] = rng.choice([np.inf, -np.inf, np.nan, 1e300, 5e-324])
    values[:, 5] = rng.choice([0.25, -0.5, 3.0], n)  # few distinct values
    info = np.tile([2500.0, 0.0, -0.0, 2500.0, 0.0, 1e-7], (n, 1))
    info[rng.random(n) < 0.3] = [1600.0, 0.5, 0.0, 1600.0, 0.0, 1111.1111111111111]
    if n % 2:
        info[rng.random(n) < 0.5] = rng.normal(size=6)  # mostly distinct rows
    return [
        "EDGE_SE3:QUAT",
        Ints(rng.integers(-(2**62), 2**62, n)),
        Ints(np.full(n, 7)),
        Floats(values, ["%.17g"] * 5 + ["%f", "%.17g"], [None, None, "0.0", "0.0", None, None, None]),
        Floats(info, ["%.17g", "%f"] * 3, [None, "0.0", "0.0", None, "0.0", None], repeated_rows=True),
        TextColumn(np.array([[ord("a"), 0]] * n, dtype=np.uint8), np.ones(n, dtype=np.int64)),
    ]


@pytest.mark.parametrize("n", [1, 2, 3, 64, 257, 1000, 3001])
def test_format_lines_small_and_large_paths_write_the_same_bytes(n, monkeypatch):
    from studio.io import textfmt

    fields = _line_fields(np.random.default_rng(n), n)
    small = textfmt.format_lines(fields).tobytes()
    monkeypatch.setattr(textfmt, "SMALL_LINES", 0)
    columns = textfmt.format_lines(fields).tobytes()
    assert small == columns
    assert small.count(b"\n") == n
    first = small.split(b"\n")[0].split(b" ")
    assert first[0] == b"EDGE_SE3:QUAT" and first[2] == b"7" and first[5] == b"0.0"
