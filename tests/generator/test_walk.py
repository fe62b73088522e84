"""The walk's draws and dead reckoning against kollagen's plain loops, bit for bit."""

import math

import numpy as np
import pytest

from studio.generator.rng import MT19937Stream, canonical_doubles
from studio.generator.walk import _dead_reckon, _walk_draws


def _plain_walk_draws(stream: MT19937Stream, n_steps: int, frag: int, retro: bool):
    """kollagen's loop: per step one Lemire integer, then per sub-step one polar round."""
    span = 3 + int(retro)
    threshold = ((1 << 32) - span) % span
    words = stream.words(20 * n_steps * frag + 1000).tolist()
    p = 0

    def uniform() -> float:
        nonlocal p
        value = canonical_doubles(np.array(words[p : p + 2], dtype=np.uint32))[0]
        p += 2
        return float(value)

    turns, n_pos, n_ang = [], [], []
    for _ in range(n_steps):
        while True:
            prod = words[p] * span
            p += 1
            if (prod & 0xFFFFFFFF) >= threshold:
                break
        turns.append((prod >> 32) - 1)
        for _ in range(frag):
            while True:
                x, y = 2.0 * uniform() - 1.0, 2.0 * uniform() - 1.0
                r2 = x * x + y * y
                if 0.0 < r2 <= 1.0:
                    break
            mult = math.sqrt(-2.0 * math.log(r2) / r2)
            n_pos.append(y * mult)
            n_ang.append(x * mult)
    return turns, n_pos, n_ang, p


@pytest.mark.parametrize("spare", [4096, 0])
@pytest.mark.parametrize("trial", range(8))
def test_walk_draws_match_the_plain_loop(trial, spare, monkeypatch):
    # no spare words: the buffer often ends inside a step, which is then drawn again from more words
    monkeypatch.setattr("studio.generator.walk._SPARE_WORDS", spare)
    rng = np.random.default_rng(trial)
    seed = int(rng.integers(0, 2**32))
    n_steps = int(rng.integers(1, 40 if spare == 0 else 1500))
    frag, retro = int(rng.integers(1, 6)), bool(trial % 2)
    stream = MT19937Stream(seed)
    stream.advance(int(rng.integers(0, 5)))  # draws may start at any word
    start = stream.position
    turns, n_pos, n_ang = _walk_draws(stream, n_steps, frag, retro)

    want_turns, want_pos, want_ang, used = _plain_walk_draws(_advanced(seed, start), n_steps, frag, retro)
    assert turns.tolist() == want_turns
    assert set(want_turns) <= set(range(-1, 2 + int(retro)))
    assert n_pos.tolist() == want_pos and n_ang.tolist() == want_ang
    assert stream.position == start + used


def _advanced(seed: int, n_words: int) -> MT19937Stream:
    stream = MT19937Stream(seed)
    stream.advance(n_words)
    return stream


def _plain_dead_reckon(odom_pos, odom_ang):
    x = y = t = 0.0
    xs, ys, ts = [0.0], [0.0], [0.0]
    for op, oa in zip(odom_pos.tolist(), odom_ang.tolist()):
        t = t + oa
        t = t - math.floor((t + math.pi) / (2 * math.pi)) * 2.0 * math.pi
        x = x + op * math.cos(t)
        y = y + op * math.sin(t)
        xs.append(x)
        ys.append(y)
        ts.append(t)
    return xs, ys, ts


@pytest.mark.parametrize("trial", range(6))
def test_dead_reckoning_matches_the_plain_loop(trial):
    rng = np.random.default_rng(trial)
    n = int(rng.integers(1, 3000))
    odom_pos = 0.25 + 0.03 * rng.normal(size=n)
    odom_pos[rng.random(n) < 0.05] = -0.0  # a -0.0 first step must still give x = 0.0
    odom_pos[0] = -0.0 if trial % 2 else odom_pos[0]
    odom_ang = rng.choice([0.0, math.pi / 2, -math.pi / 2, math.pi], n) + 0.03 * rng.normal(size=n)

    x, y, theta = _dead_reckon(odom_pos, odom_ang)

    want_x, want_y, want_t = _plain_dead_reckon(odom_pos, odom_ang)
    assert x.tobytes() == np.array(want_x).tobytes()  # bytes: -0.0 and 0.0 differ
    assert y.tobytes() == np.array(want_y).tobytes()
    assert theta.tobytes() == np.array(want_t).tobytes()
