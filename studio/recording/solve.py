"""An optimizer run as Rerun data: the estimate at every iteration on the ``iteration`` timeline,
beside the ground truth, the cost per iteration, and per-node error colouring.

Recorded with the dataset recording's application id and, for a multi-g2o dataset, its recording id,
so that opening both files shows the run on top of the dataset; for a single g2o file the id is
derived from the run's columns. Blueprint parts have ids derived from their role and no clock value
is logged (``log_time`` is off), so the same run gives the same fingerprint.
"""

from __future__ import annotations

import hashlib
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.geometry import is_planar_se3, planar_poses_to_se3
from studio.core.model import PoseGraph, PoseKind
from studio.core.types import PathLike
from studio.recording.colours import AGENT_PALETTE_RGB, GROUND_TRUTH_GREY, SOLVE_ESTIMATE_ALPHA, error_colours
from studio.recording.entities import (
    APPLICATION_ID,
    SOLVE,
    SOLVE_CHI2,
    SOLVE_ERROR,
    SOLVE_ESTIMATE,
    SOLVE_GROUND_TRUTH,
    SOLVE_SCALE,
    TIMELINE_ITERATION,
)
from studio.recording.sink import closing, write_bounded

__all__ = ["log_solve", "write_solve_recording", "solve_blueprint", "solve_recording_id"]

_NAMESPACE = uuid.UUID("0b6f5d4e-3c1a-4f7e-9d2b-8a5c6e7f1d30")


def solve_recording_id(
    offsets: np.ndarray, kind: PoseKind, iterates: Sequence[tuple[int, np.ndarray]], chi2_history: Sequence[float]
) -> str:
    """A UUID derived from the run's columns (for a graph without a dataset recording to join)."""
    from studio.recording.dataset import hash_columns

    h = hashlib.sha256(f"cslam-studio solve {kind.value}".encode())
    hash_columns(
        h, np.asarray(offsets, dtype=np.int64), np.asarray(chi2_history, dtype=np.float64), *(p for _, p in iterates)
    )
    h.update(repr([k for k, _ in iterates]).encode())
    return str(uuid.uuid5(_NAMESPACE, h.hexdigest()))


def solve_blueprint(names: Sequence[str], positions_xyz: np.ndarray | None = None, planar: bool = False) -> Any:
    """The 3D view beside the cost and error plots; planar data (``planar``) is seen from straight
    above ``positions_xyz``'s centre, with no ground grid, as in dataset recordings."""
    import rerun.blueprint as rrb

    from studio.recording.dataset import eye_over, fixed_id

    def fixed(part: Any, label: str) -> Any:
        return fixed_id(part, _NAMESPACE, f"blueprint/{label}")

    view: dict[str, Any] = {}
    if planar and positions_xyz is not None and len(positions_xyz):
        lo, hi = positions_xyz.min(axis=0), positions_xyz.max(axis=0)
        view["eye_controls"] = eye_over(0.5 * (lo + hi), float(max(np.max(hi - lo), 1.0)), planar=True)
        view["line_grid"] = rrb.LineGrid3D(visible=False)
    return rrb.Blueprint(
        fixed(
            rrb.Horizontal(
                fixed(rrb.Spatial3DView(name="estimate vs ground truth", origin=SOLVE, **view), "space"),
                fixed(
                    rrb.Vertical(
                        fixed(rrb.TimeSeriesView(name="chi2 (g2o convention)", origin=SOLVE_CHI2), "chi2"),
                        fixed(rrb.TimeSeriesView(name="mean position error [m]", origin=SOLVE_ERROR), "error"),
                        fixed(rrb.TextDocumentView(name="colours", origin=SOLVE_SCALE), "scale"),
                        row_shares=[2, 2, 1],  # the colour key's text whole at 1200x760
                    ),
                    "plots",
                ),
                column_shares=[3, 1],
            ),
            "root",
        ),
        rrb.TimePanel(timeline=TIMELINE_ITERATION, play_state="following"),
        collapse_panels=True,
    )


