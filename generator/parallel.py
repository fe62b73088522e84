"""Run independent pieces of work on several cores (forked processes), results in input order.

Agents' random walks and the inter-agent pairs each use their own random stream, so they can run in
any order on any core and still give the same bytes. Work is handed to forked children by index: the
data stays in the parent's memory (copy-on-write), only the results travel back.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from typing import Callable, TypeVar

from studio.runtime import release_free_heap

__all__ = ["parallel_map", "default_jobs"]

T = TypeVar("T")
_TASK: list[Callable[[int], object]] = []


def default_jobs() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _run(index: int):
    return _TASK[0](index)


def _worker_init() -> None:
    # Ctrl-C reaches the whole process group; only the parent handles it (and terminates the
    # workers), otherwise a worker interrupted while holding the pool's queue lock can hang it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    release_free_heap()


def parallel_map(func: Callable[[int], T], n_items: int, jobs: int | None = None) -> list[T]:
    """``[func(0), ..., func(n_items - 1)]``, computed by up to ``jobs`` forked processes."""
    jobs = default_jobs() if jobs is None else jobs
    jobs = min(jobs, n_items)
    if jobs <= 1 or "fork" not in multiprocessing.get_all_start_methods() or _TASK:
        return [func(i) for i in range(n_items)]
    _TASK.append(func)
    try:
        ctx = multiprocessing.get_context("fork")
        with ctx.Pool(jobs, initializer=_worker_init) as pool:
            return pool.map(_run, range(n_items), chunksize=1)
    finally:
        _TASK.clear()
