"""A numpy re-implementation of kollagen's data generator, bit-exact with its C++.

The public entry point is :func:`generate`, which turns a :class:`~generator.config.SynthConfig` into
a planar :class:`~studio.core.model.PoseGraph` and the few extras kollagen's single g2o file needs.

How it stays exact while being fast:

* The random walk draws its turns and odometry noise from each agent's ``mt19937`` in kollagen's
  order (one integer per step, then a position and an angle normal per sub-step) in a short scalar
  loop over pre-decoded uniforms; positions and headings are then built with integer cumulative sums.
* Loop-closure candidates ("hits": an occupied grid cell inside the discrete circle around a pose) are
  enumerated with a sorted-cell search (cost O(N + hits) instead of kollagen's O(N * R^2) map look-ups)
  and put in the exact order kollagen visits them. Each hit consumes one uniform; between two accepted
  loop closures the uniforms sit at fixed stream positions, so acceptance is decided in bulk with numpy
  and only the accepted ones (and their three normals) go through Python.
* Floating-point expressions are evaluated in kollagen's order; libm's sin/cos/exp/log are called
  through :mod:`math` rather than numpy's vectorised versions, which may differ by an ulp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from studio.generator.config import SynthConfig
from studio.core.parallel import parallel_map
from studio.generator.rng import MT19937Stream, canonical_doubles, polar_normal
from studio.core.geometry import libm_cos_sin, normalize_angle, relative_planar_pose
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.units import NS_PER_S
from studio.generator.seam import GeneratedDataset

__all__ = ["KOLLAGEN", "KollagenGenerator", "SingleG2oView", "SynthOutput", "generate", "effective_seeds", "discrete_circle", "agent_pairs"]



@dataclass(frozen=True, eq=False)
class SynthOutput:
    """What kollagen's generator produces."""

    graph: PoseGraph
    """Planar graph: per agent ground truth, dead reckoning, odometry (estimated information) and
    intra-agent loop closures; inter-agent loop closures in kollagen's order."""
    exact_odometry_information: tuple[np.ndarray, ...] | None
    """Per agent ``(n-1, 6)`` derived odometry information, when the config asks for it (kollagen
    writes it to the single g2o file only)."""
    connector_information: np.ndarray
    """``(6,)`` information of the edges that chain agents together in the single g2o file."""
    seeds: tuple[int, ...]
    """The agents' seeds after kollagen's replacement of duplicates."""


# --------------------------------------------------------------------------------------------------
# Small kollagen semantics


def _round_half_away(v: np.ndarray) -> np.ndarray:
    """C's ``round``: half away from zero (numpy's ``round`` goes half to even)."""
    t = np.trunc(v)
    frac = v - t
    return (t + np.where(np.abs(frac) >= 0.5, np.sign(v), 0.0)).astype(np.int64)


def _round_to_int(v: float) -> int:
    t = math.trunc(v)
    if abs(v - t) >= 0.5:
        t += 1 if v > 0 else -1
    return int(t)


def _libstdcxx_reduce(values: np.ndarray) -> float:
    """``std::reduce(first, last)`` as libstdc++ evaluates it for random-access iterators."""
    vals = values.tolist()
    init = 0.0
    n4 = len(vals) - len(vals) % 4
    for k in range(0, n4, 4):
        init = init + ((vals[k] + vals[k + 1]) + (vals[k + 2] + vals[k + 3]))
    for v in vals[n4:]:
        init = init + v
    return init


def effective_seeds(seeds: list[int]) -> tuple[int, ...]:
    """kollagen's ``add_walker`` seed rule, quirk included.

    A seed already used is replaced by the largest seed so far plus one. kollagen's list of used seeds
    starts with one zero per existing agent (its vector is sized, then appended to), so seed 0 counts
    as used from the second agent on. The seed is a C++ ``int``, so ``INT_MAX + 1`` wraps around.
    """
    used: list[int] = []
    out = []
    for k, seed in enumerate(seeds):
        pool = [0] * k + used
        if k > 0 and seed in pool:
            seed = (max(pool) + 1 + 2**31) % 2**32 - 2**31  # C++ int: INT_MAX + 1 wraps to INT_MIN
        used.append(seed)
        out.append(seed)
    return tuple(out)


