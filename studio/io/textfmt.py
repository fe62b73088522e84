"""Fast, exact number formatting for the text formats, in numpy.

kollagen writes every double with C's ``%.17g`` (``%f`` in ``inter_agent_lc.dat``). Formatting is
most of the cost of writing a dataset, and Python's ``%`` operator costs about 500 ns a number, so
numbers are formatted here in bulk, as columns of bytes, with the same correctly rounded digits:

* A finite double is ``m * 2**k`` (``m`` a 53-bit integer). Its 17 significant digits are
  ``round(m * 5**p * 2**(k + p))`` with ``p = 16 - X`` (``X`` its decimal exponent): a 53 x 63-bit
  product held in two 64-bit words, shifted right with round-half-to-even, as C's ``printf`` rounds
  the exact binary value. ``X`` comes from ``log10`` and is corrected until the truncated digits
  have exactly 17 places. ``%f`` is the same with ``p = 6``.
* The digits are laid out as ``%g`` does (fixed or exponent notation, trailing zeros removed): the
  numbers are sorted by layout (exponent and sign) and each layout fills its contiguous block of rows
  with a few slice copies (exponent notation split further by the digits kept).
* Numbers outside the exact fast range (``|v| >= 1e17`` or ``< 1e-11`` for ``%.17g``; non-finite
  values) are formatted by Python's ``%``, which gives C's digits too.

A :class:`TextColumn` is left-aligned bytes with a length per row, padded with NUL bytes;
:func:`join_columns` lays out whole lines (fields separated by single spaces) and returns the file's
bytes in one piece (:func:`join_array`: as a numpy array, which a file takes without a copy). Text never
holds a NUL byte, so the characters of the lines are the non-NUL bytes of the laid-out fields: one
pass over them, instead of a mask made from every field's length. Columns
that kollagen writes as a literal ``0.0`` (z, qx, qy and off-diagonal information entries of planar
data) pass ``zero="0.0"``: a positive zero is then written that way.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from itertools import chain
from typing import IO

import numpy as np

from studio.core.repeats import distinct_if_repeated
from studio.core.types import PathLike
from studio.io.atomic import start_writeback

__all__ = [
    "TextColumn",
    "BLOCK_ROWS",
    "row_blocks",
    "literal",
    "int_column",
    "digit_matrix",
    "float_columns",
    "float_rows",
    "concat",
    "join_columns",
    "join_array",
    "Ints",
    "Floats",
    "Field",
    "SMALL_LINES",
    "format_lines",
    "write_text",
    "format_float",
]

BLOCK_ROWS = 16384
"""Lines the writers format at a time. A block's text and its intermediates take a few MB, so a
file of any length is written within the same memory, which stays in the caches and, over a run,
needs fewer fresh pages (each costs a page fault; on a VM whose host reclaims free memory, up to
~10 us). Blocks only bound the work: the bytes are the same for any size."""


def row_blocks(n: int, rows: int = BLOCK_ROWS) -> list[slice]:
    """``n`` rows as consecutive slices of at most ``rows`` (none for no rows)."""
    return [slice(lo, min(n, lo + rows)) for lo in range(0, n, rows)]


_WIDTH = 24  # the longest %.17g text: "-1.2345678901234567e-308"
_FIX_DECIMALS = 6  # %f
_P10 = np.array([10**j for j in range(19)], dtype=np.uint64)
_P5 = np.array([5**j for j in range(28)], dtype=np.uint64)  # 5**27 < 2**63
_MASK32 = np.uint64(0xFFFFFFFF)
_ONE = np.uint64(1)


@dataclass(frozen=True, eq=False)
class TextColumn:
    """One text field per row: ``chars`` ``(n, width)`` uint8, left-aligned and padded with NUL bytes
    (every byte past a row's length is 0: :func:`join_array` relies on it), ``lengths`` ``(n,)``.

    A column of one row stands for the same text on every row.
    """

    chars: np.ndarray
    lengths: np.ndarray

    def __len__(self) -> int:
        return len(self.lengths)

    def take(self, index: np.ndarray) -> TextColumn:
        """The texts of rows ``index`` (a column of one row stays one row: it repeats anyway)."""
        if len(self) == 1:
            return self
        return TextColumn(self.chars[index], self.lengths[index])

    def tolist(self) -> list[str]:
        """The texts as Python strings (for tests and small outputs)."""
        return [bytes(row[:n]).decode("ascii") for row, n in zip(self.chars, self.lengths.tolist())]


def literal(text: str) -> TextColumn:
    """The same text on every row."""
    raw = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
    return TextColumn(raw.reshape(1, -1).copy(), np.array([len(raw)], dtype=np.int64))


def _from_strings(texts: Sequence[str]) -> TextColumn:
    if not texts:
        return TextColumn(np.zeros((0, 1), dtype=np.uint8), np.zeros(0, dtype=np.int64))
    arr = np.array([t.encode("ascii") for t in texts])  # dtype S<longest>, padded with NUL
    width = max(arr.dtype.itemsize, 1)
    chars = arr.view(np.uint8).reshape(len(texts), width)
    return TextColumn(chars, np.fromiter(map(len, texts), dtype=np.int64, count=len(texts)))


def digit_matrix(values: np.ndarray, places: int) -> np.ndarray:
    """``(n, places)`` ASCII digits of non-negative integers below ``10**places``, most significant first."""
    return np.ascontiguousarray(_digit_rows(values, places).T)


def _digit_rows(values: np.ndarray, places: int) -> np.ndarray:
    """``(places, n)``: row ``j`` holds digit ``j`` (ASCII, most significant first) of each value.

    Values below ``10**18`` are cut into two halves below ``10**9`` whose digits come from 32-bit
    divisions (numpy vectorises those; 64-bit ones it does one by one): 2.5x faster for 17 digits.
    """
    out = np.empty((places, len(values)), dtype=np.uint8)
    if places <= 9:
        parts = [(values.astype(np.uint32), 0, places)]
    elif places <= 18:
        hi, lo = np.divmod(values.astype(np.uint64), np.uint64(10**9))
        parts = [(hi.astype(np.uint32), 0, places - 9), (lo.astype(np.uint32), places - 9, places)]
    else:
        parts = [(values.astype(np.uint64, copy=True), 0, places)]
    for v, first, stop in parts:
        ten = v.dtype.type(10)
        for j in range(stop - 1, first - 1, -1):
            q = v // ten
            out[j] = v - q * ten
            v = q
    out += 48
    return out


_WORD_DIGITS = 8
"""Non-negative integers of up to this many digits are laid out in one 64-bit word each."""


def _small_int_column(values: np.ndarray) -> TextColumn:
    """:func:`int_column` of integers ``0 <= v < 10**8``: each row's digits right-aligned in the
    eight bytes of one little-endian word, which a right shift by the unused bytes left-aligns (the
    shift drops the leading zero digits and fills the end with NUL): ids and whole-second stamps,
    3x faster than picking each row's digits into place."""
    ndig = np.searchsorted(_P10[1:_WORD_DIGITS], values, side="right") + 1  # 0..9 -> 1, 10..99 -> 2, ...
    words = np.empty((len(values), _WORD_DIGITS), dtype=np.uint8)
    words[:] = _digit_rows(values, _WORD_DIGITS).T
    flat = words.view("<u8").ravel()
    flat >>= (8 * (_WORD_DIGITS - ndig)).astype(np.uint64)
    return TextColumn(words, ndig.astype(np.int64))


def int_column(values: np.ndarray) -> TextColumn:
    """Integers as ``str(int)`` does."""
    values = np.asarray(values, dtype=np.int64).ravel()
    n = len(values)
    if n == 0:
        return TextColumn(np.zeros((0, 1), dtype=np.uint8), np.zeros(0, dtype=np.int64))
    if values.min() >= 0 and values.max() < 10**_WORD_DIGITS:
        return _small_int_column(values)
    neg = values < 0
    mag = np.abs(values).astype(np.uint64)
    if values.min() == np.iinfo(np.int64).min:  # no positive counterpart: let Python do it
        return _from_strings([str(v) for v in values.tolist()])
    places = max(1, len(str(int(mag.max()))))
    digits = digit_matrix(mag, places)
    ndig = np.searchsorted(_P10[1:places], mag, side="right") + 1  # 0..9 -> 1, 10..99 -> 2, ...
    width = places + 1
    pos = np.arange(width, dtype=np.int64)[None, :]
    sign = neg.astype(np.int64)[:, None]
    # text position j holds digit column j - sign + (places - ndig)
    src = pos - sign + (places - ndig)[:, None]
    chars = np.take_along_axis(digits, np.clip(src, 0, places - 1), axis=1)
    chars[neg, 0] = ord("-")
    lengths = ndig + neg
    chars[pos >= lengths[:, None]] = 0  # NUL padding
    return TextColumn(chars, lengths)


def _mul_128(m: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``m * f`` as (high, low) 64-bit words, for ``m < 2**53`` and ``f < 2**63``."""
    m0, m1 = m & _MASK32, m >> np.uint64(32)
    f0, f1 = f & _MASK32, f >> np.uint64(32)
    p00 = m0 * f0
    mid = m0 * f1 + m1 * f0  # < 2**63 + 2**53: no overflow
    lo = p00 + (mid << np.uint64(32))
    carry = (lo < p00).astype(np.uint64)
    hi = m1 * f1 + (mid >> np.uint64(32)) + carry
    return hi, lo


def _scaled_digits(m: np.ndarray, k: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``floor`` and round-half-to-even of ``m * 2**k * 10**p`` for ``0 <= p <= 27``, where the
    result is below ``2**63`` and the shift ``t = -(k + p)`` lies in ``-10 .. 63``."""
    hi, lo = _mul_128(m, _P5[p])
    t = -(k + p)
    if len(t) and 1 <= t.min() and t.max() <= 63:  # the usual case: a plain right shift everywhere
        tt = t.astype(np.uint64)
        q = (hi << (np.uint64(64) - tt)) | (lo >> tt)
        rem = lo & ((_ONE << tt) - _ONE)
        half = _ONE << (tt - _ONE)
        up = (rem > half) | ((rem == half) & ((q & _ONE) == _ONE))
        return q, q + up
    left = t <= 0
    tt = np.where(left, 1, t).astype(np.uint64)  # shift for the right-shift branch
    q = np.where(tt == 64, hi, (hi << (np.uint64(64) - tt)) | (lo >> tt))
    rem = np.where(tt == 64, lo, lo & ((_ONE << tt) - _ONE))
    half = _ONE << (tt - _ONE)
    up = (rem > half) | ((rem == half) & ((q & _ONE) == _ONE))
    rounded = q + up.astype(np.uint64)
    shifted = lo << np.where(left, -t, 0).astype(np.uint64)
    return np.where(left, shifted, q), np.where(left, shifted, rounded)


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a = m * 2**k`` with ``m`` an integer below ``2**53`` (positive finite ``a``)."""
    frac, ex = np.frexp(a)
    m = np.ldexp(frac, 53).astype(np.uint64)
    return m, ex.astype(np.int64) - 53


def _g17_digits(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For positive finite ``a``: 17 significant digits ``D`` (an integer in ``[1e16, 1e17)``), the
    decimal exponent ``X`` of ``%e``, and where the fast path applies (elsewhere D and X are unset)."""
    m, k = _split(a)
    with np.errstate(divide="ignore"):
        x = np.floor(np.log10(a)).astype(np.int64)
    ok = (x >= -11) & (x <= 16)
    digits = np.zeros(len(a), dtype=np.uint64)
    # the rows still to do; None for all of them (the first pass, usually the only one with many
    # rows, then needs no gathers and no scatters)
    todo: np.ndarray | None = None if ok.all() else np.flatnonzero(ok)
    for _ in range(4):  # log10 is off by at most one; each pass fixes the exponent of the rest
        if todo is None:
            xs, ks, ms = x, k, m
        elif len(todo):
            xs, ks, ms = x[todo], k[todo], m[todo]
        else:
            break
        p = 16 - xs
        t = -(ks + p)
        inside = (p >= 0) & (p <= 27) & (t >= -10) & (t <= 64)
        if not inside.all():
            if todo is None:
                todo = np.arange(len(a))
            ok[todo[~inside]] = False
            todo, p, ks, ms = todo[inside], p[inside], ks[inside], ms[inside]
        floor_, rounded = _scaled_digits(ms, ks, p)
        low = floor_ < _P10[16]
        high = floor_ >= _P10[17]
        good = ~(low | high)
        carry = good & (rounded == _P10[17])  # 9.99..95 rounds up to the next power of ten
        value = np.where(carry, _P10[16], rounded)
        shift = carry.astype(np.int64) - low + high  # the exponent's correction
        if todo is None:
            digits = np.where(good, value, digits)
            x = x + shift
            todo = np.flatnonzero(~good)
        else:
            digits[todo[good]] = value[good]
            x[todo] += shift
            todo = todo[~good]
    if todo is not None:
        ok[todo] = False
    return digits, x, ok


def _g17_text(digits: np.ndarray, x: np.ndarray, neg: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``%.17g`` text of the numbers where ``ok``, from their 17 digits, decimal exponent and sign;
    other rows are left empty (NUL).

    The rows are sorted by layout (exponent and sign), so that each layout fills one contiguous
    block of rows with a few slice copies (digits before and after the point); exponent notation,
    which keeps only the significant digits, is split further by their number. The rows go back to
    their order in one scatter.
    """
    n = len(digits)
    fixed = (x >= -4) & (x < 17)
    key = np.where(ok, (x + 20) * 2 + neg, -1).astype(np.int16)
    order = np.argsort(key, kind="stable")
    skey = key[order]
    rows_ = _digit_rows(digits[order], 17)
    # significant digits kept: one past the last digit that is not 0
    place = np.arange(1, 17, dtype=np.uint8)[:, None]
    nd = 1 + ((rows_[1:] != ord("0")) * place).max(axis=0).astype(np.int64)
    cols = np.ascontiguousarray(rows_.T)
    xs, fx = x[order], fixed[order]
    lengths_s = np.where(
        xs >= 0,
        xs + 1 + np.where(nd > xs + 1, nd - xs, 0),  # ddd[.ddd]
        np.where(
            fx,
            1 - xs + nd,  # 0.000ddd
            nd + (nd > 1) + 4,
        ),
    )  # d[.ddd]e-XX
    lengths_s = np.where(skey >= 0, lengths_s + (skey & 1), 0)
    chars_s = np.zeros((n, _WIDTH + 1), dtype=np.uint8)
    bounds = np.flatnonzero(np.diff(skey)) + 1
    for lo, hi in zip([0, *bounds.tolist()], [*bounds.tolist(), n]):
        k = int(skey[lo])
        if k < 0:
            continue
        ex, o = k // 2 - 20, k % 2  # decimal exponent; 1 for a minus sign
        block = chars_s[lo:hi]
        if o:
            block[:, 0] = ord("-")
        if 0 <= ex < 17:  # ddd.ddd: all 17 digits (the length cuts trailing zeros)
            block[:, o : o + ex + 1] = cols[lo:hi, : ex + 1]
            if ex < 16:
                block[:, o + ex + 1] = ord(".")
                block[:, o + ex + 2 : o + 18] = cols[lo:hi, ex + 1 :]
        elif -4 <= ex < 0:  # 0.000ddd
            block[:, o : o + 1 - ex] = ord("0")
            block[:, o + 1] = ord(".")
            block[:, o + 1 - ex : o + 18 - ex] = cols[lo:hi]
        else:  # d[.ddd]e-XX with the nd digits kept
            exponent = np.frombuffer(f"e{'-' if ex < 0 else '+'}{abs(ex):02d}".encode("ascii"), dtype=np.uint8)
            nd_block = nd[lo:hi]
            for d in np.flatnonzero(np.bincount(nd_block)).tolist():  # the digit counts present, in order
                sel = np.flatnonzero(nd_block == d)
                text = np.empty((len(sel), d + (d > 1) + 4), dtype=np.uint8)
                text[:, 0] = cols[lo + sel, 0]
                if d > 1:
                    text[:, 1] = ord(".")
                    text[:, 2 : d + 1] = cols[lo + sel, 1:d]
                text[:, -4:] = exponent
                block[sel, o : o + text.shape[1]] = text
    # fixed notation laid out all 17 digits: where trailing zeros were dropped, NUL the rest
    cut = np.flatnonzero(fx & (nd < 17) & (skey >= 0))
    if len(cut):
        tail = chars_s[cut]
        tail[np.arange(_WIDTH + 1)[None, :] >= lengths_s[cut][:, None]] = 0
        chars_s[cut] = tail
    chars = np.empty((n, _WIDTH + 1), dtype=np.uint8)
    row = f"V{_WIDTH + 1}"
    chars.view(row).ravel()[order] = chars_s.view(row).ravel()
    lengths = np.empty(n, dtype=np.int64)
    lengths[order] = lengths_s
    return chars, lengths


def _f6_text(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``%f`` text of non-negative numbers (without sign), and where the fast path applies."""
    n = len(a)
    ok = (a < 2.0**42) & ((a >= 2.0**-16) | (a < 2.0**-30))
    tiny = a < 2.0**-30  # a * 1e6 < 0.001: rounds to zero
    value = np.zeros(n, dtype=np.uint64)
    fast = np.flatnonzero(ok & ~tiny)
    if len(fast):
        m, k = _split(a[fast])
        _, rounded = _scaled_digits(m, k, np.full(len(fast), _FIX_DECIMALS, dtype=np.int64))
        value[fast] = rounded
    places = max(len(str(int(value.max()))) if n else 1, _FIX_DECIMALS + 1)
    digits = digit_matrix(value, places)
    int_places = places - _FIX_DECIMALS
    ndig_int = np.maximum(np.searchsorted(_P10[_FIX_DECIMALS + 1 : places], value, side="right") + 1, 1)
    lengths = ndig_int + 1 + _FIX_DECIMALS
    j = np.arange(places + 1, dtype=np.int64)[None, :]
    skip = (int_places - ndig_int)[:, None]  # leading zero columns of the integer part
    dot = ndig_int[:, None]
    idx = np.where(j < dot, j + skip, np.where(j == dot, places, j - 1 + skip))
    src = np.concatenate([digits, np.full((n, 1), ord("."), dtype=np.uint8)], axis=1)
    body = np.take_along_axis(src, np.clip(idx, 0, places), axis=1)
    body[j >= lengths[:, None]] = 0  # NUL padding
    return body, lengths, ok


def format_float(value: float, fmt: str = "%.17g") -> str:
    """One number, as :func:`float_columns` writes it (``fmt`` ``%.17g`` or ``%f``)."""
    return float_columns(np.array([[value]]), [fmt])[0].tolist()[0]


def float_columns(
    values: np.ndarray, fmts: Sequence[str], zeros: Sequence[str | None] | None = None
) -> list[TextColumn]:
    """Each column of ``values`` (``(n, k)``) as text: ``fmts[c]`` is ``"%.17g"`` or ``"%f"``;
    ``zeros[c]``, if given, replaces the text of a positive zero.

    A constant column gives a column of one row (it repeats on every line); a column with many
    repeated values (ground-truth grid positions) is formatted once per distinct value.
    """
    values = np.asarray(values, dtype=np.float64)
    n, k = values.shape
    zeros = list(zeros) if zeros is not None else [None] * k
    # per column, the values to format and how to spread their texts over the rows (None: 1 to 1)
    plan: list[tuple[np.ndarray, np.ndarray | None]] = []
    for c in range(k):
        col = np.ascontiguousarray(values[:, c])
        bits = col.view(np.int64)
        if n > 1 and (bits == bits[0]).all():
            plan.append((col[:1], None))
        else:
            plan.append(distinct_if_repeated(col))
    out: list[TextColumn | None] = [None] * k
    for fmt in sorted(set(fmts)):
        cols = [c for c in range(k) if fmts[c] == fmt]
        chars, lengths = _format_block(np.concatenate([plan[c][0] for c in cols]), fmt)
        start = 0
        for c in cols:
            vals, spread = plan[c]
            stop = start + len(vals)
            col_text = _with_zero(TextColumn(chars[start:stop], lengths[start:stop]), vals, zeros[c])
            out[c] = col_text if spread is None else col_text.take(spread)
            start = stop
    return [c for c in out if c is not None]


def _with_zero(col: TextColumn, values: np.ndarray, zero: str | None) -> TextColumn:
    if zero is None:
        return col
    where = (values == 0.0) & ~np.signbit(values)
    if not where.any():
        return col
    raw = np.frombuffer(zero.encode("ascii"), dtype=np.uint8)
    width = max(col.chars.shape[1], len(raw))
    chars = np.zeros((len(col), width), dtype=np.uint8)
    chars[:, : col.chars.shape[1]] = col.chars
    chars[where] = 0
    chars[where, : len(raw)] = raw
    lengths = np.where(where, len(raw), col.lengths)
    return TextColumn(chars, lengths)


_PYTHON_FORMAT_MAX = {"%.17g": 256, "%f": 4096}
"""Up to this many values, :func:`_format_block` formats each with Python's ``%`` (which gives the
same text as the numpy path, and as C): the numpy path's fixed cost of about 0.3 ms per block is
more than Python's 0.5-0.7 us per value below these sizes (measured at load 14: 100 values, 80 us
against 300 us for ``%.17g``; ``%f`` is no slower in Python up to 10,000 values)."""


def _format_block(v: np.ndarray, fmt: str) -> tuple[np.ndarray, np.ndarray]:
    """Text of every value of a flat array: ``(chars (n, w), lengths (n,))``."""
    if fmt not in ("%.17g", "%f"):
        raise ValueError(f"unsupported number format {fmt!r}")
    n = len(v)
    if n == 0:
        return np.zeros((0, 1), dtype=np.uint8), np.zeros(0, dtype=np.int64)
    if n <= _PYTHON_FORMAT_MAX[fmt]:  # few values: Python's % (C's digits) beats the numpy passes
        few = _from_strings([fmt % val for val in v.tolist()])
        return few.chars, few.lengths
    neg = np.signbit(v)
    a = np.abs(v)
    finite = np.isfinite(a)
    if fmt == "%.17g":
        nonzero = finite & (a != 0.0)
        digits, x, ok = _g17_digits(np.where(nonzero, a, 1.0))
        ok &= nonzero
        chars, lengths = _g17_text(digits, x, neg, ok)
        is_zero = a == 0.0  # "0" and "-0"
        chars[is_zero & ~neg, 0] = ord("0")
        chars[is_zero & neg, :2] = np.frombuffer(b"-0", dtype=np.uint8)
        lengths = np.where(is_zero, 1 + neg, lengths)
        ok |= is_zero
    else:  # zeros come out of _f6_text as "0.000000"
        body, lengths, ok = _f6_text(np.where(finite, a, 0.0))
        ok &= finite
        chars = np.zeros((n, body.shape[1] + 1), dtype=np.uint8)
        chars[~neg, :-1] = body[~neg]
        chars[neg, 1:] = body[neg]
        chars[neg, 0] = ord("-")
        lengths = lengths + neg
    width = chars.shape[1]
    slow = np.flatnonzero(~ok)
    if len(slow):  # outside the exact fast range (and non-finite): Python's % gives C's digits
        texts = [fmt % val for val in v[slow].tolist()]
        extra = _from_strings(texts)
        if extra.chars.shape[1] > width:
            grown = np.zeros((n, extra.chars.shape[1]), dtype=np.uint8)
            grown[:, :width] = chars
            chars, width = grown, extra.chars.shape[1]
        chars[slow] = 0
        chars[slow, : extra.chars.shape[1]] = extra.chars
        lengths[slow] = extra.lengths
    return chars, lengths


def float_rows(rows: np.ndarray, fmts: Sequence[str], zeros: Sequence[str | None] | None = None) -> list[TextColumn]:
    """Like :func:`float_columns`, for rows that repeat (information matrices): each distinct row is
    formatted once, as one field (rows all equal give one field of one row, repeated on every line);
    mostly distinct rows give one column per value."""
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    n = len(rows)
    if n == 0:
        return float_columns(rows, fmts, zeros)
    bits = rows.view(np.uint64).reshape(n, -1)
    if (bits == bits[0]).all():
        return [_joined(float_columns(rows[:1], fmts, zeros))]
    # group equal rows through a 64-bit hash of their bits, then check the grouping exactly
    weights = (np.arange(1, bits.shape[1] + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)) | np.uint64(1)
    with np.errstate(over="ignore"):
        h = (bits * weights).sum(axis=1, dtype=np.uint64)
        h ^= h >> np.uint64(29)
    _, first, inv = np.unique(h, return_index=True, return_inverse=True)
    inv = inv.ravel()
    if len(first) * 2 > n or not np.array_equal(bits[first][inv], bits):
        return float_columns(rows, fmts, zeros)  # mostly distinct rows (or a hash collision)
    return [_joined(float_columns(rows[first], fmts, zeros)).take(inv)]


def _joined(columns: Sequence[TextColumn]) -> TextColumn:
    """The columns' texts of each row as one field, separated by single spaces (for a few rows)."""
    lines = join_columns(columns, end="\n").decode("ascii").split("\n")[:-1]
    return _from_strings(lines)


def _layout(columns: Sequence[TextColumn], n: int, sep: bytes, end: bytes) -> np.ndarray:
    """Every field in its slot (as wide as its longest text, NUL-padded), a separator after each but
    the last, ``end`` at the end: ``(n, total)`` bytes whose non-NUL bytes are the lines."""
    widths = [int(c.lengths.max()) if len(c) else 0 for c in columns]
    total = sum(widths) + len(sep) * (len(columns) - 1) + len(end)
    chars = np.empty((n, total), dtype=np.uint8)
    sep_raw = np.frombuffer(sep, dtype=np.uint8)
    pos = 0
    for i, (col, w) in enumerate(zip(columns, widths)):
        chars[:, pos : pos + w] = col.chars[:, :w]
        pos += w
        if i < len(columns) - 1 and len(sep):
            chars[:, pos : pos + len(sep)] = sep_raw
            pos += len(sep)
    if end:
        chars[:, pos:] = np.frombuffer(end, dtype=np.uint8)
    return chars


def concat(columns: Sequence[TextColumn]) -> TextColumn:
    """One field per row: the columns' texts one after the other, without separators."""
    n = max(len(c) for c in columns)
    width = sum(c.chars.shape[1] for c in columns)
    chars = np.zeros((n, width), dtype=np.uint8)
    offset = np.zeros(n, dtype=np.int64)
    rows = np.arange(n)
    for col in columns:
        for j in range(col.chars.shape[1]):  # padding written here is overwritten by the next column
            chars[rows, offset + j] = col.chars[:, j]
        offset = offset + col.lengths
    return TextColumn(chars, offset)


def join_array(columns: Sequence[TextColumn], *, sep: str = " ", end: str = "\n") -> np.ndarray:
    """The text of whole lines as a flat uint8 array: per row, the columns' texts separated by
    ``sep``, then ``end``. Columns of one row repeat on every row."""
    n = max(len(c) for c in columns)
    if n == 0 or any(len(c) == 0 for c in columns):
        return np.zeros(0, dtype=np.uint8)
    chars = _layout(columns, n, sep.encode("ascii"), end.encode("ascii"))
    text: np.ndarray = chars[chars != 0]
    return text


def join_columns(columns: Sequence[TextColumn], *, sep: str = " ", end: str = "\n") -> bytes:
    """:func:`join_array` as bytes."""
    return join_array(columns, sep=sep, end=end).tobytes()


# --------------------------------------------------------------------------------------------------
# Whole lines from fields: numpy columns for many lines, one Python ``%`` for few


@dataclass(frozen=True, eq=False)
class Ints:
    """A field of integers, one per row, as ``str(int)`` writes them."""

    values: np.ndarray


@dataclass(frozen=True, eq=False)
class Floats:
    """Fields of numbers: the columns of ``values`` ``(n, k)`` in ``fmts`` (``%.17g`` or ``%f``), with
    ``zeros`` as :func:`float_columns` takes them. ``repeated_rows``: the rows repeat (information
    matrices), as :func:`float_rows` writes them."""

    values: np.ndarray
    fmts: Sequence[str]
    zeros: Sequence[str | None] | None = None
    repeated_rows: bool = False


Field = str | Ints | Floats | TextColumn
"""One or more fields of every line: a ``str`` is the same text on every row."""

SMALL_LINES = 2048
"""Up to this many lines, :func:`format_lines` makes them with one Python ``%`` over a line template
(texts of constant columns and repeated rows written into it once): a small file's numpy passes,
a dozen per column with a fixed cost each, cost more than Python's 0.3-0.4 us a number (measured on
a 3-agent, 723-pose dataset: 19 ms of writing became 6 ms). Both give the same bytes. Longer blocks
are faster in numpy: the loop-closure blocks of 3,072-4,096 lines of an 8-agent set at R = 1 m took
101 ms with ``%`` and 54 ms in numpy (20 blocks, best of 3 each, 2026-12-02), blocks of up to 2,048
lines 10.2 ms with ``%`` and 16.2 ms in numpy (16 blocks; 4,096 was the bound before)."""


def _rows_of(field: Field) -> int:
    if isinstance(field, str):
        return 1
    return len(field.values) if isinstance(field, (Ints, Floats)) else len(field)


def format_lines(fields: Sequence[Field], *, sep: str = " ", end: str = "\n") -> np.ndarray:
    """The text of whole lines as a flat uint8 array, as :func:`join_array` gives it: per row, the
    fields' texts separated by ``sep``, then ``end`` (no lines when a field has no rows). Up to
    :data:`SMALL_LINES` lines the text is made with Python's ``%``, else from numpy columns."""
    n = max(_rows_of(f) for f in fields)
    if n == 0 or any(_rows_of(f) == 0 for f in fields):
        return np.zeros(0, dtype=np.uint8)
    if n > SMALL_LINES:
        columns: list[TextColumn] = []
        for f in fields:
            if isinstance(f, str):
                columns.append(literal(f))
            elif isinstance(f, TextColumn):
                columns.append(f)
            elif isinstance(f, Ints):
                columns.append(int_column(f.values))
            else:
                columns += (float_rows if f.repeated_rows else float_columns)(f.values, f.fmts, f.zeros)
        return join_array(columns, sep=sep, end=end)
    return np.frombuffer(_percent_lines(fields, n, sep.encode("ascii"), end.encode("ascii")), dtype=np.uint8)


_Slot = tuple[bytes, list[object] | None]
"""A field of the line template: its text (a constant's, or a ``%`` conversion) and, for a
conversion, the value of every row."""


def _percent_lines(fields: Sequence[Field], n: int, sep: bytes, end: bytes) -> bytes:
    slots: list[_Slot] = []
    for f in fields:
        if isinstance(f, str):
            slots.append((f.encode("ascii").replace(b"%", b"%%"), None))
        elif isinstance(f, TextColumn):
            texts = [t.encode("ascii") for t in f.tolist()]
            slots.append((texts[0].replace(b"%", b"%%"), None) if len(texts) == 1 else (b"%s", list(texts)))
        elif isinstance(f, Ints):
            v = np.asarray(f.values, dtype=np.int64).ravel()
            slots.append((str(int(v[0])).encode("ascii"), None) if (v == v[0]).all() else (b"%d", v.tolist()))
        else:
            slots += _percent_floats(f)
    template = sep.join(text for text, _ in slots) + end
    values = [v for _, v in slots if v is not None]
    if not values:
        return template * n
    flat = values[0] if len(values) == 1 else chain.from_iterable(zip(*values))
    return (template * n) % tuple(flat)


_FEW_ROWS = 8
"""Repeated rows of more distinct values than this are written column by column."""


def _percent_floats(f: Floats) -> list[_Slot]:
    values = np.ascontiguousarray(f.values, dtype=np.float64)
    k = values.shape[1]
    zeros = list(f.zeros) if f.zeros is not None else [None] * k
    if f.repeated_rows:
        bits = values.view(np.uint64).reshape(len(values), k)
        if (bits == bits[0]).all():
            return [(b" ".join(_percent_text(values[0, c], f.fmts[c], zeros[c]) for c in range(k)), None)]
        # the distinct rows (a few classes of edges), peeled off one at a time
        inv = np.empty(len(values), dtype=np.int64)
        first: list[int] = []
        todo = np.arange(len(values))
        while len(todo) and len(first) < _FEW_ROWS:
            same = (bits[todo] == bits[todo[0]]).all(axis=1)
            first.append(int(todo[0]))
            inv[todo[same]] = len(first) - 1
            todo = todo[~same]
        if not len(todo):  # few distinct rows: each one's text once
            texts = [b" ".join(_percent_text(values[r, c], f.fmts[c], zeros[c]) for c in range(k)) for r in first]
            return [(b"%s", list(map(texts.__getitem__, inv.tolist())))]
    return [_percent_column(values[:, c], f.fmts[c], zeros[c]) for c in range(k)]


def _percent_text(value: float, fmt: str, zero: str | None) -> bytes:
    if zero is not None and value == 0.0 and not np.signbit(value):
        return zero.encode("ascii")
    return (fmt % value).encode("ascii")


def _percent_column(col: np.ndarray, fmt: str, zero: str | None) -> _Slot:
    bits = col.view(np.int64)
    if (bits == bits[0]).all():
        return _percent_text(float(col[0]), fmt, zero).replace(b"%", b"%%"), None
    conversion = fmt.encode("ascii")
    if zero is not None:
        positive_zero = bits == 0
        if positive_zero.any():
            z = zero.encode("ascii")
            return b"%s", [z if pz else conversion % v for v, pz in zip(col.tolist(), positive_zero.tolist())]
    return conversion, col.tolist()


def write_text(target: PathLike | IO[str], data: bytes | np.ndarray | Iterable[bytes | np.ndarray]) -> None:
    """Write ASCII text (:func:`join_columns` or :func:`join_array` output, or pieces, one after the
    other, each made only when the previous one is written) to an open text stream or to a new file."""
    pieces: Iterable[bytes | np.ndarray] = (data,) if isinstance(data, (bytes, np.ndarray)) else data
    if hasattr(target, "write"):
        target.write("".join(bytes(p).decode("ascii") for p in pieces))
    else:
        with open(target, "wb") as f:
            for p in pieces:
                f.write(p if isinstance(p, bytes) else np.ascontiguousarray(p).data)
            start_writeback(f)
