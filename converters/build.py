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
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from studio.converters.options import GraphOptions, option_help
from studio.core.errors import ConfigError
from studio.core.geometry import (
    normalize_angle,
    quat_angle,
    quat_canonical,
    quat_conj,
    quat_from_rotvec,
    quat_mul,
    quat_rotate,
    relative_planar_pose,
    yaw_from_quat_xyzw,
)
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.outliers import WrongVertexRule, plant_wrong_vertices
from studio.core.trajectory import Trajectory
from studio.core.units import NS_PER_S
from studio.runtime.progress import Progress  # the callback type of build_graph (re-exported)

__all__ = [
    "GraphOptions",
    "OUTLIER_KIND",
    "option_help",
    "Gap",
    "BuildResult",
    "build_graph",
    "pairs_within",
    "select_keyframes",
    "step_turns_rad",
]

_DIAG21 = np.array([0, 6, 11, 15, 18, 20])  # diagonal entries of a 6x6 upper triangle
_DIAG6 = np.array([0, 3, 5])  # diagonal entries of a 3x3 upper triangle
_STREAM_ODOMETRY, _STREAM_LOOPS, _STREAM_OUTLIERS = 1, 2, 3


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


def step_turns_rad(quat_xyzw: np.ndarray) -> np.ndarray:
    """Rotation angle [rad] between consecutive orientations (``n - 1`` values)."""
    return quat_angle(quat_mul(quat_conj(quat_xyzw[:-1]), quat_xyzw[1:]))


