"""The per-node errors of an :class:`~studio.evaluate.Evaluation` as a Rerun recording (rerun-sdk 0.41).

Kept apart from the dataset recording module so that either can change alone; the entity paths sit
under :data:`ENTITY_ROOT` and the timelines are :data:`TIMELINE_NODE` (vertex index within its agent)
and :data:`TIMELINE_STAMP` (the ground-truth timestamp), so the errors line up with the poses when
this recording is opened together with (or logged into) the dataset's own. Series are sent with
``send_columns``; the table of statistics is logged once, statically.
"""

from __future__ import annotations

import os
from pathlib import Path

from studio.evaluate import Evaluation, format_markdown

__all__ = ["ENTITY_ROOT", "TIMELINE_NODE", "TIMELINE_STAMP", "APPLICATION_ID", "log_evaluation",
           "save_evaluation_recording"]

APPLICATION_ID = "cslam-studio"
ENTITY_ROOT = "evaluation"
TIMELINE_NODE = "node"
TIMELINE_STAMP = "stamp"
_SERIES = (
    ("ape_translation_m", "ape_translation_series_m", "APE translation [m]"),
    ("ape_rotation_deg", "ape_rotation_series_deg", "APE rotation [deg]"),
)


def log_evaluation(rec, evaluation: Evaluation) -> None:
    """Log the statistics table (static) and each agent's per-node APE series into ``rec``."""
    import rerun as rr

    rec.log(f"{ENTITY_ROOT}/summary", rr.TextDocument(format_markdown(evaluation), media_type="text/markdown"),
            static=True)
    for k, agent in enumerate(evaluation.agents):
        part = rr.escape_entity_path_part(agent.name)
        indexes = [
            rr.TimeColumn(TIMELINE_NODE, sequence=evaluation.node_indices[k]),
            rr.TimeColumn(TIMELINE_STAMP, timestamp=evaluation.stamps_ns[k].astype("datetime64[ns]")),
        ]
        for leaf, attr, label in _SERIES:
            path = f"{ENTITY_ROOT}/{part}/{leaf}"
            rec.log(path, rr.SeriesLines(names=f"{agent.name}: {label}"), static=True)
            rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=getattr(evaluation, attr)[k]))


def save_evaluation_recording(evaluation: Evaluation, path: str | os.PathLike, *,
                              recording_id: str | None = None) -> Path:
    """Write a new ``.rrd`` holding only the evaluation. Pass the dataset recording's id as
    ``recording_id`` to have the viewer merge both files into one recording."""
    import rerun as rr

    path = Path(path)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    rec.save(path)
    log_evaluation(rec, evaluation)
    rec.flush()
    rec.disconnect()
    return path
