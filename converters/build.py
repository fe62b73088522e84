"""From timestamped trajectories to a multi-agent pose graph (pure maths on numpy columns, no I/O).

Steps, in order (see ``docs/converters.md`` for the models):

1. one shared origin (the first position of the first agent) is subtracted from every position, so
   UTM-sized coordinates become local while agents keep their true relative placement;
2. keyframes: the first and last pose, every ``keyframe_distance`` metres of path, every
   ``keyframe_angle`` degrees of accumulated rotation, every ``keyframe_time`` seconds, and both
   ends of every gap longer than ``max_gap`` seconds;
3. odometry between consecutive keyframes: the true relative pose perturbed by Gaussian noise whose
   standard deviation grows with the distance and rotation travelled (and with the duration of a
   gap for a bridging edge), the matching diagonal information, and the dead-reckoning initial
   estimate (composition of the noisy odometry from the true first pose);
4. loop closures by proximity: all keyframe pairs closer than ``lc_radius`` are found with a grid
   of cells of that size (sort + binary search, never all pairs), filtered (intra-agent: at least
   ``lc_min_time`` seconds and ``lc_min_index`` keyframes apart; inter-agent: any time, or within
   ``rendezvous`` seconds; optional heading compatibility) and accepted with probability
   ``p * exp(-5 (d / R)^2)``;
5. optional outliers: a fraction of the accepted loop closures point at a wrong vertex.

Every random draw comes from a :class:`numpy.random.Generator` seeded with ``(seed, stream)``, one
stream per purpose, so the same trajectories, options and seed give the same graph bit for bit, and
changing a loop-closure option does not change the odometry noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Callable, Sequence

import numpy as np

from studio.core.errors import ConfigError
from studio.core.geometry import (
    normalize_angle,
    quat_angle,
    quat_canonical,
    quat_conj,
    quat_from_rotvec,
    quat_mul,
    quat_rotate,
)
from studio.core.trajectory import Trajectory
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.units import NS_PER_S

__all__ = ["GraphOptions", "Gap", "BuildResult", "build_graph", "pairs_within", "select_keyframes"]

_DIAG21 = np.array([0, 6, 11, 15, 18, 20])  # diagonal entries of a 6x6 upper triangle
_STREAM_ODOMETRY, _STREAM_LOOPS, _STREAM_OUTLIERS = 1, 2, 3

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class GraphOptions:
    """How trajectories become a graph. Lengths in metres, angles in degrees unless the name says
    ``rad``, times in seconds. A value of 0 turns an optional rule off where noted."""

    seed: int = 0
    """Seed of every random draw (noise, loop-closure selection, outliers)."""
    keyframe_distance: float = 1.0
    """A keyframe every this many metres of path (0: off)."""
    keyframe_angle: float = 15.0
    """A keyframe every this many degrees of accumulated rotation (0: off)."""
    keyframe_time: float = 0.0
    """A keyframe every this many seconds (0: off)."""
    max_gap: float = 1.0
    """Stamps further apart than this [s] are a ground-truth gap: bridged and reported."""
    gap_sigma_m_per_s: float = 0.05
    """Extra translation std dev of a bridging edge per second of gap [m/s]."""
    gap_sigma_rad_per_s: float = 0.005
    """Extra rotation std dev of a bridging edge per second of gap [rad/s]."""
    odo_sigma_m_per_m: float = 0.02
    """Odometry translation std dev per metre travelled [m/m], on each axis."""
    odo_sigma_rad_per_rad: float = 0.02
    """Odometry rotation std dev per radian turned [rad/rad], on each axis."""
    odo_sigma_rad_per_m: float = 0.001
    """Odometry rotation std dev per metre travelled [rad/m]."""
    odo_sigma_min_m: float = 0.002
    """Odometry translation std dev floor [m]."""
    odo_sigma_min_rad: float = 0.0005
    """Odometry rotation std dev floor [rad]."""
    lc_radius: float = 2.0
    """Loop-closure radius R [m]."""
    lc_prob_intra: float = 0.5
    """p of intra-agent loop closures (probability at distance 0)."""
    lc_prob_inter: float = 0.5
    """p of inter-agent loop closures."""
    lc_min_time: float = 30.0
    """Intra-agent pairs must be at least this far apart in time [s]."""
    lc_min_index: int = 10
    """Intra-agent pairs must be at least this many keyframes apart."""
    lc_max_heading: float = 0.0
    """Heading compatibility: the x axes of both poses within this angle [deg] (0: off)."""
    rendezvous: float = 0.0
    """Inter-agent pairs must be within this many seconds of each other (0: any time)."""
    lc_sigma_m: float = 0.05
    """Loop-closure translation noise std dev [m], on each axis."""
    lc_sigma_rad: float = 0.01
    """Loop-closure rotation noise std dev [rad], on each axis."""
    outlier_fraction: float = 0.0
    """Fraction of accepted loop closures turned into outliers (wrong vertex), in [0, 1)."""
    planar: bool = False
    """Project to SE(2): x, y and yaw only."""

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            key = "--" + f.name.replace("_", "-")
            if f.name == "planar":
                if not isinstance(v, bool):
                    raise ConfigError(f"{key}: expected true or false, got {v!r}")
                continue
            if f.name in ("seed", "lc_min_index"):
                if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                    raise ConfigError(f"{key}: expected a non-negative integer, got {v!r}")
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"{key}: expected a finite number >= 0, got {v!r}")
            object.__setattr__(self, f.name, float(v))  # 3 and 3.0 give the same convert.json
        if self.lc_radius <= 0:
            raise ConfigError("--lc-radius: must be > 0")
        if self.max_gap <= 0:
            raise ConfigError("--max-gap: must be > 0")
        if self.lc_prob_intra > 1 or self.lc_prob_inter > 1:
            raise ConfigError("--lc-prob-intra/--lc-prob-inter: a probability must be <= 1")
        if self.outlier_fraction >= 1:
            raise ConfigError("--outlier-fraction: must be < 1")
        if self.lc_max_heading > 180:
            raise ConfigError("--lc-max-heading: must be <= 180 degrees")


@dataclass(frozen=True)
class Gap:
    """A ground-truth gap longer than ``max_gap``, bridged by odometry edge ``vertex -> vertex + 1``."""

    agent: str
    vertex: int
    start_ns: int
    end_ns: int
    metres: float

    @property
    def seconds(self) -> float:
        return (self.end_ns - self.start_ns) / NS_PER_S


@dataclass(frozen=True, eq=False)
class BuildResult:
    graph: PoseGraph
    origin_xyz: np.ndarray
    """The shared origin subtracted from every position (in the sources' frame) [m]."""
    gaps: tuple[Gap, ...]
    outliers: np.ndarray
    """(k, 4) int64 rows ``agent_from vertex_from agent_to vertex_to`` (0-based) of the outliers."""
    candidates: dict = field(default_factory=dict)
    """Counts: candidate pairs within R, and accepted, per kind."""


def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([seed, stream])


def select_keyframes(stamps_ns: np.ndarray, positions_xyz: np.ndarray, quat_xyzw: np.ndarray,
                     opts: GraphOptions) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the keyframes, and the boolean "a gap follows this pose" of every pose."""
    n = len(stamps_ns)
    gap_after = np.zeros(n, dtype=bool)
    gap_after[:-1] = np.diff(stamps_ns) > int(round(opts.max_gap * NS_PER_S))
    new = np.zeros(n, dtype=bool)
    new[0] = new[-1] = True
    new |= gap_after
    new[1:] |= gap_after[:-1]
    if opts.keyframe_distance > 0:
        step = np.linalg.norm(np.diff(positions_xyz, axis=0), axis=1)
        b = np.floor(np.concatenate([[0.0], np.cumsum(step)]) / opts.keyframe_distance)
        new[1:] |= b[1:] != b[:-1]
    if opts.keyframe_angle > 0:
        turn = quat_angle(quat_mul(quat_conj(quat_xyzw[:-1]), quat_xyzw[1:]))
        b = np.floor(np.concatenate([[0.0], np.cumsum(turn)]) / math.radians(opts.keyframe_angle))
        new[1:] |= b[1:] != b[:-1]
    if opts.keyframe_time > 0:
        b = (stamps_ns - stamps_ns[0]) // max(1, int(round(opts.keyframe_time * NS_PER_S)))
        new[1:] |= b[1:] != b[:-1]
    return np.flatnonzero(new), gap_after


def _relative(p_a, q_a, p_b, q_b):
    """Pose of b in the frame of a: translation and quaternion."""
    qa_inv = quat_conj(q_a)
    return quat_rotate(qa_inv, p_b - p_a), quat_mul(qa_inv, q_b)


def _perturb(t_rel, q_rel, sigma_t, sigma_r, rng, planar):
    """Measurement ``(t + n_t, q * Exp(n_r))`` with the diagonal information of the noise."""
    m = len(t_rel)
    z = rng.standard_normal((m, 6))
    sig = np.column_stack([sigma_t, sigma_t, sigma_t, sigma_r, sigma_r, sigma_r])
    noise = z * sig
    if planar:
        noise[:, [2, 3, 4]] = 0.0
    t = t_rel + noise[:, :3]
    q = quat_canonical(quat_mul(q_rel, quat_from_rotvec(noise[:, 3:])))
    info = np.zeros((m, 21))
    info[:, _DIAG21] = 1.0 / np.maximum(sig, 1e-9) ** 2
    return np.column_stack([t, q]), info


def _compose_chain(p0, q0, t_steps, q_steps):
    """Poses obtained by composing ``steps`` from ``(p0, q0)``: a log-depth prefix scan."""
    T = t_steps.copy()
    Q = q_steps.copy()
    k = 1
    while k < len(T):
        T_new = T.copy()
        Q_new = Q.copy()
        T_new[k:] = quat_rotate(Q[:-k], T[k:]) + T[:-k]
        Q_new[k:] = quat_mul(Q[:-k], Q[k:])
        T, Q = T_new, Q_new / np.linalg.norm(Q_new, axis=1, keepdims=True)
        k *= 2
    m = len(T)
    qs = np.repeat(q0[None, :], m, axis=0)
    pos = p0 + quat_rotate(qs, T)
    quat = quat_canonical(quat_mul(qs, Q))
    return (np.vstack([p0[None, :], pos]), np.vstack([quat_canonical(q0[None, :]), quat]))


#: Memory for one candidate pair while loop closures are searched (indices, distance, temporaries).
BYTES_PER_CANDIDATE = 64


def pairs_within(points_xyz: np.ndarray, radius: float, *,
                 max_bytes: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All pairs ``i < j`` with ``|p_i - p_j| < radius``, found with a grid of ``radius``-sized cells.

    Returns ``(i, j, d)`` sorted by ``(i, j)``. Cost: sort + binary search per neighbour cell, and
    memory linear in the number of points plus pairs in neighbouring cells. With ``max_bytes``, the
    candidates are counted first and a search that would need more memory raises ConfigError.
    """
    n = len(points_xyz)
    if n < 2:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    cell = np.floor(points_xyz / radius).astype(np.int64)
    cell -= cell.min(axis=0) - 1
    dims = cell.max(axis=0) + 2
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.argsort(key, kind="stable")
    skey = key[order]
    idx = np.arange(n)
    if max_bytes is not None:
        candidates = 0
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                nk = key + (dx * dims[1] + dy) * dims[2] + np.arange(-1, 2)[:, None]
                candidates += int((np.searchsorted(skey, nk, "right") - np.searchsorted(skey, nk, "left")).sum())
        need = candidates * BYTES_PER_CANDIDATE
        if need > max_bytes:
            raise ConfigError(
                f"the loop-closure search would examine {candidates:.3g} keyframe pairs (about "
                f"{need / 1e9:.3g} GB of memory, over the {max_bytes / 1e9:g} GB limit): use a smaller "
                f"--lc-radius, a larger --keyframe-distance, or raise --max-memory-gb"
            )
    out_i, out_j, out_d = [], [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                nk = key + (dx * dims[1] + dy) * dims[2] + dz
                lo = np.searchsorted(skey, nk, "left")
                hi = np.searchsorted(skey, nk, "right")
                cnt = hi - lo
                total = int(cnt.sum())
                if total == 0:
                    continue
                i = np.repeat(idx, cnt)
                first = np.cumsum(cnt) - cnt
                j = order[np.arange(total) - np.repeat(first, cnt) + np.repeat(lo, cnt)]
                keep = i < j
                i, j = i[keep], j[keep]
                d = np.linalg.norm(points_xyz[i] - points_xyz[j], axis=1)
                close = d < radius
                out_i.append(i[close])
                out_j.append(j[close])
                out_d.append(d[close])
    if not out_i:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    i, j, d = np.concatenate(out_i), np.concatenate(out_j), np.concatenate(out_d)
    o = np.lexsort((j, i))
    return i[o], j[o], d[o]


def _planarise(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    q = traj.quat_xyzw
    yaw = np.arctan2(2.0 * (q[:, 3] * q[:, 2] + q[:, 0] * q[:, 1]), 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2))
    pos = traj.positions_xyz.copy()
    pos[:, 2] = 0.0
    quat = np.zeros((len(q), 4))
    quat[:, 2] = np.sin(yaw / 2)
    quat[:, 3] = np.cos(yaw / 2)
    return pos, quat


def _se3_rows_to_se2(rows7: np.ndarray) -> np.ndarray:
    yaw = normalize_angle(2.0 * np.arctan2(rows7[:, 5], rows7[:, 6]))
    return np.column_stack([rows7[:, 0], rows7[:, 1], yaw])


def _info_to_se2(info21: np.ndarray) -> np.ndarray:
    # (x, y, rz) entries of the 6x6 upper triangle: xx xy x-rz yy y-rz rz-rz
    return info21[:, [0, 1, 5, 6, 10, 20]]


def build_graph(trajectories: Sequence[Trajectory], opts: GraphOptions, *,
                progress: Progress | None = None, max_memory_gb: float | None = None) -> BuildResult:
    """Build the pose graph of ``trajectories`` (agent order kept); see the module docstring.

    ``max_memory_gb`` bounds the loop-closure search, checked before it allocates anything.
    """
    if not trajectories:
        raise ConfigError("no trajectories to convert")
    names = [t.name for t in trajectories]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise ConfigError(f"two agents are named {dup!r}; rename one of the inputs")
    origin = trajectories[0].positions_xyz[0].copy()
    if opts.planar:
        origin[2] = 0.0
    rng_odo = _rng(opts.seed, _STREAM_ODOMETRY)
    gaps: list[Gap] = []
    kf_pos, kf_quat, kf_stamps, kf_agent, kf_index = [], [], [], [], []
    agents_data = []
    for a, traj in enumerate(trajectories):
        if progress:
            progress("keyframes and odometry", a, len(trajectories))
        if opts.planar:
            pos, quat = _planarise(traj)
        else:
            pos, quat = traj.positions_xyz, traj.quat_xyzw
        pos = pos - origin
        kf, gap_after = select_keyframes(traj.stamps_ns, pos, quat, opts)
        p, q, st = pos[kf], quat_canonical(quat[kf]), traj.stamps_ns[kf]
        t_rel, q_rel = _relative(p[:-1], q[:-1], p[1:], q[1:])
        dist = np.linalg.norm(t_rel, axis=1)
        turn = quat_angle(q_rel)
        sigma_t = opts.odo_sigma_min_m + opts.odo_sigma_m_per_m * dist
        sigma_r = opts.odo_sigma_min_rad + opts.odo_sigma_rad_per_rad * turn + opts.odo_sigma_rad_per_m * dist
        bridge = gap_after[kf[:-1]]
        dt = np.diff(st) / NS_PER_S
        sigma_t = sigma_t + np.where(bridge, opts.gap_sigma_m_per_s * dt, 0.0)
        sigma_r = sigma_r + np.where(bridge, opts.gap_sigma_rad_per_s * dt, 0.0)
        meas, info = _perturb(t_rel, q_rel, sigma_t, sigma_r, rng_odo, opts.planar)
        init_p, init_q = _compose_chain(p[0], q[0], meas[:, :3], meas[:, 3:])
        for v in np.flatnonzero(bridge).tolist():
            gaps.append(Gap(traj.name, int(v), int(st[v]), int(st[v + 1]), float(dist[v])))
        m = len(kf)
        agents_data.append((traj.name, st, np.column_stack([init_p, init_q]), np.column_stack([p, q]),
                            meas, info))
        kf_pos.append(p)
        kf_quat.append(q)
        kf_stamps.append(st)
        kf_agent.append(np.full(m, a, dtype=np.int64))
        kf_index.append(np.arange(m, dtype=np.int64))
    if progress:
        progress("loop closures", 0, 1)
    P = np.concatenate(kf_pos)
    Qk = np.concatenate(kf_quat)
    S = np.concatenate(kf_stamps)
    A = np.concatenate(kf_agent)
    V = np.concatenate(kf_index)
    i, j, d = pairs_within(P, opts.lc_radius, max_bytes=None if max_memory_gb is None else max_memory_gb * 1e9)
    same = A[i] == A[j]
    dt_ns = np.abs(S[j] - S[i])
    ok = np.where(same, (dt_ns >= int(round(opts.lc_min_time * NS_PER_S))) & (np.abs(V[j] - V[i]) >= opts.lc_min_index),
                  True)
    if opts.rendezvous > 0:
        ok &= same | (dt_ns <= int(round(opts.rendezvous * NS_PER_S)))
    if opts.lc_max_heading > 0:
        ex = np.zeros((len(i), 3))
        ex[:, 0] = 1.0
        fi, fj = quat_rotate(Qk[i], ex), quat_rotate(Qk[j], ex)
        ok &= np.einsum("ij,ij->i", fi, fj) >= math.cos(math.radians(opts.lc_max_heading))
    i, j, d, same = i[ok], j[ok], d[ok], same[ok]
    p0 = np.where(same, opts.lc_prob_intra, opts.lc_prob_inter)
    prob = p0 * np.exp(-5.0 * (d / opts.lc_radius) ** 2)
    rng_lc = _rng(opts.seed, _STREAM_LOOPS)
    accept = rng_lc.random(len(i)) < prob
    i, j, same = i[accept], j[accept], same[accept]
    t_rel, q_rel = _relative(P[i], Qk[i], P[j], Qk[j])
    n_lc = len(i)
    meas_lc, info_lc = _perturb(t_rel, q_rel, np.full(n_lc, opts.lc_sigma_m), np.full(n_lc, opts.lc_sigma_rad),
                                rng_lc, opts.planar)
    j_out = j.copy()
    outlier = np.zeros(n_lc, dtype=bool)
    if opts.outlier_fraction > 0 and n_lc:
        rng_out = _rng(opts.seed, _STREAM_OUTLIERS)
        k = int(round(opts.outlier_fraction * n_lc))
        chosen = np.sort(rng_out.choice(n_lc, size=k, replace=False))
        for e in chosen.tolist():
            # a wrong vertex of the same agent as the true one, at least 2R from it (and from i)
            mask = (A == A[j[e]]) & (np.linalg.norm(P - P[j[e]], axis=1) >= 2 * opts.lc_radius)
            mask &= np.linalg.norm(P - P[i[e]], axis=1) >= 2 * opts.lc_radius
            cand = np.flatnonzero(mask)
            if cand.size:
                j_out[e] = cand[rng_out.integers(cand.size)]
                outlier[e] = True
    agents = []
    kind = PoseKind.SE2 if opts.planar else PoseKind.SE3
    for a, (name, st, init, gt, meas, info) in enumerate(agents_data):
        sel = same & (A[i] == a)
        m = len(st)
        odo = Edges(PoseKind.SE3, np.arange(m - 1), np.arange(1, m), meas, info)
        lc = Edges(PoseKind.SE3, V[i[sel]], V[j_out[sel]], meas_lc[sel], info_lc[sel])
        agents.append((name, st, init, gt, odo, lc))
    inter_sel = ~same
    inter_cols = (A[i[inter_sel]], V[i[inter_sel]], A[j_out[inter_sel]], V[j_out[inter_sel]],
                  meas_lc[inter_sel], info_lc[inter_sel])
    graph = _assemble(kind, agents, inter_cols)
    out_rows = np.column_stack([A[i], V[i], A[j_out], V[j_out]])[outlier].astype(np.int64).reshape(-1, 4)
    counts = {
        "candidate_pairs": int(len(ok)),
        "intra_loop_closures": int(np.count_nonzero(same)),
        "inter_loop_closures": int(np.count_nonzero(~same)),
        "outliers": int(np.count_nonzero(outlier)),
    }
    return BuildResult(graph, origin, tuple(gaps), out_rows, counts)


def _assemble(kind: PoseKind, agents, inter_cols) -> PoseGraph:
    planar = kind is PoseKind.SE2

    def rows(x):
        return _se3_rows_to_se2(x) if planar else x

    def info(x):
        return _info_to_se2(x) if planar else x

    out = []
    for name, st, init, gt, odo, lc in agents:
        out.append(AgentGraph(
            name, kind, st, rows(init), rows(gt),
            Edges(kind, odo.from_index, odo.to_index, rows(odo.measurements), info(odo.information_upper)),
            Edges(kind, lc.from_index, lc.to_index, rows(lc.measurements), info(lc.information_upper)),
        ))
    fa, fv, ta, tv, meas, inf = inter_cols
    inter = InterAgentEdges(kind, fa, fv, ta, tv, rows(meas), info(inf))
    return PoseGraph(kind, tuple(out), inter)