def discrete_circle(radius: int) -> np.ndarray:
    """kollagen's ``DiscreteCircle``: ``(k, 2)`` integer offsets in its iteration order.

    x runs from -radius to radius; for each x, y takes 0, 1, -1, 2, -2, ... while y^2 <= r^2 - x^2.
    """
    xs = np.arange(-radius, radius + 1, dtype=np.int64)
    ylim = np.array([math.isqrt(radius * radius - x * x) for x in xs.tolist()], dtype=np.int64)
    counts = 2 * ylim + 1
    x = np.repeat(xs, counts)
    k = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    y = (k + 1) // 2 * np.where(k % 2 == 1, 1, -1)
    return np.column_stack([x, y])


def agent_pairs(n: int) -> list[tuple[int, int]]:
    """The pairs kollagen's ``get_all_pairs`` yields (lexicographic), for n >= 2."""
    return [(a, b) for a in range(n) for b in range(a + 1, n)]


def _quarter_angle_table() -> dict[int, tuple[float, float, float]]:
    """theta_int -> (theta as kollagen stores it, cos, sin), for theta_int in -3..3."""
    table = {}
    for k in range(-3, 4):
        th = normalize_angle(k * 0.5 * math.pi)
        table[k] = (th, math.cos(th), math.sin(th))
    return table


_QUARTER = _quarter_angle_table()


# --------------------------------------------------------------------------------------------------
# The random walk


@dataclass(frozen=True, eq=False)
class _Walk:
    x: np.ndarray  # ground truth (before alignment), metres
    y: np.ndarray
    theta: np.ndarray
    delta_theta: np.ndarray  # per odometry edge: the turn (quarter turns) at a step's first sub-step
    odom_pos: np.ndarray
    odom_ang: np.ndarray
    drx: np.ndarray
    dry: np.ndarray
    drtheta: np.ndarray


def _walk_draws(stream: MT19937Stream, n_steps: int, frag: int, retro: bool):
    """Turns and odometry normals in kollagen's draw order; leaves the stream after the last draw.

    Each step draws one integer (``uniform_int_distribution(-1, 1 + retro)``, Lemire's method) and
    then, per sub-step, a position normal and an angle normal: one polar-method round whose two
    uniforms start at any word offset, so uniforms are pre-decoded at every offset.
    """
    span = 3 + int(retro)
    threshold = ((1 << 32) - span) % span
    turns = [0] * n_steps
    n_pos = [0.0] * (n_steps * frag)
    n_ang = [0.0] * (n_steps * frag)
    log, sqrt = math.log, math.sqrt
    want = n_steps + 6 * n_steps * frag + 4096
    s = 0
    while s < n_steps:
        words = stream.words(want)
        w = words.tolist()
        u = canonical_doubles(words, every_offset=True).tolist()
        p = 0
        try:
            while s < n_steps:
                start = p
                prod = w[p] * span
                p += 1
                while (prod & 0xFFFFFFFF) < threshold:
                    prod = w[p] * span
                    p += 1
                base = s * frag
                for k in range(frag):
                    # rng.polar_normal inlined: this loop runs once per pose
                    while True:
                        x = 2.0 * u[p] - 1.0
                        y = 2.0 * u[p + 2] - 1.0
                        p += 4
                        r2 = x * x + y * y
                        if not (r2 > 1.0 or r2 == 0.0):
                            break
                    mult = sqrt(-2.0 * log(r2) / r2)
                    n_pos[base + k] = y * mult
                    n_ang[base + k] = x * mult
                turns[s] = (prod >> 32) - 1
                s += 1
        except IndexError:  # the buffer ended inside a step: redo that step with more words
            p = start
        stream.advance(p)
        want *= 2
    return np.array(turns, dtype=np.int64), np.array(n_pos), np.array(n_ang)


