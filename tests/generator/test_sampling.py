"""The loop-closure sampler against a plain hit-by-hit loop, on random hits and real uniforms."""

import math
import os

import numpy as np
import pytest

from studio.generator import loop_closures
from studio.generator.loop_closures import _sample
from studio.generator.rng import MT19937Stream, UniformTape


@pytest.fixture(autouse=True, params=["compiled", "python"])
def sampler(request, monkeypatch):
    """Every test runs on the compiled kernel and on the Python sampler it replaces."""
    if request.param == "python":
        monkeypatch.setattr(loop_closures, "_compiled_sample", None)
    elif loop_closures._compiled_sample is None:
        pytest.skip("the compiled sampler was not built (no C compiler at install)")
    return request.param


@pytest.mark.skipif(not os.environ.get("CI"), reason="only CI's install must have built the kernel")
def test_ci_built_the_compiled_sampler():
    import importlib

    assert callable(importlib.import_module("studio.generator._sampler").sample)


def _polar(u: list[float], q: int) -> tuple[float, float, int]:
    while True:
        x, y = 2.0 * u[q] - 1.0, 2.0 * u[q + 1] - 1.0
        q += 2
        r2 = x * x + y * y
        if 0.0 < r2 <= 1.0:
            mult = math.sqrt(-2.0 * math.log(r2) / r2)
            return y * mult, x * mult, q


def _plain_sample(u: list[float], probs: list[float], cached: float | None):
    """kollagen's loop: one uniform per hit; an accepted hit draws three normals."""
    q, accepted, normals = 0, [], []
    for h, p in enumerate(probs):
        q += 1
        if not p > u[q - 1]:
            continue
        accepted.append(h)
        for _ in range(3):
            if cached is None:
                value, cached, q = _polar(u, q)
            else:
                value, cached = cached, None
            normals.append(value)
    return accepted, normals, cached, q


@pytest.mark.parametrize("trial", range(12))
def test_sample_matches_the_plain_loop(trial):
    rng = np.random.default_rng(trial)
    n = int(rng.integers(1, 30_000))
    likely = rng.random(n) < rng.choice([0.0, 0.003, 0.02, 0.3])
    probs = np.where(likely, rng.choice([0.5, 0.8, 1.0, 1.5], n), rng.random(n) * rng.choice([0.001, 0.05, 0.3]))
    cached = None if trial % 2 == 0 else float(rng.normal())
    seed = int(rng.integers(-(2**31), 2**31))
    u = UniformTape(MT19937Stream(seed)).head(5 * n + 10_000).tolist()
    want_acc, want_normals, want_cached, want_used = _plain_sample(u, probs.tolist(), cached)

    acc, normals, left, used = _sample(UniformTape(MT19937Stream(seed)), probs, cached)

    assert acc.tolist() == want_acc
    assert normals.shape == (len(want_acc), 3)
    assert normals.ravel().tolist() == want_normals  # bit for bit
    assert left == want_cached
    assert used == want_used


def test_sample_shares_a_tape_between_calls():
    # kollagen's inter-agent pairs each restart the same seed: one tape, read from its start each time
    tape = UniformTape(MT19937Stream(2710))
    probs = np.full(3000, 0.02)
    probs[::50] = 0.9
    first = _sample(tape, probs, None)
    second = _sample(tape, probs[:1000], None)
    fresh = _sample(UniformTape(MT19937Stream(2710)), probs[:1000], None)
    assert len(fresh[0]) > 10
    assert second[0].tolist() == fresh[0].tolist() == first[0][: len(fresh[0])].tolist()
    assert np.array_equal(second[1], fresh[1])


class _CountingTape(UniformTape):
    def __init__(self, stream):
        super().__init__(stream)
        self.asked: list[int] = []

    def head(self, n):
        self.asked.append(n)
        return super().head(n)


def test_sample_grows_its_buffer_and_resumes(monkeypatch):
    # no spare uniforms: three sure hits need more than the estimate of four uniforms each as soon as
    # the polar method rejects a pair, and the sampler must go on from its last accepted hit
    monkeypatch.setattr("studio.generator.loop_closures._SPARE_UNIFORMS", 0)
    grown = 0
    for seed in range(40):
        u = UniformTape(MT19937Stream(seed)).head(100).tolist()
        want = _plain_sample(u, [1.0, 0.0, 1.0, 1.0], None)
        tape = _CountingTape(MT19937Stream(seed))
        acc, normals, left, used = _sample(tape, np.array([1.0, 0.0, 1.0, 1.0]), None)
        assert (acc.tolist(), normals.ravel().tolist(), left, used) == want
        grown += len(tape.asked) > 1
    assert grown > 0


def test_uniform_tape_grows_without_moving_the_stream():
    stream = MT19937Stream(7)
    tape = UniformTape(stream)
    small = tape.head(10).copy()
    big = tape.head(200_000)
    assert len(big) >= 200_000 and np.array_equal(big[:10], small)
    assert stream.position == 0
    assert big[150_000] == UniformTape(MT19937Stream(7)).head(150_001)[150_000]


def test_a_tape_that_owns_its_stream_reads_the_same_uniforms_and_keeps_no_words():
    plain = UniformTape(MT19937Stream(7))
    stream = MT19937Stream(7)
    owned = UniformTape(stream, owns=True)
    for n in (10, 1000, 70_000, 150_001):  # growing past the stream's block of 65,536 words
        assert np.array_equal(owned.head(n)[:n], plain.head(n)[:n])
    got = len(owned.head(1))
    assert stream.position == 2 * got  # the cursor sits at the tape's end
    assert len(stream.words(0)) == 0 and stream._words.size < 65_536  # the decoded words are gone
