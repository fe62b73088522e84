"""A replay as Rerun data, on the ``replay_time`` timeline (seconds since the replay's start).

At each checkpoint: every back-end's belief of each robot's own trajectory so far (a line strip,
in the frame the robot holds it, decimated to at most :data:`MAX_POINTS_PER_SNAPSHOT` points per
back-end and checkpoint so a paper-size replay stays small), the links between robots in contact
(segments between their ground-truth positions), the inter-agent closures delivered so far
(ground-truth ends, at most :data:`MAX_CLOSURE_SEGMENTS`), the team's APE per back-end and, for a
back-end whose robots keep each other's poses, jrl's Shared Variable Error (translation); per tick
the number of robots in contact and of closures delivered. Scrubbing the timeline shows the maps
snapping together when robots meet; the blueprint gives each back-end a 3D view of its own. No wall clock is logged and blueprint ids are fixed, so the
same replay gives the same fingerprint.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.model import PoseGraph
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.recording.colours import (
    AGENT_PALETTE_RGB,
    GROUND_TRUTH_GREY,
    INTER_FAINT_ALPHA,
    INTER_FAINT_RGB,
    REPLAY_LINK_COLOUR,
)
from studio.recording.entities import (
    APPLICATION_ID,
    REPLAY,
    REPLAY_APE,
    REPLAY_CLOSURES,
    REPLAY_DELIVERED,
    REPLAY_ESTIMATE,
    REPLAY_GROUND_TRUTH,
    REPLAY_IN_CONTACT,
    REPLAY_LINKS,
    REPLAY_SVE,
    REPLAY_WORLD,
    TIMELINE_REPLAY,
    TIMELINE_REPLAY_TICK,
)
from studio.recording.sink import closing, write_bounded

__all__ = ["log_replay", "write_replay_recording", "replay_blueprint", "MAX_POINTS_PER_SNAPSHOT"]

_NAMESPACE = uuid.UUID("5c3e2b1a-7d4f-4e8a-9b6c-1f2e3d4c5b6a")
#: Points of one back-end's beliefs (all robots) drawn per checkpoint, at most.
MAX_POINTS_PER_SNAPSHOT = 4000
#: Delivered inter-agent closures drawn per checkpoint, at most.
MAX_CLOSURE_SEGMENTS = 1500


def replay_blueprint(
    backends: Sequence[str], truth_xyz: np.ndarray | None = None, *, planar: bool = False, sve: bool = False
) -> Any:
    """One view per back-end beside the APE and communication plots (and, with ``sve``, the shared
    variable error's), the time panel following (a viewer opens at the end). With ``truth_xyz``
    (the ground-truth positions) every view looks at the whole team; planar data is seen from
    straight above with no ground grid."""
    import rerun.blueprint as rrb

    from studio.recording.dataset import eye_over, fixed_id

    def fixed(part: Any, label: str) -> Any:
        return fixed_id(part, _NAMESPACE, f"blueprint/{label}")

    view: dict[str, Any] = {}
    if truth_xyz is not None and len(truth_xyz):
        lo, hi = truth_xyz.min(axis=0), truth_xyz.max(axis=0)
        view["eye_controls"] = eye_over(0.5 * (lo + hi), float(max(np.max(hi - lo), 1.0)), planar=planar)
        if planar:
            view["line_grid"] = rrb.LineGrid3D(visible=False)

    return rrb.Blueprint(
        fixed(
            rrb.Horizontal(
                fixed(
                    rrb.Grid(
                        *(
                            fixed(
                                rrb.Spatial3DView(
                                    name=f"{b}: the team's beliefs",
                                    origin=REPLAY_WORLD,
                                    contents=[
                                        f"+ {REPLAY_WORLD}/ground_truth/**",
                                        f"+ {REPLAY_WORLD}/{_escape(b)}/**",
                                        f"+ {REPLAY_LINKS}",
                                        f"+ {REPLAY_CLOSURES}",
                                    ],
                                    **view,
                                ),
                                f"space/{b}",
                            )
                            for b in backends
                        )
                    ),
                    "space",
                ),
                fixed(
                    rrb.Vertical(
                        fixed(rrb.TimeSeriesView(name="team APE se3 [m]", origin=f"{REPLAY}/metrics/ape_se3_m"), "ape"),
                        *(
                            [
                                fixed(
                                    rrb.TimeSeriesView(
                                        name="shared variable error [m]", origin=f"{REPLAY}/metrics/sve_t_m"
                                    ),
                                    "sve",
                                )
                            ]
                            if sve
                            else []
                        ),
                        fixed(rrb.TimeSeriesView(name="robots in contact", origin=REPLAY_IN_CONTACT), "contact"),
                        fixed(rrb.TimeSeriesView(name="closures delivered", origin=REPLAY_DELIVERED), "delivered"),
                    ),
                    "plots",
                ),
                column_shares=[3, 1],
            ),
            "root",
        ),
        rrb.TimePanel(timeline=TIMELINE_REPLAY, play_state="following"),
        collapse_panels=True,
    )


def _escape(name: str) -> str:
    import rerun as rr

    return rr.escape_entity_path_part(name)


def _stride(total: int) -> int:
    return max(1, -(-total // MAX_POINTS_PER_SNAPSHOT))


def _log_static(rec: Any, names: list[str], truth: list[np.ndarray]) -> None:
    """Each robot's ground truth and the series' names, once."""
    import rerun as rr

    for k, name in enumerate(names):
        rec.log(
            REPLAY_GROUND_TRUTH.format(agent=name),
            rr.LineStrips3D([truth[k]], colors=[GROUND_TRUTH_GREY], radii=-0.5),
            static=True,
        )
    rec.log(REPLAY_IN_CONTACT, rr.SeriesLines(names="robots in contact"), static=True)
    rec.log(REPLAY_DELIVERED, rr.SeriesLines(names="closures delivered"), static=True)


def _log_per_tick(rec: Any, ticks_ns: np.ndarray, delivered_tick: np.ndarray, robots_in_contact: np.ndarray) -> None:
    """Robots in contact and closures delivered so far, at every tick (columns)."""
    import rerun as rr

    t0 = int(ticks_ns[0])
    times = rr.TimeColumn(TIMELINE_REPLAY, duration=(ticks_ns - t0) / NS_PER_S)
    tick_index = rr.TimeColumn(TIMELINE_REPLAY_TICK, sequence=np.arange(len(ticks_ns)))
    delivered = np.cumsum(np.bincount(delivered_tick[delivered_tick >= 0], minlength=len(ticks_ns)))
    rec.send_columns(
        REPLAY_IN_CONTACT, indexes=[times, tick_index], columns=rr.Scalars.columns(scalars=robots_in_contact)
    )
    rec.send_columns(REPLAY_DELIVERED, indexes=[times, tick_index], columns=rr.Scalars.columns(scalars=delivered))


def _log_links(rec: Any, here: list[np.ndarray], pairs: np.ndarray, up: np.ndarray) -> None:
    """Segments between the robots in contact at this tick (their ground-truth positions now)."""
    import rerun as rr

    segs = [np.stack([here[a], here[b]]) for (a, b), on in zip(pairs.tolist(), up.tolist()) if on]
    rec.log(REPLAY_LINKS, rr.LineStrips3D(segs, colors=[REPLAY_LINK_COLOUR], radii=-2.0))


def _log_closures(rec: Any, ends_a: np.ndarray, ends_b: np.ndarray) -> None:
    """The inter-agent closures delivered so far (ground-truth ends)."""
    import rerun as rr

    rec.log(
        REPLAY_CLOSURES,
        rr.LineStrips3D(np.stack([ends_a, ends_b], axis=1), colors=[(*INTER_FAINT_RGB, INTER_FAINT_ALPHA)]),
    )


def _log_beliefs(
    rec: Any,
    backend: str,
    poses: np.ndarray,
    *,
    names: list[str],
    offsets: np.ndarray,
    seen: list[int],
    stride: int,
    colours: list[tuple[int, int, int, int]],
) -> None:
    """One back-end's belief of each robot's trajectory so far (decimated by ``stride``)."""
    import rerun as rr

    for k, name in enumerate(names):
        lo = int(offsets[k])
        keep = np.unique(np.concatenate([np.arange(0, seen[k], stride), [max(seen[k] - 1, 0)]]))
        rec.log(
            REPLAY_ESTIMATE.format(backend=backend, agent=name),
            rr.LineStrips3D([poses[lo + keep, 0:3]], colors=[colours[k]], radii=-1.0),
        )


def log_replay(
    rec: Any,
    graph: PoseGraph,
    *,
    ticks_ns: np.ndarray,
    contact: np.ndarray,
    pairs: np.ndarray,
    closure_from: np.ndarray,
    closure_from_index: np.ndarray,
    closure_to: np.ndarray,
    closure_to_index: np.ndarray,
    delivered_tick: np.ndarray,
    robots_in_contact: np.ndarray,
    runs: Sequence[tuple[str, np.ndarray, np.ndarray, Sequence[np.ndarray]]],
    vertex_ns: np.ndarray,
    sve: Sequence[tuple[str, np.ndarray]] = (),
) -> None:
    """``runs``: per back-end, its name, checkpoint ticks, team APE per checkpoint and the beliefs
    (``(num_vertices, 7)`` SE(3) rows, global ids) at each checkpoint. ``sve``: per back-end whose
    robots keep each other's poses, its name and SVE translation [m] per checkpoint (NaN: none
    shared yet, nothing logged)."""
    import rerun as rr

    g3 = graph.to_se3()
    truth = [np.asarray(a.ground_truth)[:, 0:3] for a in g3.agents]
    names = [rr.escape_entity_path_part(a.name) for a in graph.agents]
    offsets = np.concatenate([[0], np.cumsum([a.num_poses for a in graph.agents])]).astype(np.int64)
    flat_truth = np.concatenate(truth)
    t0 = int(ticks_ns[0])
    _log_static(rec, names, truth)
    _log_per_tick(rec, ticks_ns, delivered_tick, robots_in_contact)
    stride = _stride(int(offsets[-1]))
    colours = [(*AGENT_PALETTE_RGB[k % len(AGENT_PALETTE_RGB)], 255) for k in range(len(names))]
    checkpoints = runs[0][1] if runs else np.zeros(0, dtype=np.int64)
    order = np.argsort(delivered_tick, kind="stable")
    for name_b, _, _, _ in runs:
        rec.log(
            REPLAY_APE.format(backend=rr.escape_entity_path_part(name_b)), rr.SeriesLines(names=name_b), static=True
        )
    for name_b, _ in sve:
        rec.log(
            REPLAY_SVE.format(backend=rr.escape_entity_path_part(name_b)), rr.SeriesLines(names=name_b), static=True
        )
    for c, tick in enumerate(checkpoints.tolist()):
        rec.set_time(TIMELINE_REPLAY, duration=(int(ticks_ns[tick]) - t0) / NS_PER_S)
        rec.set_time(TIMELINE_REPLAY_TICK, sequence=int(tick))
        now = int(ticks_ns[tick])
        seen = [int((vertex_ns[offsets[k] : offsets[k + 1]] <= now).sum()) for k in range(len(names))]
        # where each robot is now (ground truth at its latest pose)
        _log_links(rec, [truth[k][max(seen[k] - 1, 0)] for k in range(len(names))], pairs, contact[tick])
        got = order[(delivered_tick[order] >= 0) & (delivered_tick[order] <= tick)]
        if len(got) > MAX_CLOSURE_SEGMENTS:
            got = got[np.linspace(0, len(got) - 1, MAX_CLOSURE_SEGMENTS).astype(np.int64)]
        ends_a = flat_truth[offsets[closure_from[got]] + closure_from_index[got]]
        ends_b = flat_truth[offsets[closure_to[got]] + closure_to_index[got]]
        _log_closures(rec, ends_a, ends_b)
        for name_b, _, ape, beliefs in runs:
            b = rr.escape_entity_path_part(name_b)
            _log_beliefs(rec, b, beliefs[c], names=names, offsets=offsets, seen=seen, stride=stride, colours=colours)
            rec.log(REPLAY_APE.format(backend=b), rr.Scalars(float(ape[c])))
        for name_b, series in sve:
            if np.isfinite(series[c]):
                rec.log(REPLAY_SVE.format(backend=rr.escape_entity_path_part(name_b)), rr.Scalars(float(series[c])))


def write_replay_recording(
    path: PathLike,
    graph: PoseGraph,
    *,
    name: str,
    force: bool = False,
    inputs: Sequence[PathLike] = (),
    **columns: Any,
) -> Path:
    """Write the replay to a new ``.rrd`` (staged, renamed into place; never over or inside
    ``inputs``, the files it was made from); ``columns`` as :func:`log_replay` takes them."""
    import rerun as rr

    from studio.io.atomic import staged_outputs
    from studio.recording.dataset import is_planar_graph, recording_id_for

    path = Path(path)
    backends = [r[0] for r in columns["runs"]]
    truth = np.concatenate([np.asarray(a.ground_truth)[:, 0:3] for a in graph.to_se3().agents])
    planar = is_planar_graph(graph)  # the dataset recording's rule: seen from above when planar
    rid = recording_id_for(graph)

    def write(target: Path) -> None:
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid, send_properties=False)
        rec.set_log_time_enabled(False)
        with closing(rec, target, shown=path):
            rec.save(
                target, default_blueprint=replay_blueprint(backends, truth, planar=planar, sve=bool(columns.get("sve")))
            )
            rec.send_recording_name(name)
            log_replay(rec, graph, **columns)

    with staged_outputs(path.parent, [path.name], force=force, inputs=inputs) as staging:
        write_bounded(write, staging / path.name, shown=path)
    return path