def _random_walk(stream: MT19937Stream, cfg: SynthConfig, agent) -> _Walk:
    frag, stepsize = cfg.step_fragment, cfg.stepsize
    turns, npos, nang = _walk_draws(stream, cfg.number_of_steps, frag, cfg.allow_retrocession)
    # heading in quarter turns, with C's truncating %
    theta_int_steps = np.empty(len(turns), dtype=np.int64)
    t = 0
    for s, d in enumerate(turns.tolist()):
        t = int(math.fmod(t + d, 4))
        theta_int_steps[s] = t
    theta_int = np.repeat(theta_int_steps, frag)
    lut = np.arange(-3, 4)
    th_tab = np.array([_QUARTER[k][0] for k in lut])
    dx_tab = np.array([_round_to_int(_QUARTER[k][1]) for k in lut], dtype=np.int64)
    dy_tab = np.array([_round_to_int(_QUARTER[k][2]) for k in lut], dtype=np.int64)
    dxi = dx_tab[theta_int + 3]
    dyi = dy_tab[theta_int + 3]
    xi = np.concatenate([[0], np.cumsum(dxi)])
    yi = np.concatenate([[0], np.cumsum(dyi)])
    x = xi.astype(np.float64) * stepsize / frag
    y = yi.astype(np.float64) * stepsize / frag
    theta = np.concatenate([[0.0], th_tab[theta_int + 3]])
    ddx = dxi.astype(np.float64) * stepsize / frag
    ddy = dyi.astype(np.float64) * stepsize / frag
    odom_pos = np.hypot(ddx, ddy) + agent.std_dev_position * npos
    delta_theta = np.zeros(len(theta_int), dtype=np.int64)
    delta_theta[::frag] = turns
    first = np.zeros(len(theta_int), dtype=bool)
    first[::frag] = True
    turn_angle = np.array([normalize_angle(k * 0.5 * math.pi) for k in range(-1, 3)])[delta_theta + 1]
    noise_ang = agent.std_dev_angle * nang
    odom_ang = np.where(first, turn_angle + noise_ang, noise_ang)
    drx, dry, drt = _dead_reckon(odom_pos, odom_ang)
    return _Walk(x, y, theta, delta_theta, odom_pos, odom_ang, drx, dry, drt)


def _dead_reckon(odom_pos: np.ndarray, odom_ang: np.ndarray):
    cos, sin, floor = math.cos, math.sin, math.floor
    pi, two_pi = math.pi, 2 * math.pi
    n = len(odom_pos) + 1
    xs = [0.0] * n
    ys = [0.0] * n
    ts = [0.0] * n
    x = y = t = 0.0
    for k, (op, oa) in enumerate(zip(odom_pos.tolist(), odom_ang.tolist()), start=1):
        t = t + oa
        t = t - floor((t + pi) / two_pi) * 2.0 * pi
        x = x + op * cos(t)
        y = y + op * sin(t)
        xs[k] = x
        ys[k] = y
        ts[k] = t
    return np.array(xs), np.array(ys), np.array(ts)


# --------------------------------------------------------------------------------------------------
# Loop-closure candidates and their sampling


def _grid_cells(x: np.ndarray, y: np.ndarray, cfg: SynthConfig) -> tuple[np.ndarray, np.ndarray]:
    frag, stepsize = float(cfg.step_fragment), cfg.stepsize
    return _round_half_away(x * frag / stepsize), _round_half_away(y * frag / stepsize)


