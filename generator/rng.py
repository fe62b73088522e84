"""Bit-exact replicas of the random draws kollagen makes with libstdc++.

kollagen draws from ``std::mt19937`` through three libstdc++ distributions. numpy's legacy
``RandomState`` is the same Mersenne Twister with the same integer seeding, and its raw 32-bit words
are reachable through the public ``randint(0, 2**32, dtype=uint32)``. On top of the words:

* ``uniform_real_distribution<double>(0, 1)`` (``generate_canonical``): two words ``a, b`` give
  ``(a + b * 2**32) / 2**64``; a result ``>= 1`` becomes the largest double below 1.
* ``normal_distribution<double>``: Marsaglia's polar method on two such uniforms, rejecting while
  ``r2 > 1 or r2 == 0``; returns ``y * m`` and caches ``x * m`` for the next call.
* ``uniform_int_distribution<int>(a, b)``: Lemire's multiply-shift on one word with rejection of the
  biased low products.

Every draw of a uniform or a normal consumes an even number of words, so once a phase starts (after
the integer draws of the random walk) the uniforms can be decoded in bulk as a numpy array.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["MT19937Stream", "UniformTape", "canonical_doubles", "polar_normal"]

_TWO32 = 4294967296.0
_TWO64 = 18446744073709551616.0
_BELOW_ONE = math.nextafter(1.0, 0.0)
_BLOCK_WORDS = 1 << 12
"""The fewest words a stream draws at a time (its readers ask for what they expect to need)."""

_FREE_STATES: list[np.random.RandomState] = []
"""Generators handed back by :meth:`MT19937Stream.release`, for the next streams of this process:
re-seeding one is much cheaper than making one (numpy gathers entropy for a new one first, then
seeds it again), and a small dataset needs four."""


def canonical_doubles(words: np.ndarray, *, every_offset: bool = False) -> np.ndarray:
    """Decode word pairs into ``generate_canonical<double, 53>`` values.

    By default the pairs are consecutive and disjoint (words 0-1, 2-3, ...); with ``every_offset``
    value ``k`` is decoded from words ``k, k+1``, for a stream whose draws may start at any word.
    """
    if every_offset:
        lo, hi = words[:-1], words[1:]
    else:
        lo, hi = words[0::2], words[1::2]
    out = hi.astype(np.float64)
    out *= _TWO32  # exact (a power of two)
    out += lo  # one rounding, as libstdc++'s sum
    out *= 1.0 / _TWO64  # exact: a power of two, and no result is subnormal
    np.minimum(out, _BELOW_ONE, out=out)
    return out


def polar_normal(uniforms: Sequence[float] | memoryview | np.ndarray, q: int) -> tuple[float, float, int]:
    """One round of libstdc++'s polar method starting at uniform index ``q``.

    Returns ``(returned, cached, next_q)``: the value the call returns, the value it keeps for the next
    call, and the index of the next unused uniform.
    """
    while True:
        x = 2.0 * uniforms[q] - 1.0
        y = 2.0 * uniforms[q + 1] - 1.0
        q += 2
        r2 = x * x + y * y
        if not (r2 > 1.0 or r2 == 0.0):
            break
    mult = math.sqrt(-2.0 * math.log(r2) / r2)
    return y * mult, x * mult, q


class MT19937Stream:
    """The 32-bit word stream of ``std::mt19937(seed)``, read forward with a cursor.

    ``seed`` is converted the way C++ converts an ``int`` to the engine's ``result_type`` and then
    reduces it modulo 2**32, so negative seeds behave as in kollagen.
    """

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)
        # RandomState.seed(s) is RandomState(s)'s own seeding (init_genrand), whatever the state held
        self._state: np.random.RandomState | None = _FREE_STATES.pop() if _FREE_STATES else np.random.RandomState(0)
        self._state.seed(self.seed % (1 << 32))
        self._words = np.empty(0, dtype=np.uint32)
        self._start = 0  # stream index of self._words[0]
        self.position = 0  # stream index of the next unread word

    def _ensure(self, end: int) -> None:
        have = self._start + len(self._words)
        if end <= have:
            return
        if self._state is None:
            raise RuntimeError("MT19937Stream: words asked for after release()")
        if self.position > have:  # advanced past the words drawn (another reader of the stream read them)
            self._state.randint(0, 1 << 32, size=self.position - have, dtype=np.uint32)
            self._words, self._start, have = self._words[:0], self.position, self.position
        need = max(end - have, _BLOCK_WORDS)
        fresh = self._state.randint(0, 1 << 32, size=need, dtype=np.uint32)
        keep = self._words[self.position - self._start :]
        self._start = self.position
        self._words = np.concatenate([keep, fresh]) if len(keep) else fresh

    def words(self, n: int) -> np.ndarray:
        """The next ``n`` words, without moving the cursor."""
        self._ensure(self.position + n)
        i = self.position - self._start
        return self._words[i : i + n]

    def advance(self, n_words: int) -> None:
        self.position += n_words

    def forget_read(self) -> None:
        """Drop the words before the cursor (they can no longer be read)."""
        keep = self._words[self.position - self._start :]
        self._words = keep.copy() if len(keep) else np.empty(0, dtype=np.uint32)
        self._start = self.position

    def release(self) -> None:
        """Hand the generator back for the next stream of this process; the words already drawn can
        still be read, no new ones drawn."""
        if self._state is not None:
            _FREE_STATES.append(self._state)
            self._state = None

    def uniforms(self, n: int) -> np.ndarray:
        """The next ``n`` canonical doubles (``2 n`` words), without moving the cursor."""
        return canonical_doubles(self.words(2 * n))


class UniformTape:
    """The canonical doubles of a stream from its current word on, decoded once and kept.

    The tape reads the stream's words without moving its cursor (a reader that goes on drawing
    advances the stream by two words per uniform it used), unless it ``owns`` the stream: then it
    moves the cursor past the words it decoded and the stream drops them (half the memory of a long
    tape). kollagen restarts its inter-agent generator with the same seed for every pair of agents,
    so every pair reads the same uniforms: one tape serves them all.
    """

    def __init__(self, stream: MT19937Stream, *, owns: bool = False) -> None:
        self._stream = stream
        self._owns = owns
        self._values = np.empty(0)

    def head(self, n: int) -> np.ndarray:
        """The tape's first ``n`` uniforms or more (it at least doubles when it grows)."""
        have = len(self._values)
        if n > have:
            n = max(n, 2 * have)
            if self._owns:  # the stream's cursor is at the tape's end
                fresh = canonical_doubles(self._stream.words(2 * (n - have)))
                self._stream.advance(2 * (n - have))
                self._stream.forget_read()
            else:
                fresh = canonical_doubles(self._stream.words(2 * n)[2 * have :])
            self._values = np.concatenate([self._values, fresh]) if have else fresh
        return self._values
