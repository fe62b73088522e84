"""kollagen's random walk: turns and odometry noise in its draw order, positions by integer sums.

Each agent's ``mt19937`` gives, per step, one integer (the turn) and then, per sub-step, a position
and an angle normal; positions and headings are built with integer cumulative sums and the dead
reckoning follows kollagen's floating-point order (libm through :mod:`math`). Where the studio was
installed with a C compiler the draws, the walk and the dead-reckoned headings are compiled
(generator/_sampler.c: ``walk``, ``trajectory``, ``headings``), with the same bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from studio.core.geometry import libm_cos_sin, normalize_angle
from studio.generator.config import AgentConfig, SynthConfig
from studio.generator.rng import MT19937Stream, canonical_doubles

try:  # the compiled draws and headings (generator/_sampler.c, built at install where a C compiler is found)
    from studio.generator._sampler import headings as _compiled_headings
    from studio.generator._sampler import trajectory as _compiled_trajectory
    from studio.generator._sampler import walk as _compiled_walk
except ImportError:  # no compiler at install: numpy and Python (the same bytes; tests run both)
    _compiled_walk = None  # type: ignore[assignment]
    _compiled_headings = None  # type: ignore[assignment]
    _compiled_trajectory = None  # type: ignore[assignment]

__all__ = ["Walk", "random_walk"]


def _round_half_away(v: np.ndarray) -> np.ndarray:
    """C's ``round``: half away from zero (numpy's ``round`` goes half to even)."""
    t = np.trunc(v)
    frac = v - t
    rounded: np.ndarray = (t + np.where(np.abs(frac) >= 0.5, np.sign(v), 0.0)).astype(np.int64)
    return rounded


def _round_to_int(v: float) -> int:
    t = math.trunc(v)
    if abs(v - t) >= 0.5:
        t += 1 if v > 0 else -1
    return int(t)


def _quarter_angle_table() -> dict[int, tuple[float, float, float]]:
    """theta_int -> (theta as kollagen stores it, cos, sin), for theta_int in -3..3."""
    table = {}
    for k in range(-3, 4):
        th = normalize_angle(k * 0.5 * math.pi)
        table[k] = (th, math.cos(th), math.sin(th))
    return table


_QUARTER = _quarter_angle_table()

#: per quarter-turn heading -3..3 (index + 3): kollagen's stored angle and its unit step in cells
_TH_TAB = np.array([_QUARTER[k][0] for k in range(-3, 4)])
_DX_TAB = np.array([_round_to_int(_QUARTER[k][1]) for k in range(-3, 4)], dtype=np.int64)
_DY_TAB = np.array([_round_to_int(_QUARTER[k][2]) for k in range(-3, 4)], dtype=np.int64)
#: per turn -1..2 (index + 1): the turn's angle as kollagen writes it in the odometry
_TURN_ANGLE = np.array([normalize_angle(k * 0.5 * math.pi) for k in range(-1, 3)])
for _table in (_TH_TAB, _DX_TAB, _DY_TAB, _TURN_ANGLE):
    _table.setflags(write=False)

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


_SPARE_WORDS = 512
"""Words :func:`_walk_draws` reads beyond its estimate (about 5.1 words per sub-step) before it has to
read more."""


def _walk_draws(
    stream: MT19937Stream, n_steps: int, frag: int, retro: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Turns and odometry normals in kollagen's draw order; leaves the stream after the last draw.

    Each step draws one integer (``uniform_int_distribution(-1, 1 + retro)``, Lemire's method) and
    then, per sub-step, a position normal and an angle normal: one polar-method round whose tries
    read the uniforms at words ``p`` and ``p + 2`` for any word offset ``p``. Whether a try is accepted
    is decided for every offset at once, and so is the next accepted try of each offset (tries of a
    round are 4 words apart); the walk through the words then only follows integers in Python, and
    the normals of the accepted tries are computed in bulk (libm's log through :mod:`math`).
    """
    if _compiled_walk is not None and stream.position == 0:  # the kernel reads the stream from its start
        turns_b, pos_b, ang_b, used = _compiled_walk(stream.seed, n_steps, frag, retro)
        stream.advance(used)
        return (
            np.frombuffer(turns_b, dtype=np.int64),
            np.frombuffer(pos_b, dtype=np.float64),
            np.frombuffer(ang_b, dtype=np.float64),
        )
    span = 3 + int(retro)
    threshold = ((1 << 32) - span) % span
    turns: list[int] = []
    n_pos: list[np.ndarray] = []
    n_ang: list[np.ndarray] = []
    log = math.log
    want = n_steps + 6 * n_steps * frag + _SPARE_WORDS
    while len(turns) < n_steps:
        words = stream.words(want)
        u = canonical_doubles(words, every_offset=True)
        x = 2.0 * u[:-2] - 1.0  # the try at word p
        y = 2.0 * u[2:] - 1.0
        r2 = x * x + y * y
        # the first accepted try at or after each offset, among the offsets 4k words further on
        # (past the buffer's end: an offset no word can be read at)
        nxt = np.where((r2 <= 1.0) & (r2 != 0.0), np.arange(len(r2)), len(words))
        for r in range(4):
            nxt[r::4] = np.minimum.accumulate(nxt[r::4][::-1])[::-1]
        wv, nv = words.data, nxt.data
        accepted: list[int] = []
        p = 0
        try:
            while len(turns) < n_steps:
                start = p
                prod = wv[p] * span
                p += 1
                while (prod & 0xFFFFFFFF) < threshold:
                    prod = wv[p] * span
                    p += 1
                tries = []
                for _ in range(frag):
                    tries.append(nv[p])
                    p = tries[-1] + 4
                if p > len(words):
                    raise IndexError  # the last round has no accepted try in this buffer
                accepted += tries
                turns.append((prod >> 32) - 1)
        except IndexError:  # the buffer ended inside a step: redo that step with more words
            p = start
        at = np.array(accepted, dtype=np.int64)
        r2_at = r2[at]
        mult = np.sqrt(-2.0 * np.fromiter(map(log, r2_at.tolist()), dtype=np.float64, count=len(r2_at)) / r2_at)
        n_pos.append(y[at] * mult)
        n_ang.append(x[at] * mult)
        stream.advance(p)
        want *= 2
    return np.array(turns, dtype=np.int64), np.concatenate(n_pos), np.concatenate(n_ang)