def select_keyframes(
    stamps_ns: np.ndarray,
    positions: np.ndarray,
    step_turn_rad: np.ndarray,
    opts: GraphOptions,
    forced_ns: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the keyframes, and the boolean "a gap follows this pose" of every pose.

    ``positions`` are ``(n, 2)`` or ``(n, 3)`` metres; ``step_turn_rad`` the ``n - 1`` rotation angles
    between consecutive poses (:func:`step_turns_rad`, or the yaw increments of a planar path).
    ``forced_ns``: stamps whose nearest pose must be a keyframe (those within the span)."""
    n = len(stamps_ns)
    gap_after = np.zeros(n, dtype=bool)
    gap_after[:-1] = np.diff(stamps_ns) > int(round(opts.max_gap * NS_PER_S))
    new = np.zeros(n, dtype=bool)
    new[0] = new[-1] = True
    new |= gap_after
    new[1:] |= gap_after[:-1]
    if opts.keyframe_distance > 0:
        step = np.linalg.norm(np.diff(positions, axis=0), axis=1)
        b = np.floor(np.concatenate([[0.0], np.cumsum(step)]) / opts.keyframe_distance)
        new[1:] |= b[1:] != b[:-1]
    if opts.keyframe_angle > 0:
        b = np.floor(np.concatenate([[0.0], np.cumsum(step_turn_rad)]) / math.radians(opts.keyframe_angle))
        new[1:] |= b[1:] != b[:-1]
    if opts.keyframe_time > 0:
        b = (stamps_ns - stamps_ns[0]) // max(1, int(round(opts.keyframe_time * NS_PER_S)))
        new[1:] |= b[1:] != b[:-1]
    if forced_ns is not None and len(forced_ns):
        f = np.asarray(forced_ns, dtype=np.int64)
        f = f[(f >= stamps_ns[0]) & (f <= stamps_ns[-1])]
        hi = np.clip(np.searchsorted(stamps_ns, f), 0, n - 1)
        lo = np.maximum(hi - 1, 0)
        new[np.where(np.abs(f - stamps_ns[lo]) <= np.abs(stamps_ns[hi] - f), lo, hi)] = True
    return np.flatnonzero(new), gap_after


def _relative(p_a, q_a, p_b, q_b):
    """Pose of b in the frame of a: translation and quaternion."""
    qa_inv = quat_conj(q_a)
    return quat_rotate(qa_inv, p_b - p_a), quat_mul(qa_inv, q_b)


#: g2o's ``EDGE_SE3:QUAT`` error uses the quaternion's vector part, ``sin(theta/2) axis``, about half
#: the rotation vector: the information of a rotation noise of std dev s is ``4 / s^2`` in that
#: convention (docs/formats.md). Planar (``EDGE_SE2``) information is on the angle itself.
SE3_QUAT_INFORMATION_SCALE = 4.0


def _perturb(t_rel, q_rel, sigma_t, sigma_r, rng):
    """Measurement ``(t + n_t, q * Exp(n_r))`` with the diagonal information of the noise in g2o's
    ``EDGE_SE3:QUAT`` convention (rotation information on the quaternion's vector part)."""
    m = len(t_rel)
    z = rng.standard_normal((m, 6))
    sig = np.column_stack([sigma_t, sigma_t, sigma_t, sigma_r, sigma_r, sigma_r])
    noise = z * sig
    t = t_rel + noise[:, :3]
    q = quat_canonical(quat_mul(q_rel, quat_from_rotvec(noise[:, 3:])))
    info = np.zeros((m, 21))
    info[:, _DIAG21] = 1.0 / np.maximum(sig, 1e-9) ** 2
    info[:, _DIAG21[3:]] *= SE3_QUAT_INFORMATION_SCALE
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


def _relative_se2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Planar poses ``b`` in the frames of ``a`` (rows ``x y yaw``)."""
    dx, dy, dth = relative_planar_pose(a[:, 0], a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2])
    return np.column_stack([dx, dy, dth])


def _perturb_se2(
    rel: np.ndarray, sigma_t: np.ndarray, sigma_r: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Planar measurement ``(dx + n_x, dy + n_y, dyaw + n_yaw)`` with its diagonal information.

    Six normals are drawn per edge as in the spatial model (x, y and the z rotation are used), so a
    stream gives the same noise to a planar and a spatial conversion of the same path."""
    m = len(rel)
    z = rng.standard_normal((m, 6))
    sig = np.column_stack([sigma_t, sigma_t, sigma_r])
    noise = z[:, [0, 1, 5]] * sig
    meas = np.column_stack([rel[:, 0:2] + noise[:, 0:2], normalize_angle(rel[:, 2] + noise[:, 2])])
    info = np.zeros((m, 6))
    info[:, _DIAG6] = 1.0 / np.maximum(sig, 1e-9) ** 2
    return meas, info


def _compose_se2(first: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Planar poses obtained by composing ``steps`` (rows ``dx dy dyaw``) from the pose ``first``."""
    yaw = first[2] + np.concatenate([[0.0], np.cumsum(steps[:, 2])])
    c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    dx = c * steps[:, 0] - s * steps[:, 1]
    dy = s * steps[:, 0] + c * steps[:, 1]
    xy = first[0:2] + np.column_stack([np.concatenate([[0.0], np.cumsum(dx)]), np.concatenate([[0.0], np.cumsum(dy)])])
    return np.column_stack([xy, normalize_angle(yaw)])


#: Memory for one candidate pair while loop closures are searched (indices, distance, temporaries).
BYTES_PER_CANDIDATE = 64


def pairs_within(
    points_xyz: np.ndarray,
    radius: float,
    *,
    max_bytes: float | None = None,
    on_step: Callable[[int, int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All pairs ``i < j`` with ``|p_i - p_j| < radius``, found with a grid of ``radius``-sized cells.

    Returns ``(i, j, d)`` sorted by ``(i, j)``. Cost: sort + binary search per neighbour cell, and
    memory linear in the number of points plus pairs in neighbouring cells. With ``max_bytes``, the
    candidates are counted first and a search that would need more memory raises ConfigError.
    ``on_step(examined, candidates)`` hears of the candidate pairs examined so far (``candidates`` is
    0 when they were not counted).
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
    candidates = 0
    if max_bytes is not None:
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
    examined = 0
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                nk = key + (dx * dims[1] + dy) * dims[2] + dz
                lo = np.searchsorted(skey, nk, "left")
                hi = np.searchsorted(skey, nk, "right")
                cnt = hi - lo
                total = int(cnt.sum())
                examined += total
                if on_step is not None:
                    on_step(examined, max(candidates, examined))
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


def build_graph(
    trajectories: Sequence[Trajectory],
    opts: GraphOptions,
    *,
    progress: Progress | None = None,
    max_memory_gb: float | None = None,
    keyframe_stamps: Mapping[str, np.ndarray] | None = None,
) -> BuildResult:
    """Build the pose graph of ``trajectories`` (agent order kept); see the module docstring.

    ``keyframe_stamps``: per agent name, stamps whose nearest pose must be a keyframe (where a
    source's sightings were made).

    ``max_memory_gb`` bounds the loop-closure search, checked before it allocates anything. The steps
    of the module docstring, in order: the shared origin (1), each agent's keyframes and odometry (2,
    3), the loop closures (4), the outliers (5), then the graph of their columns.
    """
    if not trajectories:
        raise ConfigError("no trajectories to convert")
    _check_distinct_names(trajectories)
    origin = trajectories[0].positions_xyz[0].copy()
    if opts.planar:
        origin[2] = 0.0
    chains = _keyframe_chains(trajectories, origin, opts, progress, keyframe_stamps)
    loops = _loop_closures(chains, opts, progress, max_memory_gb)
    j_out, outlier = _plant_outliers(chains, loops, opts)
    graph = _assemble(chains, loops, j_out, opts.planar)
    i, same = loops.i, loops.same
    out_rows = np.column_stack([chains.A[i], chains.V[i], chains.A[j_out], chains.V[j_out]])[outlier]
    counts = {
        "candidate_pairs": loops.candidate_pairs,
        "intra_loop_closures": int(np.count_nonzero(same)),
        "inter_loop_closures": int(np.count_nonzero(~same)),
        "outliers": int(np.count_nonzero(outlier)),
    }
    return BuildResult(graph, origin, chains.gaps, out_rows.astype(np.int64).reshape(-1, 4), counts)


def _check_distinct_names(trajectories: Sequence[Trajectory]) -> None:
    names = [t.name for t in trajectories]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        files = [str(t.source) for t in trajectories if t.name == dup][:2]
        raise ConfigError(
            f"two agents are named {dup!r} ({' and '.join(files)}); rename one of the inputs (or its folder)"
        )


@dataclass(frozen=True, eq=False)
class _AgentChain:
    """One agent's keyframes and odometry (steps 2 and 3)."""

    name: str
    stamps_ns: np.ndarray
    initial: np.ndarray
    truth: np.ndarray
    measurements: np.ndarray
    information: np.ndarray
    positions_xyz: np.ndarray
    """(m, 3) true keyframe positions [m] (z = 0 when planar), for the loop-closure search."""
    headings: np.ndarray
    """(m,) yaw [rad] when planar, else (m, 4) quaternions ``xyzw``."""
    gaps: list[Gap]


@dataclass(frozen=True, eq=False)
class _Chains:
    """Every agent's chain and the keyframe columns of all agents, concatenated in agent order."""

    agents: list[_AgentChain]
    gaps: tuple[Gap, ...]
    P: np.ndarray  # positions [m]
    H: np.ndarray  # yaw (planar) or quaternion rows
    S: np.ndarray  # stamps [ns]
    A: np.ndarray  # agent of each keyframe
    V: np.ndarray  # index of each keyframe in its agent


def _keyframe_chains(
    trajectories: Sequence[Trajectory],
    origin: np.ndarray,
    opts: GraphOptions,
    progress: Progress | None,
    forced: Mapping[str, np.ndarray] | None = None,
) -> _Chains:
    """Steps 2 and 3 for every agent, in order (one odometry noise stream for all)."""
    rng_odo = _rng(opts.seed, _STREAM_ODOMETRY)
    agents = []
    for a, traj in enumerate(trajectories):
        if progress:
            progress("keyframes and odometry", a, len(trajectories), "agents")
        agents.append(_agent_chain(traj, origin, opts, rng_odo, (forced or {}).get(traj.name)))
    if progress:
        progress("keyframes and odometry", len(trajectories), len(trajectories), "agents")
    return _Chains(
        agents,
        tuple(g for c in agents for g in c.gaps),
        np.concatenate([c.positions_xyz for c in agents]),
        np.concatenate([c.headings for c in agents]),
        np.concatenate([c.stamps_ns for c in agents]),
        np.concatenate([np.full(len(c.stamps_ns), a, dtype=np.int64) for a, c in enumerate(agents)]),
        np.concatenate([np.arange(len(c.stamps_ns), dtype=np.int64) for c in agents]),
    )


def _agent_chain(
    traj: Trajectory,
    origin: np.ndarray,
    opts: GraphOptions,
    rng_odo: np.random.Generator,
    forced_ns: np.ndarray | None = None,
) -> _AgentChain:
    """One agent's keyframes (step 2) and noisy odometry with its dead-reckoning estimate (step 3)."""
    planar = opts.planar
    if planar:
        # planar graphs are built in SE(2) from the start: x, y and the heading (ZYX yaw)
        pos = traj.positions_xyz[:, 0:2] - origin[0:2]
        yaw = yaw_from_quat_xyzw(traj.quat_xyzw)
        kf, gap_after = select_keyframes(traj.stamps_ns, pos, np.abs(normalize_angle(np.diff(yaw))), opts, forced_ns)
        gt = np.column_stack([pos[kf], yaw[kf]])
        rel = _relative_se2(gt[:-1], gt[1:])
        dist = np.linalg.norm(rel[:, 0:2], axis=1)
        turn = np.abs(rel[:, 2])
    else:
        pos = traj.positions_xyz - origin
        kf, gap_after = select_keyframes(traj.stamps_ns, pos, step_turns_rad(traj.quat_xyzw), opts, forced_ns)
        p, q = pos[kf], quat_canonical(traj.quat_xyzw[kf])
        t_rel, q_rel = _relative(p[:-1], q[:-1], p[1:], q[1:])
        dist = np.linalg.norm(t_rel, axis=1)
        turn = quat_angle(q_rel)
    st = traj.stamps_ns[kf]
    sigma_t = opts.odo_sigma_min_m + opts.odo_sigma_m_per_m * dist
    sigma_r = opts.odo_sigma_min_rad + opts.odo_sigma_rad_per_rad * turn + opts.odo_sigma_rad_per_m * dist
    bridge = gap_after[kf[:-1]]
    dt = np.diff(st) / NS_PER_S
    sigma_t = sigma_t + np.where(bridge, opts.gap_sigma_m_per_s * dt, 0.0)
    sigma_r = sigma_r + np.where(bridge, opts.gap_sigma_rad_per_s * dt, 0.0)
    if planar:
        meas, info = _perturb_se2(rel, sigma_t, sigma_r, rng_odo)
        init = _compose_se2(gt[0], meas)
        kf_pos, kf_heading = np.column_stack([gt[:, 0:2], np.zeros(len(gt))]), gt[:, 2]
    else:
        meas, info = _perturb(t_rel, q_rel, sigma_t, sigma_r, rng_odo)
        init_p, init_q = _compose_chain(p[0], q[0], meas[:, :3], meas[:, 3:])
        init, gt = np.column_stack([init_p, init_q]), np.column_stack([p, q])
        kf_pos, kf_heading = p, q
    gaps = [Gap(traj.name, int(v), int(st[v]), int(st[v + 1]), float(dist[v])) for v in np.flatnonzero(bridge).tolist()]
    return _AgentChain(traj.name, st, init, gt, meas, info, kf_pos, kf_heading, gaps)


@dataclass(frozen=True, eq=False)
class _Loops:
    """The accepted loop closures (step 4): keyframe pairs ``i -> j`` (indices into the columns)."""

    i: np.ndarray
    j: np.ndarray
    same: np.ndarray
    """True for an intra-agent pair."""
    measurements: np.ndarray
    information: np.ndarray
    candidate_pairs: int
    """Pairs within R, before the filters."""


def _loop_closures(
    chains: _Chains, opts: GraphOptions, progress: Progress | None, max_memory_gb: float | None
) -> _Loops:
    """Step 4: the pairs within R, filtered, accepted with ``p exp(-5 (d/R)^2)``, and measured."""
    P, H, S, A, V = chains.P, chains.H, chains.S, chains.A, chains.V
    if progress:
        progress("loop-closure search", 0, 0, "pairs")
    i, j, d = pairs_within(
        P,
        opts.lc_radius,
        max_bytes=None if max_memory_gb is None else max_memory_gb * 1e9,
        on_step=None
        if progress is None
        else (lambda done, total: progress("loop-closure search", done, total, "pairs")),
    )
    same = A[i] == A[j]
    dt_ns = np.abs(S[j] - S[i])
    ok = np.where(
        same, (dt_ns >= int(round(opts.lc_min_time * NS_PER_S))) & (np.abs(V[j] - V[i]) >= opts.lc_min_index), True
    )
    if opts.rendezvous > 0:
        ok &= same | (dt_ns <= int(round(opts.rendezvous * NS_PER_S)))
    if opts.lc_max_heading > 0:
        if opts.planar:
            cos_between = np.cos(H[j] - H[i])
        else:
            ex = np.zeros((len(i), 3))
            ex[:, 0] = 1.0
            cos_between = np.einsum("ij,ij->i", quat_rotate(H[i], ex), quat_rotate(H[j], ex))
        ok &= cos_between >= math.cos(math.radians(opts.lc_max_heading))
    i, j, d, same = i[ok], j[ok], d[ok], same[ok]
    p0 = np.where(same, opts.lc_prob_intra, opts.lc_prob_inter)
    prob = p0 * np.exp(-5.0 * (d / opts.lc_radius) ** 2)
    rng_lc = _rng(opts.seed, _STREAM_LOOPS)
    accept = rng_lc.random(len(i)) < prob
    i, j, same = i[accept], j[accept], same[accept]
    n_lc = len(i)
    sig_t, sig_r = np.full(n_lc, opts.lc_sigma_m), np.full(n_lc, opts.lc_sigma_rad)
    if opts.planar:
        meas_lc, info_lc = _perturb_se2(
            _relative_se2(np.column_stack([P[i, 0:2], H[i]]), np.column_stack([P[j, 0:2], H[j]])), sig_t, sig_r, rng_lc
        )
    else:
        t_rel, q_rel = _relative(P[i], H[i], P[j], H[j])
        meas_lc, info_lc = _perturb(t_rel, q_rel, sig_t, sig_r, rng_lc)
    return _Loops(i, j, same, meas_lc, info_lc, int(len(ok)))


#: The kind of the outliers the builder plants (``outliers.txt``'s ``# kind:`` line): the ``to`` vertex
#: replaced by one at least two loop-closure radii from both true endpoints.
OUTLIER_KIND = "far"


def _plant_outliers(chains: _Chains, loops: _Loops, opts: GraphOptions) -> tuple[np.ndarray, np.ndarray]:
    """Step 5: the ``to`` keyframe of every loop closure (a wrong one for the outliers) and which are
    outliers."""
    i, j = loops.i, loops.j
    n_lc = len(i)
    j_out = j.copy()
    outlier = np.zeros(n_lc, dtype=bool)
    if opts.outlier_fraction > 0 and n_lc:
        rng_out = _rng(opts.seed, _STREAM_OUTLIERS)
        k = int(round(opts.outlier_fraction * n_lc))
        chosen = np.sort(rng_out.choice(n_lc, size=k, replace=False))
        # a wrong vertex of the same agent as the true one, at least 2R from it and from the from vertex;
        # a loop closure without such a vertex stays true
        far = WrongVertexRule(OUTLIER_KIND, min_to_m=2 * opts.lc_radius, min_from_m=2 * opts.lc_radius)
        A, V = chains.A, chains.V
        ends = np.column_stack([A[i], V[i], A[j], V[j]])
        kf_pos = [c.positions_xyz for c in chains.agents]
        new_to, _ = plant_wrong_vertices(rng_out, ends, chosen.tolist(), [(far, k)], kf_pos)
        first = np.cumsum([0] + [len(p) for p in kf_pos])  # each agent's first keyframe in P
        for e, v in new_to.items():
            j_out[e] = first[A[j[e]]] + v
            outlier[e] = True
    return j_out, outlier


def _assemble(chains: _Chains, loops: _Loops, j_out: np.ndarray, planar: bool) -> PoseGraph:
    """The graph: each agent's odometry and intra-agent loop closures, then the inter-agent ones."""
    A, V, i, same = chains.A, chains.V, loops.i, loops.same
    kind = PoseKind.SE2 if planar else PoseKind.SE3
    agents = []
    for a, c in enumerate(chains.agents):
        sel = same & (A[i] == a)
        m = len(c.stamps_ns)
        agents.append(
            AgentGraph(
                c.name,
                kind,
                c.stamps_ns,
                c.initial,
                c.truth,
                Edges(kind, np.arange(m - 1), np.arange(1, m), c.measurements, c.information),
                Edges(kind, V[i[sel]], V[j_out[sel]], loops.measurements[sel], loops.information[sel]),
            )
        )
    inter_sel = ~same
    inter = InterAgentEdges(
        kind,
        A[i[inter_sel]],
        V[i[inter_sel]],
        A[j_out[inter_sel]],
        V[j_out[inter_sel]],
        loops.measurements[inter_sel],
        loops.information[inter_sel],
    )
    return PoseGraph(kind, tuple(agents), inter)