class _CircleTable:
    """kollagen's discrete circle: the rank of each offset in its visiting order.

    Rank -1 is the same-cell check that comes before the circle; ranks 0.. follow ``DiscreteCircle``
    (the centre offset itself is skipped there).
    """

    def __init__(self, radius: int) -> None:
        self.radius = radius
        circle = discrete_circle(radius)
        size = 2 * radius + 1
        self.rank = np.full((size, size), -2, dtype=np.int64)
        self.rank[circle[:, 0] + radius, circle[:, 1] + radius] = np.arange(len(circle))
        self.rank[radius, radius] = -1
        self.size = len(circle)
        #: squared offset length and "diagonal or centre" per rank + 1
        d2 = np.zeros(self.size + 1, dtype=np.int64)
        d2[1:] = circle[:, 0] ** 2 + circle[:, 1] ** 2
        self.d2_by_rank = d2
        diag = np.ones(self.size + 1, dtype=bool)
        diag[1:] = (circle[:, 0] != 0) & (circle[:, 1] != 0)
        self.diagonal_by_rank = diag
        self.ylim = np.array(
            [math.isqrt(radius * radius - dx * dx) for dx in range(-radius, radius + 1)], dtype=np.int64
        )

    def probabilities(self, same_cell: float, scale: float, radius_m: float) -> np.ndarray:
        """Probability per rank + 1: ``same_cell`` for the same-cell check, else kollagen's
        ``scale * exp(-5 (dx^2 + dy^2) / r^2)`` (offsets in cells, radius in metres)."""
        p = np.array([scale * math.exp(-5.0 * v / (radius_m * radius_m)) for v in self.d2_by_rank.tolist()])
        p[0] = same_cell
        return p


def _visits(cx: np.ndarray, cy: np.ndarray, which: str) -> np.ndarray:
    """For each distinct grid cell, the index of its ``"first"`` or ``"last"`` visit (kollagen's
    intra-agent map keeps the first visit, its inter-agent map the last)."""
    key = (cx - cx.min()) * (int(cy.max() - cy.min()) + 1) + (cy - cy.min())
    if which == "first":
        return np.unique(key, return_index=True)[1]
    return len(key) - 1 - np.unique(key[::-1], return_index=True)[1]


def _enumerate_hits(qx, qy, tx, ty, circle: _CircleTable):
    """Every (query k, table m) pair whose cells are at most the circle's radius apart.

    Returns ``(k, m, rank)`` sorted in kollagen's visiting order: by query, then the same-cell check,
    then the circle's order. Table cells must be distinct.
    """
    R = circle.radius
    if len(tx) == 0 or len(qx) == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z, z
    xmin = min(int(qx.min()), int(tx.min())) - R
    ymin = min(int(qy.min()), int(ty.min())) - R
    stride = max(int(qy.max()), int(ty.max())) - ymin + R + 1
    tkey = (tx - xmin) * stride + (ty - ymin)
    order = np.argsort(tkey)
    skey = tkey[order]
    qkey = (qx - xmin) * stride + (qy - ymin)
    dxs = np.arange(-R, R + 1, dtype=np.int64)
    centre = qkey[:, None] + dxs[None, :] * stride
    start = np.searchsorted(skey, (centre - circle.ylim[None, :]).ravel(), side="left")
    stop = np.searchsorted(skey, (centre + circle.ylim[None, :]).ravel(), side="right")
    counts = stop - start
    total = int(counts.sum())
    shift = start - (np.cumsum(counts) - counts)
    pos = np.arange(total, dtype=np.int64) + np.repeat(shift, counts)
    k = np.repeat(np.arange(len(qx), dtype=np.int64), counts.reshape(len(qx), -1).sum(axis=1))
    # offset (dx, dy) as dx * stride + dy, mapped to its rank in the circle
    delta = skey[pos] - qkey[k]
    lut = np.full((2 * R + 1) * stride, -2, dtype=np.int64)
    span = np.arange(-R, R + 1, dtype=np.int64)
    lut[((span[:, None] + R) * stride + (span[None, :] + R)).ravel()] = circle.rank.ravel()
    rank = lut[delta + R * stride + R]
    key = k * (circle.size + 1) + (rank + 1)
    perm = np.argsort(key, kind="stable")
    return k[perm], order[pos[perm]], rank[perm]


