"""Sightings of one agent by another (range and bearing), tied to the graph's keyframes.

A source that carries robot-to-robot measurements (MR.CLAM) reads them into :class:`Sightings`:
stamps and agent names as the data has them. After the graph is built, :func:`resolve_sightings`
ties each side of a sighting to that agent's keyframe nearest in time (the offset is kept and
written), and estimates the measurements' noise against the ground truth: the true range and bearing
at the sighting's stamp come from both agents' ground-truth trajectories (interpolated), and each
standard deviation is the robust spread (1.4826 x the median absolute deviation) of the errors, with
a floor of 1 mm / 1 mrad. Sightings outside an agent's time span are dropped and counted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studio.converters.odometry_source import poses_at
from studio.core.geometry import normalize_angle, yaw_from_quat_xyzw
from studio.core.model import PoseGraph, RangeBearing
from studio.core.trajectory import Trajectory

__all__ = ["Sightings", "SightingsFit", "resolve_sightings", "MIN_SIGMA_RANGE_M", "MIN_SIGMA_BEARING_RAD"]

MIN_SIGMA_RANGE_M = 1e-3
MIN_SIGMA_BEARING_RAD = 1e-3


@dataclass(frozen=True, eq=False)
class Sightings:
    """Raw sightings: ``observer``/``observed`` index :attr:`names` (robot names of the source)."""

    names: tuple[str, ...]
    stamps_ns: np.ndarray
    observer: np.ndarray
    observed: np.ndarray
    range_m: np.ndarray
    bearing_rad: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)
    """What the source left out (landmark sightings, unknown barcodes, ...), by name."""


@dataclass(frozen=True)
class SightingsFit:
    sightings: int
    dropped_outside_time_span: int
    sigma_range_m: float
    sigma_bearing_rad: float
    rms_range_error_m: float
    rms_bearing_error_rad: float
    beyond_3_sigma: int
    max_keyframe_offset_s: float
    median_keyframe_offset_s: float
    source_counts: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The fit as report.json holds it; a value there is none of (NaN: no sightings) is null."""
        from dataclasses import asdict

        return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in asdict(self).items()}


def _agent_of(name: str, names: Sequence[str]) -> list[int]:
    """Agents that are robot ``name`` (itself, or the parts ``name_1..`` of a split)."""
    out = []
    for k, n in enumerate(names):
        base, sep, part = n.rpartition("_")
        if n == name or (sep and part.isdigit() and base == name):
            out.append(k)
    return out


def _side(stamps: np.ndarray, robot: np.ndarray, robot_names: Sequence[str], graph: PoseGraph):
    """Per sighting, the agent (or -1) whose keyframe span holds it, and its nearest keyframe."""
    names = [a.name for a in graph.agents]
    agent = np.full(len(stamps), -1, dtype=np.int64)
    index = np.zeros(len(stamps), dtype=np.int64)
    offset = np.zeros(len(stamps), dtype=np.int64)
    for r, rname in enumerate(robot_names):
        for k in _agent_of(rname, names):
            st = graph.agents[k].stamps_ns
            sel = (robot == r) & (agent < 0) & (stamps >= st[0]) & (stamps <= st[-1])
            rows = np.flatnonzero(sel)
            if not rows.size:
                continue
            hi = np.clip(np.searchsorted(st, stamps[rows]), 0, len(st) - 1)
            lo = np.maximum(hi - 1, 0)
            near = np.where(np.abs(stamps[rows] - st[lo]) <= np.abs(st[hi] - stamps[rows]), lo, hi)
            agent[rows], index[rows], offset[rows] = k, near, stamps[rows] - st[near]
    return agent, index, offset


def resolve_sightings(
    graph: PoseGraph, sightings: Sightings, trajectories: Sequence[Trajectory]
) -> tuple[RangeBearing, SightingsFit]:
    """Tie ``sightings`` to ``graph``'s keyframes and estimate their noise on ``trajectories`` (the
    ground truth the graph was built from, one per agent in the graph's order)."""
    s = sightings
    a_obs, i_obs, o_obs = _side(s.stamps_ns, s.observer, s.names, graph)
    a_tgt, i_tgt, o_tgt = _side(s.stamps_ns, s.observed, s.names, graph)
    keep = np.flatnonzero((a_obs >= 0) & (a_tgt >= 0))
    dropped = len(s.stamps_ns) - len(keep)
    stamps, rng, brg = s.stamps_ns[keep], s.range_m[keep], s.bearing_rad[keep]
    a_obs, i_obs, o_obs, a_tgt, i_tgt, o_tgt = (x[keep] for x in (a_obs, i_obs, o_obs, a_tgt, i_tgt, o_tgt))
    true_r = np.zeros(len(keep))
    true_b = np.zeros(len(keep))
    for k in np.unique(a_obs).tolist():
        for j in np.unique(a_tgt[a_obs == k]).tolist():
            rows = np.flatnonzero((a_obs == k) & (a_tgt == j))
            p_o, q_o = poses_at(trajectories[k], stamps[rows], what="the ground truth")
            p_t, _ = poses_at(trajectories[j], stamps[rows], what="the ground truth")
            d = p_t[:, 0:2] - p_o[:, 0:2]
            true_r[rows] = np.linalg.norm(d, axis=1)
            true_b[rows] = normalize_angle(np.arctan2(d[:, 1], d[:, 0]) - yaw_from_quat_xyzw(q_o))
    err_r = rng - true_r
    err_b = normalize_angle(brg - true_b)

    def robust(e: np.ndarray, floor: float) -> float:
        if not len(e):
            return floor
        return max(floor, 1.4826 * float(np.median(np.abs(e - np.median(e)))))

    sig_r, sig_b = robust(err_r, MIN_SIGMA_RANGE_M), robust(err_b, MIN_SIGMA_BEARING_RAD)
    n = len(keep)
    rb = RangeBearing(stamps, a_obs, i_obs, a_tgt, i_tgt, rng, brg, np.full(n, sig_r), np.full(n, sig_b), o_obs, o_tgt)
    offsets = np.abs(np.concatenate([o_obs, o_tgt])) / 1e9
    fit = SightingsFit(
        n,
        dropped,
        sig_r,
        sig_b,
        float(np.sqrt(np.mean(err_r**2))) if n else math.nan,
        float(np.sqrt(np.mean(err_b**2))) if n else math.nan,
        int(np.count_nonzero((np.abs(err_r) > 3 * sig_r) | (np.abs(err_b) > 3 * sig_b))),
        float(offsets.max()) if n else 0.0,
        float(np.median(offsets)) if n else 0.0,
        dict(s.counts),
    )
    return rb, fit
