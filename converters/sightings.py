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
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from studio.converters.odometry_source import poses_at
from studio.core.errors import GraphError
from studio.core.geometry import normalize_angle, yaw_from_quat_xyzw
from studio.core.model import InterAgentEdges, PoseGraph, PoseKind, RangeBearing
from studio.core.trajectory import Trajectory
from studio.io.graph_table import matrix_to_upper

__all__ = [
    "Sightings",
    "SightingsFit",
    "resolve_sightings",
    "sighting_closures",
    "sighting_stamps",
    "with_sighting_closures",
    "MIN_SIGMA_RANGE_M",
    "MIN_SIGMA_BEARING_RAD",
]

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


#: Seed stream of the drawn relative headings of sighting closures (build.py uses 1-3).
STREAM_SIGHTING_HEADINGS = 4


def _planar_at(trajectories: Sequence[Trajectory], agent: np.ndarray, stamps: np.ndarray) -> np.ndarray:
    """``(n, 3)`` ground-truth ``x y yaw`` of ``agent[k]`` at ``stamps[k]`` (interpolated)."""
    out = np.zeros((len(stamps), 3))
    for a in np.unique(agent).tolist():
        rows = np.flatnonzero(agent == a)
        p, q = poses_at(trajectories[a], stamps[rows], what="the ground truth")
        out[rows] = np.column_stack([p[:, 0:2], yaw_from_quat_xyzw(q)])
    return out


def _compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack(
        [a[:, 0] + c * b[:, 0] - s * b[:, 1], a[:, 1] + s * b[:, 0] + c * b[:, 1], normalize_angle(a[:, 2] + b[:, 2])]
    )


def _between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` of planar rows."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, normalize_angle(b[:, 2] - a[:, 2])])


def _rot(theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def sighting_closures(
    graph: PoseGraph,
    rb: RangeBearing,
    trajectories: Sequence[Trajectory],
    *,
    sigma_heading_rad: float,
    seed: int,
) -> InterAgentEdges:
    """One inter-agent closure per sighting, from the observer's keyframe to the observed one's.

    The observed robot's position in the observer's frame at the sighting is the measurement
    itself, ``range (cos bearing, sin bearing)``; the relative heading, which a range and a bearing
    do not observe, is the ground truth's at that time plus N(0, ``sigma_heading_rad``) noise (seed
    stream :data:`STREAM_SIGHTING_HEADINGS`). Each side is carried from the sighting's time to its
    keyframe along that robot's ground truth (the keyframe offsets, as synthetic odometry would).
    The information is the inverse of the covariance propagated from ``sigma_range_m``,
    ``sigma_bearing_rad`` and ``sigma_heading_rad`` (first order), in the frame of the edge's error
    (g2o's ``Z^-1 (Xi^-1 Xj)``), so range and bearing keep their own, unequal, weights. Planar
    graphs only (a 3D graph's z, roll and pitch would have no measurement)."""
    if graph.kind is not PoseKind.SE2:
        raise GraphError("sighting closures are planar: build the graph with planar=True (--planar)")
    n = len(rb)
    a_t = _planar_at(trajectories, rb.observer_agent, rb.stamps_ns)
    b_t = _planar_at(trajectories, rb.observed_agent, rb.stamps_ns)
    kf_a = np.array([graph.agents[a].stamps_ns[i] for a, i in zip(rb.observer_agent, rb.observer_index)], np.int64)
    kf_b = np.array([graph.agents[a].stamps_ns[i] for a, i in zip(rb.observed_agent, rb.observed_index)], np.int64)
    off_a = _between(_planar_at(trajectories, rb.observer_agent, kf_a.reshape(-1)), a_t)  # A_i^-1 A(t)
    off_b = _between(b_t, _planar_at(trajectories, rb.observed_agent, kf_b.reshape(-1)))  # B(t)^-1 B_j
    rng = np.random.default_rng([seed, STREAM_SIGHTING_HEADINGS])
    phi = normalize_angle(b_t[:, 2] - a_t[:, 2] + rng.normal(0.0, sigma_heading_rad, n))
    r, b = rb.range_m, rb.bearing_rad
    meas = np.column_stack([r * np.cos(b), r * np.sin(b), phi])
    z = _compose(_compose(off_a, meas), off_b)
    # first-order covariance of z in (range, bearing, heading)
    ra = _rot(off_a[:, 2])
    ob = off_b[:, 0:2]
    d_phi = np.column_stack(
        [-np.sin(phi) * ob[:, 0] - np.cos(phi) * ob[:, 1], np.cos(phi) * ob[:, 0] - np.sin(phi) * ob[:, 1]]
    )
    jac = np.zeros((n, 3, 3))
    jac[:, 0:2, 0] = np.einsum("nij,nj->ni", ra, np.column_stack([np.cos(b), np.sin(b)]))
    jac[:, 0:2, 1] = np.einsum("nij,nj->ni", ra, r[:, None] * np.column_stack([-np.sin(b), np.cos(b)]))
    jac[:, 0:2, 2] = np.einsum("nij,nj->ni", ra, d_phi)
    jac[:, 2, 2] = 1.0
    sig = np.zeros((n, 3, 3))
    sig[:, 0, 0], sig[:, 1, 1], sig[:, 2, 2] = rb.sigma_range_m**2, rb.sigma_bearing_rad**2, sigma_heading_rad**2
    cov = jac @ sig @ jac.transpose(0, 2, 1)
    g = np.zeros((n, 3, 3))
    g[:, 0:2, 0:2] = _rot(z[:, 2]).transpose(0, 2, 1)
    g[:, 2, 2] = 1.0
    info = np.linalg.inv(g @ cov @ g.transpose(0, 2, 1))
    info = (info + info.transpose(0, 2, 1)) / 2
    upper = matrix_to_upper(info)
    meas_rows = z
    return InterAgentEdges(
        graph.kind, rb.observer_agent, rb.observer_index, rb.observed_agent, rb.observed_index, meas_rows, upper
    )


def with_sighting_closures(graph: PoseGraph, closures: InterAgentEdges) -> PoseGraph:
    """``graph`` with ``closures`` after its inter-agent loop closures."""
    old = graph.inter
    cat = np.concatenate
    inter = InterAgentEdges(
        graph.kind,
        cat([old.from_agent, closures.from_agent]),
        cat([old.from_index, closures.from_index]),
        cat([old.to_agent, closures.to_agent]),
        cat([old.to_index, closures.to_index]),
        cat([old.measurements, closures.measurements]),
        cat([old.information_upper, closures.information_upper]),
    )
    return replace(graph, inter=inter)


def sighting_stamps(sightings: Sightings, agent_names: Sequence[str]) -> dict[str, np.ndarray]:
    """Per agent name (a robot, or the parts ``name_1..`` of a split), the stamps of the sightings it
    made or was seen in: where :func:`studio.converters.build.build_graph` puts keyframes when asked."""
    s = sightings
    out: dict[str, np.ndarray] = {}
    for r, rname in enumerate(s.names):
        stamps = np.unique(s.stamps_ns[(s.observer == r) | (s.observed == r)])
        for k in _agent_of(rname, agent_names):
            out[agent_names[k]] = stamps
    return out