def _sample(stream: MT19937Stream, probs: np.ndarray, cached: float | None):
    """Decide every hit with one uniform each; accepted hits draw three normals.

    Between two accepted hits the uniforms sit at fixed stream positions, so a whole chunk of hits is
    compared with its uniforms at once and only accepted hits (and their normals) run in Python.
    Returns (accepted hit indices, (n, 3) normals, cache state after the last draw) and advances the
    stream past everything consumed.
    """
    n_hits = len(probs)
    accepted: list[int] = []
    normals: list[float] = []
    # expected uniforms: one per hit plus about 2.5 per accepted hit for its three normals
    budget = n_hits + int(3 * float(np.minimum(probs, 1.0).sum())) + 1024  # a probability over 1 accepts once
    u = stream.uniforms(budget)
    h = 0  # next hit
    q = 0  # next uniform
    chunk = 256
    while h < n_hits:
        k = min(chunk, n_hits - h)
        if q + k + 64 > len(u):
            u = stream.uniforms(max(2 * len(u), q + k + 4096))
        hit = probs[h : h + k] > u[q : q + k]
        t = int(hit.argmax())
        if not hit[t]:
            h += k
            q += k
            chunk = min(chunk * 2, 1 << 16)
            continue
        h += t
        q += t + 1
        chunk = max(64, 2 * (t + 1))
        for _ in range(3):
            if cached is not None:
                normals.append(cached)
                cached = None
                continue
            while True:
                window = u[q : q + 16].tolist()
                try:
                    ret, keep, used = polar_normal(window, 0)
                    break
                except IndexError:  # 8 rejections in a row, or the end of the buffer
                    if q + 64 > len(u):
                        u = stream.uniforms(2 * len(u))
                    window = u[q : q + 4096].tolist()
                    ret, keep, used = polar_normal(window, 0)
                    break
            q += used
            normals.append(ret)
            cached = keep
        accepted.append(h)
        h += 1
    stream.advance(2 * q)
    return np.array(accepted, dtype=np.int64), np.array(normals).reshape(-1, 3), cached


def _intra_loop_closures(stream: MT19937Stream, walk: _Walk, cfg: SynthConfig, agent):
    cx, cy = _grid_cells(walk.x, walk.y, cfg)
    n = len(cx)
    radius = _round_to_int(agent.intra_loop_closure_radius * cfg.step_fragment / cfg.stepsize)
    circle = _CircleTable(radius)
    first = np.sort(_visits(cx, cy, "first"))  # cells in order of their first visit
    # kollagen's map only holds cells first visited before the current pose. Poses are taken in
    # blocks; a block looks only at cells first visited before its end, so few hits are discarded.
    parts = []
    bounds = np.linspace(0, n, num=min(n, 16) + 1).astype(np.int64)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        known = first[: np.searchsorted(first, hi)]
        k, m, rank = _enumerate_hits(cx[lo:hi], cy[lo:hi], cx[known], cy[known], circle)
        k = k + lo
        j = known[m]
        # intra-agent: only cells seen before, and (kollagen's quirk) only diagonal circle offsets
        keep = (j < k) & circle.diagonal_by_rank[rank + 1]
        parts.append((k[keep], j[keep], rank[keep]))
    k, j, rank = (np.concatenate(c) for c in zip(*parts))
    probs = circle.probabilities(
        agent.same_position_intra_loop_closure_probability,
        agent.intra_loop_closure_probability_scaling,
        agent.intra_loop_closure_radius,
    )[rank + 1]
    acc, noise, _ = _sample(stream, probs, None)
    i_to, j_from = k[acc], j[acc]
    dX, dY, dT = relative_planar_pose(walk.x[j_from], walk.y[j_from], walk.theta[j_from],
                           walk.x[i_to], walk.y[i_to], walk.theta[i_to])
    sp, sa = agent.std_dev_intra_loop_closure_position, agent.std_dev_intra_loop_closure_angle
    meas = np.column_stack([dX + noise[:, 0] * sp, dY + noise[:, 1] * sp, dT + noise[:, 2] * sa])
    info = _diag_information(
        len(acc), agent.estimated_information_intra_position, agent.estimated_information_intra_angle
    )
    return Edges(PoseKind.SE2, j_from, i_to, meas.reshape(-1, 3), info)


