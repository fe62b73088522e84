"""kollagen's random walk: turns and odometry noise in its draw order, positions by integer sums.

Each agent's ``mt19937`` gives, per step, one integer (the turn) and then, per sub-step, a position
and an angle normal; positions and headings are built with integer cumulative sums and the dead
reckoning follows kollagen's floating-point order (libm through :mod:`math`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from studio.core.geometry import normalize_angle
from studio.generator.config import AgentConfig, SynthConfig
from studio.generator.rng import MT19937Stream, canonical_doubles

__all__ = ["Walk", "random_walk"]


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


def _random_walk(stream: MT19937Stream, cfg: SynthConfig, agent: AgentConfig) -> _Walk:
    frag, stepsize = cfg.step_fragment, cfg.stepsize
    turns, npos, nang = _walk_draws(stream, cfg.number_of_steps, frag, cfg.allow_retrocession)
    # heading in quarter turns, with C's truncating %
    theta_int_steps = np.empty(len(turns), dtype=np.int64)
    t = 0
    for s, d in enumerate(turns.tolist()):
        t = int(math.fmod(t + d, 4))
        theta_int_steps[s] = t
    theta_int = np.repeat(theta_int_steps, frag)
    lut = range(-3, 4)
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


Walk = _Walk
random_walk = _random_walk
