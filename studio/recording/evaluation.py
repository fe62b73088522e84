"""An evaluation as a Rerun recording (rerun-sdk 0.41): the picture a user wants, and the numbers.

The recording holds, under :data:`~studio.recording.entities.EVALUATION`:

* a 3D view (``evaluation/world``): each agent's ground truth as a solid grey line (grey shows on
  the dark and light themes and is not on the error scale) and its estimate (after any alignment) as segments coloured by APE translation on one scale for
  all agents (blue: no error, through green and amber, to red: the largest error);
* one plot per metric (``evaluation/<metric>/<agent>``) with every agent in its colour, on the
  dataset recording's timelines (``node``: vertex index within its agent; ``time``: the
  ground-truth timestamp), so the errors line up with the poses when this recording is opened
  together with the dataset's own;
* the table of statistics (static Markdown);

and a blueprint that lays these out (:func:`evaluation_blueprint`). Series are sent with
``send_columns``. This module takes columns, not the evaluation pipeline's result type, so it sits
below the pipelines.

The content depends only on the inputs: the recording id is derived from everything the recording
shows (:func:`evaluation_recording_id`: the statistics table, which names the dataset, the estimate,
the alignment and the RPE options, and every logged column), blueprint parts have ids derived from
their role, and no clock value is logged. Two runs on the same inputs give the same fingerprint
(:func:`studio.recording.rrd_checks.fingerprint_rrd`); the bytes differ only by Rerun's time-based
chunk and row ids (see docs/recordings.md).
"""

from __future__ import annotations

import hashlib
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.types import PathLike
from studio.recording.colours import GROUND_TRUTH_GREY, error_colours
from studio.recording.dataset import LEGEND_HEADROOM, agent_colour, eye_over, fixed_id, hash_columns, plot_legend
from studio.recording.entities import (
    APPLICATION_ID,
    EVALUATION_ESTIMATE,
    EVALUATION_GROUND_TRUTH,
    EVALUATION_SERIES,
    EVALUATION_SUMMARY,
    EVALUATION_WORLD,
    TIMELINE_NODE,
    TIMELINE_TIME,
)
from studio.recording.sink import closing, write_bounded

__all__ = [
    "ErrorSeries",
    "METRIC_LABELS",
    "error_colours",
    "evaluation_blueprint",
    "evaluation_recording_id",
    "log_evaluation",
    "save_evaluation_recording",
]

_BLUEPRINT_NAMESPACE = uuid.UUID("9f0c2f52-8d2e-4b0e-a7f3-3c1e6c1d4b90")


@dataclass(frozen=True, eq=False)
class ErrorSeries:
    """One agent's per-node errors: ``values`` keyed by metric name (``ape_translation_m``...), and
    optionally the positions (n, 3) of the scored ground-truth and estimate poses for the 3D view."""

    agent: str
    node_indices: np.ndarray
    stamps_ns: np.ndarray
    values: dict[str, np.ndarray]
    ground_truth_xyz: np.ndarray | None = None
    estimate_xyz: np.ndarray | None = None


#: Label shown in the viewer for each metric the evaluation logs.
METRIC_LABELS = {"ape_translation_m": "APE translation [m]", "ape_rotation_deg": "APE rotation [deg]"}


def evaluation_recording_id(summary_markdown: str, series: Sequence[ErrorSeries]) -> str:
    """A UUID derived from everything the recording shows: the statistics table (which names the
    dataset, the estimate, the alignment and the RPE options) and, per agent, its name and every
    column (nodes, stamps, each metric's values, the positions). The same inputs and options give
    the same id; it never equals a dataset recording's id (:func:`~studio.recording.dataset.recording_id_for`).
    """
    h = hashlib.sha256(b"cslam-studio evaluation\0")
    h.update(summary_markdown.encode() + b"\0")
    for s in series:
        h.update(s.agent.encode() + b"\0")
        hash_columns(h, s.node_indices, s.stamps_ns)
        for metric in sorted(s.values):
            h.update(metric.encode() + b"\0")
            hash_columns(h, s.values[metric])
        hash_columns(h, s.ground_truth_xyz, s.estimate_xyz)
    return str(uuid.uuid5(_BLUEPRINT_NAMESPACE, h.hexdigest()))


def _largest_error(series: Sequence[ErrorSeries]) -> float:
    values = [
        float(np.max(s.values["ape_translation_m"])) for s in series if len(s.values.get("ape_translation_m", ())) > 0
    ]
    return max(values + [0.0])