def _inter_loop_closures(walks, cells, cfg: SynthConfig, jobs: int | None):
    p = cfg.inter
    radius = _round_to_int(p.loop_closure_radius * cfg.step_fragment / cfg.stepsize)
    circle = _CircleTable(radius)
    prob_by_rank = circle.probabilities(
        p.same_position_loop_closure_probability, p.loop_closure_probability_scaling, p.loop_closure_radius
    )
    pairs = agent_pairs(len(walks))

    def one_pair(index: int):
        a, b = pairs[index]
        wa, wb = walks[a], walks[b]
        (ax, ay), (bx, by) = cells[a], cells[b]
        # kollagen's map keeps the last visit of each cell of agent a
        last = _visits(ax, ay, "last")
        k, m, rank = _enumerate_hits(bx, by, ax[last], ay[last], circle)
        j = last[m]
        probs = prob_by_rank[rank + 1]
        stream = MT19937Stream(p.random_number_generator_seed)
        acc, noise, _ = _sample(stream, probs, None)
        i_from, j_to = k[acc], j[acc]
        dX, dY, dT = relative_planar_pose(wb.x[i_from], wb.y[i_from], wb.theta[i_from],
                               wa.x[j_to], wa.y[j_to], wa.theta[j_to])
        meas = np.column_stack([
            dX + noise[:, 0] * p.std_dev_loop_closure_position,
            dY + noise[:, 1] * p.std_dev_loop_closure_position,
            dT + noise[:, 2] * p.std_dev_loop_closure_angle,
        ])
        return np.full(len(acc), b), i_from, np.full(len(acc), a), j_to, meas.reshape(-1, 3)

    done = parallel_map(one_pair, len(pairs), jobs)
    cols = {c: [d[k] for d in done] for k, c in enumerate(("fa", "fi", "ta", "ti", "m"))}
    meas = np.concatenate(cols["m"])
    info = _diag_information(len(meas), p.estimated_information_position, p.estimated_information_angle)
    return InterAgentEdges(
        PoseKind.SE2,
        np.concatenate(cols["fa"]),
        np.concatenate(cols["fi"]),
        np.concatenate(cols["ta"]),
        np.concatenate(cols["ti"]),
        meas,
        info,
    )


def _diag_information(n: int, position: float, angle: float) -> np.ndarray:
    info = np.zeros((n, 6))
    info[:, 0] = position
    info[:, 3] = position
    info[:, 5] = angle
    return info


def _exact_odometry_information(walk: _Walk, cfg: SynthConfig, agent) -> np.ndarray:
    """kollagen's ``set_information_matrix`` (see its doc/information-matrix-derivation.pdf)."""
    d = cfg.stepsize / cfg.step_fragment
    sd = agent.std_dev_position
    st = agent.std_dev_angle
    d2 = math.pow(d, 2)
    sd2 = math.pow(sd, 2)
    st2 = math.pow(st, 2)
    e1 = (d2 + sd2) / 2.0 * (1 - math.exp(-2 * st2))
    e2 = (d2 + sd2) / 2.0 * (1 + math.exp(-2 * st2)) - d2 * math.exp(-st2)
    a = e1 * st2 - d2 * math.pow(st, 4) * math.exp(-st2)
    c = d * st2 * math.exp(-0.5 * st2)
    rows = {}
    for dt in (-1, 0, 1, 2):
        if dt in (0, 2):
            i23 = c / a
            rows[dt] = (1.0 / e2, 0.0, 0.0, st2 / a, -i23 if dt == 0 else i23, e1 / a)
        else:
            i13 = c / a
            rows[dt] = (st2 / a, 0.0, -i13 if dt == -1 else i13, 1.0 / e2, 0.0, e1 / a)
    table = np.array([rows[k] for k in (-1, 0, 1, 2)])
    return table[walk.delta_theta + 1]


# --------------------------------------------------------------------------------------------------