def _random_walk(stream: MT19937Stream, cfg: SynthConfig, agent: AgentConfig) -> _Walk:
    frag, stepsize = cfg.step_fragment, cfg.stepsize
    turns, npos, nang = _walk_draws(stream, cfg.number_of_steps, frag, cfg.allow_retrocession)
    if _compiled_trajectory is not None:
        cols = _compiled_trajectory(
            np.ascontiguousarray(turns, dtype=np.int64),
            np.ascontiguousarray(npos, dtype=np.float64),
            np.ascontiguousarray(nang, dtype=np.float64),
            frag,
            float(stepsize),
            float(agent.std_dev_position),
            float(agent.std_dev_angle),
            _TH_TAB,
            _DX_TAB,
            _DY_TAB,
            _TURN_ANGLE,
        )
        x, y, theta, odom_pos, odom_ang = (np.frombuffer(cols[i], dtype=np.float64) for i in (0, 1, 2, 4, 5))
        return _Walk(x, y, theta, np.frombuffer(cols[3], dtype=np.int64), odom_pos, odom_ang)
    # heading in quarter turns, with C's truncating %
    theta_int_steps = np.empty(len(turns), dtype=np.int64)
    t = 0
    for s, d in enumerate(turns.tolist()):
        t = int(math.fmod(t + d, 4))
        theta_int_steps[s] = t
    theta_int = np.repeat(theta_int_steps, frag)
    th_tab, dx_tab, dy_tab = _TH_TAB, _DX_TAB, _DY_TAB
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
    turn_angle = _TURN_ANGLE[delta_theta + 1]
    noise_ang = agent.std_dev_angle * nang
    odom_ang = np.where(first, turn_angle + noise_ang, noise_ang)
    return _Walk(x, y, theta, delta_theta, odom_pos, odom_ang)


def _dead_reckon(odom_pos: np.ndarray, odom_ang: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """kollagen's dead reckoning from the origin: the heading is wrapped after every step (a recurrence,
    run in Python); the positions are running sums, which numpy adds in kollagen's order.

    Only the initial estimate needs it (loop closures use the ground truth and the odometry), so
    the generator runs it in each agent's task, on any core, instead of before them."""
    if _compiled_headings is not None:
        theta_b, cos_b, sin_b = _compiled_headings(np.ascontiguousarray(odom_ang, dtype=np.float64))
        theta = np.frombuffer(theta_b, dtype=np.float64)
        c, s = np.frombuffer(cos_b, dtype=np.float64), np.frombuffer(sin_b, dtype=np.float64)
    else:
        floor, pi, two_pi = math.floor, math.pi, 2 * math.pi
        ts = [0.0] * (len(odom_ang) + 1)
        t = 0.0
        for k, oa in enumerate(odom_ang.tolist(), start=1):
            t = t + oa
            t = t - floor((t + pi) / two_pi) * 2.0 * pi
            ts[k] = t
        theta = np.array(ts)
        c, s = libm_cos_sin(theta[1:])
    # 0.0 first, so the first position is 0.0 + step as in kollagen (a -0.0 step gives 0.0)
    x = np.cumsum(np.concatenate([[0.0], odom_pos * c]))
    y = np.cumsum(np.concatenate([[0.0], odom_pos * s]))
    return x, y, theta


Walk = _Walk
random_walk = _random_walk
