"""Per-node errors of an evaluation as Rerun data (rerun-sdk 0.41).

The series sit under :data:`~studio.recording.entities.EVALUATION` on the dataset recording's
timelines (``node``: vertex index within its agent; ``time``: the ground-truth timestamp), so the
errors line up with the poses when this recording is opened together with the dataset's own. Series
are sent with ``send_columns``; the table of statistics is logged once, statically. This module takes
columns, not the evaluation pipeline's result type, so it sits below the pipelines.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from studio.recording.entities import (
    APPLICATION_ID,
    EVALUATION_SERIES,
    EVALUATION_SUMMARY,
    TIMELINE_NODE,
    TIMELINE_TIME,
)

__all__ = ["ErrorSeries", "log_evaluation", "save_evaluation_recording"]


@dataclass(frozen=True, eq=False)
class ErrorSeries:
    """One agent's per-node errors: ``values`` keyed by metric name (``ape_translation_m``...)."""

    agent: str
    node_indices: np.ndarray
    stamps_ns: np.ndarray
    values: dict[str, np.ndarray]


#: Label shown in the viewer for each metric the evaluation logs.
METRIC_LABELS = {"ape_translation_m": "APE translation [m]", "ape_rotation_deg": "APE rotation [deg]"}


def log_evaluation(rec: Any, summary_markdown: str, series: Sequence[ErrorSeries]) -> None:
    """Log the statistics table (static) and each agent's per-node error series into ``rec``."""
    import rerun as rr

    rec.log(EVALUATION_SUMMARY, rr.TextDocument(summary_markdown, media_type="text/markdown"), static=True)
    for s in series:
        part = rr.escape_entity_path_part(s.agent)
        indexes = [
            rr.TimeColumn(TIMELINE_NODE, sequence=s.node_indices),
            rr.TimeColumn(TIMELINE_TIME, timestamp=s.stamps_ns.astype("datetime64[ns]")),
        ]
        for metric, values in s.values.items():
            path = EVALUATION_SERIES.format(agent=part, metric=metric)
            rec.log(path, rr.SeriesLines(names=f"{s.agent}: {METRIC_LABELS.get(metric, metric)}"), static=True)
            rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=values))


def save_evaluation_recording(path: str | os.PathLike, summary_markdown: str, series: Sequence[ErrorSeries],
                              *, recording_id: str | None = None) -> Path:
    """Write a new ``.rrd`` holding only the evaluation. Pass the dataset recording's id as
    ``recording_id`` to have the viewer merge both files into one recording."""
    import rerun as rr

    path = Path(path)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    rec.save(path)
    log_evaluation(rec, summary_markdown, series)
    rec.flush()
    rec.disconnect()
    return path
