"""Fast, exact number formatting for the text formats.

kollagen writes every double with C's ``%.17g`` (``%f`` in ``inter_agent_lc.dat``). Python's ``%``
operator gives the same correctly rounded digits, but formatting is most of the cost of writing a
dataset, so each column is formatted once per distinct bit pattern and the strings are reused.
Columns that kollagen writes as a literal ``0.0`` (z, qx, qy and off-diagonal information entries of
planar data) use :func:`format_column` with ``zero="0.0"``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["format_column", "format_int_column"]

_DEDUP_MIN = 64


def format_column(values: np.ndarray, fmt: str = "%.17g", zero: str | None = None) -> list[str]:
    """Format every value with ``fmt``; ``zero`` (if given) replaces the text of a positive zero."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    n = len(values)
    if n >= _DEDUP_MIN:
        bits = values.view(np.int64)
        uniq, inv = np.unique(bits, return_inverse=True)
        if len(uniq) * 2 < n:
            texts = _format(uniq.view(np.float64), fmt, zero)
            table = np.array(texts, dtype=object)
            return table[inv].tolist()
    return _format(values, fmt, zero)


def _format(values: np.ndarray, fmt: str, zero: str | None) -> list[str]:
    vals = values.tolist()
    if not vals:
        return []
    out = ((fmt + "\n") * len(vals) % tuple(vals)).split("\n")[:-1]
    if zero is not None:
        pos_zero = np.flatnonzero((values == 0.0) & ~np.signbit(values))
        for k in pos_zero.tolist():
            out[k] = zero
    return out


def format_int_column(values: np.ndarray) -> list[str]:
    return [str(v) for v in np.asarray(values, dtype=np.int64).tolist()]


def format_rows(rows: np.ndarray, fmts: list[str], zeros: list[str | None]) -> list[str]:
    """Format each row of ``rows`` as its columns joined by single spaces.

    Rows are formatted once per distinct row (information matrices repeat a lot), then reused.
    """
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    n = len(rows)
    if n == 0:
        return []
    bits = rows.view(np.int64).reshape(n, -1)
    uniq, inv = np.unique(bits, axis=0, return_inverse=True)
    uvals = uniq.view(np.float64).reshape(len(uniq), -1)
    cols = [_format(uvals[:, c].copy(), fmts[c], zeros[c]) for c in range(uvals.shape[1])]
    texts = np.array([" ".join(parts) for parts in zip(*cols)], dtype=object)
    return texts[inv.ravel()].tolist()
