"""Wall-time bounds that follow the machine's measured speed.

A test that checks a refusal comes quickly (no read of a 2 GB file, no wait on a dead scheduler)
asserts a bound in seconds; CI runs on 2 shared cores whose speed varies several-fold under other
work, so a fixed bound fails on a busy machine. :func:`bound_s` scales a bound chosen on a quiet
machine by how much slower a fixed pure-Python loop runs right now; a hang still fails."""

from __future__ import annotations

import time

#: The reference loop's time on a quiet machine of the project's kind [s].
QUIET_LOOP_S = 0.05


def slowness() -> float:
    """How many times slower than quiet the machine is now (at least 1)."""
    t0 = time.perf_counter()
    total = 0
    for i in range(1_000_000):
        total += i
    return max(1.0, (time.perf_counter() - t0) / QUIET_LOOP_S)


def bound_s(quiet_s: float) -> float:
    """``quiet_s`` [s], a bound chosen on a quiet machine, scaled to the machine's speed now."""
    return quiet_s * slowness()
