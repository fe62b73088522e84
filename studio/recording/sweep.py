"""A sweep's summary as Rerun data: one point per cell on the ``cell`` timeline, one series per metric.

Cells are points, not a line: neighbouring cells differ in any parameter, so a line between them
would draw a trend that is not there (the PNGs of ``OUT/plots`` put the metrics against their
parameters' values)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from studio.core.types import PathLike
from studio.recording.entities import APPLICATION_ID, SWEEP_SERIES, SWEEP_TABLE, TIMELINE_CELL
from studio.recording.sink import closing, write_bounded

__all__ = ["log_sweep", "write_sweep_recording"]


def log_sweep(rec: Any, table: Any) -> None:
    """``table``: a pandas DataFrame, one row per cell; numeric columns become series."""
    import rerun as rr

    rec.log(SWEEP_TABLE, rr.TextDocument(table.to_string(index=False)), static=True)
    index = [rr.TimeColumn(TIMELINE_CELL, sequence=np.arange(len(table)))]
    for col in table.columns:
        if col.startswith("param:") or table[col].dtype.kind not in "fiu":
            continue
        values = table[col].to_numpy(dtype=np.float64)
        path = SWEEP_SERIES.format(metric=rr.escape_entity_path_part(col))
        rec.log(path, rr.SeriesPoints(names=col, markers="circle", marker_sizes=3.0), static=True)
        rec.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=values))


def write_sweep_recording(path: PathLike, name: str, table: Any) -> Path:
    import rerun as rr

    from studio.io.atomic import write_replacing

    def write(tmp: Path) -> None:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=f"sweep-{name}", send_properties=False)
        with closing(rec, tmp, shown=Path(path)):
            rec.save(tmp)
            rec.send_recording_name(f"sweep {name}")
            log_sweep(rec, table)

    return write_replacing(path, lambda tmp: write_bounded(write, tmp, shown=Path(path)))