def generate(cfg: SynthConfig, *, jobs: int | None = None) -> SynthOutput:
    """Run kollagen's generator: walk, intra-agent loop closures, alignment, inter-agent loop closures.

    ``jobs`` processes share the agents and then the agent pairs (default: every core this process
    may use); the output does not depend on it.
    """
    seeds = effective_seeds([a.random_number_generator_seed for a in cfg.agents])

    def one_agent(k: int):
        stream = MT19937Stream(seeds[k])
        walk = _random_walk(stream, cfg, cfg.agents[k])
        return walk, _intra_loop_closures(stream, walk, cfg, cfg.agents[k])

    done = parallel_map(one_agent, len(seeds), jobs)
    walks = [w for w, _ in done]
    intra = [lc for _, lc in done]

    if cfg.align:
        walks = _align(walks)

    cells = [_grid_cells(w.x, w.y, cfg) for w in walks]
    inter = (
        _inter_loop_closures(walks, cells, cfg, jobs) if len(walks) > 1 else InterAgentEdges.empty(PoseKind.SE2)
    )

    agents = []
    exact = []
    for idx, (walk, agent, lcs) in enumerate(zip(walks, cfg.agents, intra)):
        n = len(walk.x)
        c, s = libm_cos_sin(walk.odom_ang)
        odo = np.column_stack([walk.odom_pos * c, walk.odom_pos * s, walk.odom_ang])
        odometry = Edges(
            PoseKind.SE2,
            np.arange(n - 1),
            np.arange(1, n),
            odo.reshape(-1, 3),
            _diag_information(n - 1, agent.estimated_information_position, agent.estimated_information_angle),
        )
        agents.append(
            AgentGraph(
                name=f"agent{idx + 1}",
                kind=PoseKind.SE2,
                stamps_ns=np.arange(n, dtype=np.int64) * NS_PER_S,
                initial=np.column_stack([walk.drx, walk.dry, walk.drtheta]),
                ground_truth=np.column_stack([walk.x, walk.y, walk.theta]),
                odometry=odometry,
                loop_closures=lcs,
            )
        )
        if cfg.exact_information_matrix:
            exact.append(_exact_odometry_information(walk, cfg, agent))

    graph = PoseGraph(PoseKind.SE2, tuple(agents), inter, {"generator": "kollagen", "name": cfg.name})
    p = cfg.inter
    connector = np.array(
        [p.estimated_information_position, 0.0, 0.0, p.estimated_information_position, 0.0,
         p.estimated_information_angle]
    )
    return SynthOutput(graph, tuple(exact) if cfg.exact_information_matrix else None, connector, seeds)


def _align(walks: list[_Walk]) -> list[_Walk]:
    """kollagen's ``align_center_of_masses``: integer shifts (in metres) towards agent 1's centre."""
    def centre(w: _Walk) -> tuple[int, int]:
        n = len(w.x)
        return _round_to_int(_libstdcxx_reduce(w.x) / n), _round_to_int(_libstdcxx_reduce(w.y) / n)

    x0, y0 = centre(walks[0])
    out = []
    for w in walks:
        xc, yc = centre(w)
        sx, sy = x0 - xc, y0 - yc
        if sx == 0 and sy == 0:
            out.append(w)
            continue
        out.append(
            _Walk(w.x + sx, w.y + sy, w.theta, w.delta_theta, w.odom_pos, w.odom_ang,
                  w.drx + sx, w.dry + sy, w.drtheta)
        )
    return out


@dataclass(frozen=True, eq=False)
class SingleG2oView:
    """kollagen's extra: the single g2o file and its two TUM files, in ``OUT/<name>_singleg2o``."""

    connector_information: np.ndarray
    """``(6,)`` information of the edges that chain agents together."""
    exact_odometry_information: tuple[np.ndarray, ...] | None
    """Per agent ``(n-1, 6)`` derived odometry information, or None."""
    suffix: str = "_singleg2o"


class KollagenGenerator:
    """kollagen behind the :class:`~studio.generator.seam.Generator` seam."""

    name = "kollagen"

    def extra_suffixes(self, config: SynthConfig) -> tuple[str, ...]:
        return ("_singleg2o",)

    def generate(self, config: SynthConfig, *, jobs: int | None = None) -> GeneratedDataset:
        out = generate(config, jobs=jobs)
        view = SingleG2oView(out.connector_information, out.exact_odometry_information)
        return GeneratedDataset(out.graph, (view,))


KOLLAGEN = KollagenGenerator()
