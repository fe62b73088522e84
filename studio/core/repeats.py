"""Columns with many repeated values (ground truth on a grid, constant information entries): work
done once per distinct value and spread back."""

from __future__ import annotations

import numpy as np

__all__ = ["distinct_if_repeated"]


def distinct_if_repeated(values: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """``(distinct, spread)`` with ``distinct[spread] == values`` bit for bit when the column has many
    repeats (judged on its first 256 values), else ``(values, None)``.

    Values are told apart by their bit pattern, so ``-0.0`` stays apart from ``0.0`` (and a function
    of them, such as ``sin`` or ``%g``, keeps its sign).
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    bits = values.view(np.int64)
    if len(values) < 64:
        return values, None
    head = np.sort(bits[:256])  # its distinct values counted (np.unique would import numpy.ma)
    if 1 + np.count_nonzero(head[1:] != head[:-1]) >= 128:
        return values, None
    uniq, spread = np.unique(bits, return_inverse=True)
    return uniq.view(np.float64), spread.ravel()
