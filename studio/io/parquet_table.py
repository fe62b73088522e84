"""CSV tables also written as Parquet (``studio replay --parquet``), when pyarrow is importable.

A Parquet file here is its CSV table read back by pyarrow's CSV reader: the same columns in the same
order, the same rows, types as pyarrow infers them from the text (an integer column stays int64, a
column with a non-number, such as ``tick`` in ``timings.csv`` with its ``total`` rows, a string; an
empty cell is a null). pyarrow writes no wall clock, so the same CSV gives the same Parquet bytes
with the same pyarrow version.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from studio.core.errors import ConfigError
from studio.core.types import PathLike

__all__ = ["require_pyarrow", "write_parquet_from_csv"]


def require_pyarrow() -> Any:
    """pyarrow's module, or a :class:`ConfigError` that says how to install it."""
    try:
        return importlib.import_module("pyarrow")
    except ImportError:
        raise ConfigError("parquet: needs pyarrow, which is not installed (pip install pyarrow)") from None


def write_parquet_from_csv(path: PathLike, csv_text: str) -> Path:
    """Write the CSV table ``csv_text`` (header line first) to the Parquet file ``path``."""
    pa = require_pyarrow()
    pa_csv = importlib.import_module("pyarrow.csv")
    pq = importlib.import_module("pyarrow.parquet")
    table = pa_csv.read_csv(pa.BufferReader(csv_text.encode("utf-8")))
    path = Path(path)
    pq.write_table(table, path)
    return path