def log_evaluation(rec: Any, summary_markdown: str, series: Sequence[ErrorSeries]) -> None:
    """Log the statistics table (static), each agent's per-node error series and, when the series
    carry positions, the 3D ground truth and error-coloured estimate into ``rec``."""
    import rerun as rr

    largest = _largest_error(series)
    legend = (
        f"\n\nIn the 3D view each estimate is coloured by its APE translation: blue 0 m, green, "
        f"amber, red {largest:.3g} m (the largest). Ground truth: solid grey lines."
    )
    rec.log(EVALUATION_SUMMARY, rr.TextDocument(summary_markdown + legend, media_type="text/markdown"), static=True)
    for k, s in enumerate(series):
        part = rr.escape_entity_path_part(s.agent)
        colour = agent_colour(k)
        indexes = [
            rr.TimeColumn(TIMELINE_NODE, sequence=s.node_indices),
            rr.TimeColumn(TIMELINE_TIME, timestamp=s.stamps_ns.astype("datetime64[ns]")),
        ]
        for metric, values in s.values.items():
            path = EVALUATION_SERIES.format(agent=part, metric=metric)
            rec.log(path, rr.SeriesLines(names=s.agent, colors=[colour]), static=True)
            rec.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=values))
        if s.ground_truth_xyz is not None and len(s.ground_truth_xyz):
            rec.log(
                EVALUATION_GROUND_TRUTH.format(agent=part),
                rr.LineStrips3D([s.ground_truth_xyz], colors=[GROUND_TRUTH_GREY], radii=-2.0),
                static=True,
            )
        if s.estimate_xyz is not None and len(s.estimate_xyz) > 1:
            est = s.estimate_xyz
            err = s.values["ape_translation_m"]
            segments = np.stack([est[:-1], est[1:]], axis=1)
            rec.log(
                EVALUATION_ESTIMATE.format(agent=part),
                rr.LineStrips3D(segments, colors=error_colours(0.5 * (err[:-1] + err[1:]), largest), radii=-1.0),
                static=True,
            )


def _fixed(part: Any, label: str) -> Any:
    return fixed_id(part, _BLUEPRINT_NAMESPACE, f"evaluation/{label}")


def evaluation_blueprint(series: Sequence[ErrorSeries]) -> Any:
    """3D estimate-vs-ground-truth view on the left; one plot per metric (every agent) and the
    statistics table on the right; time panel on ``node``."""
    import rerun as rr
    import rerun.blueprint as rrb

    pts = [p for s in series for p in (s.ground_truth_xyz, s.estimate_xyz) if p is not None and len(p)]
    views = []
    if pts:
        allp = np.concatenate(pts)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        c = (lo + hi) / 2.0
        extent = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1.0))
        eye = eye_over(c, extent, planar=float(hi[2] - lo[2]) < 1e-9)  # planar: from straight above
        views.append(
            _fixed(
                rrb.Spatial3DView(
                    origin=f"/{EVALUATION_WORLD}",
                    name="estimate vs ground truth",
                    eye_controls=eye,
                    line_grid=rrb.LineGrid3D(visible=False),
                ),
                "world",
            )
        )
    whole = rr.TimeRange(start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.infinite())
    # translation first: the tab shown on opening
    metrics = sorted({m for s in series for m in s.values}, key=lambda m: (m != "ape_translation_m", m))

    def largest(metric: str) -> float:
        return max([float(np.max(s.values[metric])) for s in series if len(s.values.get(metric, ()))] + [1e-9])

    plots = [
        _fixed(
            rrb.TimeSeriesView(
                origin="/" + EVALUATION_SERIES.split("{metric}")[0] + m,
                name=METRIC_LABELS.get(m, m),
                axis_x=rrb.TimeAxis(view_range=whole),
                axis_y=rrb.ScalarAxis(range=(0.0, LEGEND_HEADROOM * largest(m))),
                plot_legend=plot_legend(),
            ),
            f"metric/{m}",
        )
        for m in metrics
    ]
    # the plots share one pane as tabs, so one of them is tall enough for eight agents' legend
    tabs = [_fixed(rrb.Tabs(*plots, active_tab=0), "plots")] if plots else []
    summary = _fixed(rrb.TextDocumentView(origin=f"/{EVALUATION_SUMMARY}", name="statistics"), "summary")
    # the statistics grow with the agents (a row each, and `all`): for eight agents the panel takes
    # about half the column, so every row shows without scrolling
    table_share = 1.0 + 0.15 * len(series)
    right = _fixed(rrb.Vertical(*tabs, summary, row_shares=[2.0] * len(tabs) + [table_share]), "right")
    root = _fixed(rrb.Horizontal(*views, right, column_shares=[1, 1] if views else None), "root")
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline=TIMELINE_NODE, play_state="following", expanded=False),
        rrb.BlueprintPanel(expanded=False),
        rrb.SelectionPanel(expanded=False),
        auto_views=False,
    )


def save_evaluation_recording(
    path: PathLike, summary_markdown: str, series: Sequence[ErrorSeries], *, recording_id: str | None = None
) -> Path:
    """Write a new ``.rrd`` holding only the evaluation, with its layout. The recording id is
    :func:`evaluation_recording_id` unless ``recording_id`` is given: pass the dataset recording's
    id to have the viewer merge both files into one recording."""
    import rerun as rr

    path = Path(path)
    rid = evaluation_recording_id(summary_markdown, series) if recording_id is None else recording_id

    def write(target: Path) -> None:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid, send_properties=False)
        with closing(rec, target, shown=path):
            rec.save(target, default_blueprint=evaluation_blueprint(series))
            log_evaluation(rec, summary_markdown, series)

    write_bounded(write, path, shown=path)  # a stuck writer (a full disk) is one OutputError, never a hang
    return path
