"""Fast, exact number formatting for the text formats.

kollagen writes every double with C's ``%.17g`` (``%f`` in ``inter_agent_lc.dat``). Python's ``%``
operator gives the same correctly rounded digits, but formatting is most of the cost of writing a
dataset, so:

* a column is formatted in one ``%`` operation over a repeated format string (no per-value call);
* a column with few distinct values (ground-truth grid positions, constant information entries) is
  formatted once per distinct bit pattern (``-0.0`` stays apart from ``0.0``);
* inside :func:`shared_formatting`, a column that was already formatted with the same format is
  reused, so the same poses written to several files are formatted once.

Columns that kollagen writes as a literal ``0.0`` (z, qx, qy and off-diagonal information entries of
planar data) pass ``zero="0.0"``: a positive zero is then written that way.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
from typing import IO, Iterator

import numpy as np

__all__ = ["write_lines", "format_column", "format_int_column", "format_rows", "format_columns", "shared_formatting"]

_CACHE: contextvars.ContextVar[dict | None] = contextvars.ContextVar("studio_format_cache", default=None)


@contextlib.contextmanager
def shared_formatting() -> Iterator[None]:
    """Reuse formatted columns within the block (memory: the strings of every column formatted)."""
    token = _CACHE.set({})
    try:
        yield
    finally:
        _CACHE.reset(token)


def format_column(values: np.ndarray, fmt: str = "%.17g", zero: str | None = None) -> list[str]:
    """Format every value with ``fmt``; ``zero`` (if given) replaces the text of a positive zero."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    cache = _CACHE.get()
    if cache is not None and len(values) > 256:
        key = (fmt, zero, values.tobytes())
        hit = cache.get(key)
        if hit is None:
            hit = cache[key] = _format_column(values, fmt, zero)
        return hit
    return _format_column(values, fmt, zero)


def _format_column(values: np.ndarray, fmt: str, zero: str | None) -> list[str]:
    n = len(values)
    if n == 0:
        return []
    bits = values.view(np.int64)
    if (bits == bits[0]).all():
        return _format(values[:1], fmt, zero) * n
    if n >= 64 and len(np.unique(bits[:256])) < 128:  # a column with many repeats
        uniq, inv = np.unique(bits, return_inverse=True)
        texts = np.array(_format(uniq.view(np.float64), fmt, zero), dtype=object)
        return texts[inv].tolist()
    return _format(values, fmt, zero)


def _format(values: np.ndarray, fmt: str, zero: str | None) -> list[str]:
    vals = values.tolist()
    out = ((fmt + "\n") * len(vals) % tuple(vals)).split("\n")
    out.pop()
    if zero is not None:
        pos_zero = np.flatnonzero((values == 0.0) & ~np.signbit(values))
        for k in pos_zero.tolist():
            out[k] = zero
    return out


def format_int_column(values: np.ndarray) -> list[str]:
    return list(map(str, np.asarray(values, dtype=np.int64).tolist()))


def format_columns(values: np.ndarray, fmts: list[str], zeros: list[str | None]) -> list[str]:
    """Each column formatted on its own, the columns of a row joined by single spaces."""
    values = np.asarray(values, dtype=np.float64)
    cols = [format_column(values[:, c], fmts[c], zeros[c]) for c in range(values.shape[1])]
    return list(map(" ".join, zip(*cols)))


def format_rows(rows: np.ndarray, fmts: list[str], zeros: list[str | None]) -> list[str]:
    """Like :func:`format_columns`, for rows that repeat (information matrices): each distinct row
    is formatted once."""
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    n = len(rows)
    if n == 0:
        return []
    bits = rows.view(np.uint64).reshape(n, -1)
    if (bits == bits[0]).all():
        return format_columns(rows[:1], fmts, zeros) * n
    # group equal rows through a 64-bit hash of their bits, then check the grouping exactly
    weights = (np.arange(1, bits.shape[1] + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)) | np.uint64(1)
    with np.errstate(over="ignore"):
        h = (bits * weights).sum(axis=1, dtype=np.uint64)
        h ^= h >> np.uint64(29)
    _, first, inv = np.unique(h, return_index=True, return_inverse=True)
    inv = inv.ravel()
    if len(first) * 2 > n or not np.array_equal(bits[first][inv], bits):
        return format_columns(rows, fmts, zeros)  # mostly distinct rows (or a hash collision)
    texts = np.array(format_columns(rows[first], fmts, zeros), dtype=object)
    return texts[inv].tolist()


def write_lines(target: str | os.PathLike | IO[str], lines: list[str]) -> None:
    """Write text lines (with their newlines) to an open text stream or to a new ASCII file."""
    text = "".join(lines)
    if hasattr(target, "write"):
        target.write(text)
    else:
        with open(target, "w", encoding="ascii", newline="\n") as f:
            f.write(text)