def log_solve(
    rec: Any,
    graph: PoseGraph | None,
    offsets: np.ndarray,
    kind: PoseKind,
    iterates: Sequence[tuple[int, np.ndarray]],
    chi2_history: Sequence[float],
) -> None:
    """Log the iterates (global-id poses, ``kind`` rows) split per agent by ``offsets``."""
    import rerun as rr

    names = [a.name for a in graph.agents] if graph is not None else ["graph"]
    lifted = [(k, planar_poses_to_se3(p) if kind is PoseKind.SE2 else p) for k, p in iterates]
    truth = None
    if graph is not None and all(a.ground_truth is not None for a in graph.agents):
        g3 = graph.to_se3()
        truth = np.concatenate([a.ground_truth for a in g3.agents])
        for a in g3.agents:
            rec.log(
                SOLVE_GROUND_TRUTH.format(agent=rr.escape_entity_path_part(a.name)),
                rr.LineStrips3D([a.ground_truth[:, 0:3]], colors=[GROUND_TRUTH_GREY], radii=-1.0),  # type: ignore[index]
                static=True,
            )
    scale = 1.0
    if truth is not None and lifted:
        # scaled to the estimate the recording ends on: a 5 cm optimum is not drawn in the colour of
        # the initial guess's metres
        final = np.linalg.norm(lifted[-1][1][:, 0:3] - truth[:, 0:3], axis=1)
        scale = max(float(np.percentile(final, 95)), 1e-6)
        rec.log(
            SOLVE_SCALE,
            rr.TextDocument(
                f"Points: position error against the ground truth, viridis from dark blue (0 m) to green "
                f"({scale:.4g} m, the final estimate's 95th percentile; larger errors stay green). "
                f"Paths: each agent's colour; ground truth grey.",
                media_type="text/markdown",
            ),
            static=True,
        )
    rec.log(SOLVE_CHI2, rr.SeriesLines(names="chi2"), static=True)
    rec.log(SOLVE_ERROR, rr.SeriesLines(names="mean position error [m]"), static=True)
    for k, poses in lifted:
        rec.set_time(TIMELINE_ITERATION, sequence=k)
        err = None if truth is None else np.linalg.norm(poses[:, 0:3] - truth[:, 0:3], axis=1)
        for j, name in enumerate(names):
            lo, hi = int(offsets[j]), int(offsets[j + 1])
            pts = poses[lo:hi, 0:3]
            colours = None if err is None else error_colours(err[lo:hi], scale)
            path = SOLVE_ESTIMATE.format(agent=rr.escape_entity_path_part(name))
            line = (*AGENT_PALETTE_RGB[j % len(AGENT_PALETTE_RGB)], SOLVE_ESTIMATE_ALPHA)
            rec.log(
                path,
                rr.Points3D(pts, colors=colours, radii=-2.0),
                rr.LineStrips3D([pts], colors=[line], radii=-0.75),
            )
        if k < len(chi2_history):
            rec.log(SOLVE_CHI2, rr.Scalars(chi2_history[k]))
        if err is not None:
            rec.log(SOLVE_ERROR, rr.Scalars(float(err.mean())))


def write_solve_recording(
    path: PathLike,
    graph: PoseGraph | None,
    offsets: np.ndarray,
    kind: PoseKind,
    iterates: Sequence[tuple[int, np.ndarray]],
    chi2_history: Sequence[float],
    *,
    name: str,
    force: bool = False,
    inputs: Sequence[PathLike] = (),
) -> Path:
    """Write the run to a new ``.rrd`` (staged, renamed into place; refused when it overlaps one of
    ``inputs``, the dataset and the solve's other outputs)."""
    from studio.io.atomic import staged_outputs
    from studio.recording.dataset import recording_id_for

    path = Path(path)
    rid = recording_id_for(graph) if graph is not None else solve_recording_id(offsets, kind, iterates, chi2_history)
    names = [a.name for a in graph.agents] if graph is not None else ["graph"]

    def write(target: Path) -> None:
        import rerun as rr

        rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid, send_properties=False)
        rec.set_log_time_enabled(False)  # no wall clock in the data: the same run, the same content
        shown = planar_poses_to_se3(iterates[-1][1]) if iterates and kind is PoseKind.SE2 else None
        if iterates and shown is None:
            shown = iterates[-1][1]
        planar = kind is PoseKind.SE2 or (shown is not None and is_planar_se3(shown))
        xyz = None if shown is None else shown[:, 0:3]
        with closing(rec, target, shown=Path(path)):
            rec.save(target, default_blueprint=solve_blueprint(names, xyz, planar))
            rec.send_recording_name(name)
            log_solve(rec, graph, offsets, kind, iterates, chi2_history)

    with staged_outputs(path.parent, [path.name], force=force, inputs=inputs) as staging:
        write_bounded(write, staging / path.name, shown=path)
    return path
