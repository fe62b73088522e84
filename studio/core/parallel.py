"""Process-level helpers: run independent pieces of work on several cores (forked processes), results in input order.

Agents' random walks and the inter-agent pairs each use their own random stream, so they can run in
any order on any core and still give the same bytes. Work is handed out by index, to this process and to
forked children: the data stays in the parent's memory (copy-on-write), only the results travel back.

Also the allocator tuning of the command line (glibc only; never done on import).
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import time
from typing import Any, Callable, TypeVar

__all__ = ["parallel_map", "default_jobs", "available_cores", "tune_allocator", "release_free_heap"]

T = TypeVar("T")
_TASK: list[tuple[Callable[[int], Any], Any, Any, int]] = []
"""The running map: ``(func, claim counter, finished counter, n_items)`` (shared counters of
``multiprocessing.Value``); forked workers see it as it was at the fork."""


def available_cores() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _other_runnable(samples: int = 3, interval_s: float = 0.001) -> int | None:
    """How many other tasks are running or waiting for a CPU right now (the median of a few readings
    of ``/proc/loadavg``'s runnable count, less this process), or None where it cannot be read."""
    counts = []
    for k in range(samples):
        try:
            with open("/proc/loadavg", encoding="ascii") as f:
                counts.append(int(f.read().split()[3].split("/")[0]) - 1)
        except (OSError, ValueError, IndexError):
            return None
        if k + 1 < samples:
            time.sleep(interval_s)
    return sorted(counts)[len(counts) // 2]


def default_jobs() -> int:
    """The processes to use when the caller does not say: the cores this process may use, less those
    other tasks keep busy right now (at least 1).

    The parallel path does more work than one process (forking, copy-on-write and fresh pages in the
    worker: about 3x the page faults and +20-25 % CPU time on Multi10000x5 at R = 6 m), which pays
    off only with idle cores; on a machine whose cores are all taken it made ``studio synth`` up to
    1.2x slower than ``--jobs 1`` (benchmarks/bench_busy.py), so there it runs in one process.
    """
    cores = available_cores()
    busy = _other_runnable()
    return cores if busy is None else max(1, min(cores, cores - busy))


def _claim_loop(report: Callable[[], None] | None = None) -> dict[int, Any]:
    """Run items until none is left, claiming each from the shared counter; ``{item: result}``.

    Runs in the calling process (with ``report``, called after each of its items) and in each worker
    alike. An item that raises stops every process from claiming more (the counter jumps to the end)
    before the error goes up.
    """
    func, claim, finished, n_items = _TASK[0]
    results: dict[int, Any] = {}
    while True:
        with claim.get_lock():
            index = claim.value
            claim.value = index + 1
        if index >= n_items:
            return results
        try:
            results[index] = func(index)
        except BaseException:
            with claim.get_lock():
                claim.value = n_items
            raise
        with finished.get_lock():
            finished.value += 1
        if report is not None:
            report()


def _worker_init() -> None:
    # Ctrl-C reaches the whole process group; only the parent handles it (and terminates the
    # workers), otherwise a worker interrupted while holding the pool's queue lock can hang it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    release_free_heap()


def parallel_map(func: Callable[[int], T], n_items: int, jobs: int | None = None, *,
                 on_done: Callable[[int, int], None] | None = None) -> list[T]:
    """``[func(0), ..., func(n_items - 1)]``, computed by this process and up to ``jobs - 1`` forked ones.

    Every process claims the next item from a shared counter (items in order, so the long ones put
    first are shared out first). This process takes part: its heap is warm, while a forked worker
    pays a page fault for every fresh page it writes (measured: worker tasks ran up to twice as long
    as the same tasks here). ``on_done(done, n_items)``, if given, is called in this process with the
    number of items finished by all processes: after each of its own items, and at the end.
    """
    jobs = default_jobs() if jobs is None else jobs
    jobs = min(jobs, n_items)
    if on_done is not None:
        on_done(0, n_items)
    if jobs <= 1 or "fork" not in multiprocessing.get_all_start_methods() or _TASK:
        out = []
        for i in range(n_items):
            out.append(func(i))
            if on_done is not None:
                on_done(i + 1, n_items)
        return out
    ctx = multiprocessing.get_context("fork")
    finished = ctx.Value("q", 0)
    _TASK.append((func, ctx.Value("q", 0), finished, n_items))
    report = None if on_done is None else (lambda: on_done(finished.value, n_items))
    try:
        with ctx.Pool(jobs - 1, initializer=_worker_init) as pool:
            pending = [pool.apply_async(_claim_loop) for _ in range(jobs - 1)]
            results = _claim_loop(report)
            try:
                for p in pending:
                    results.update(p.get())
            except Exception as err:
                # the worker's error, as if raised here: no RemoteTraceback chained to it, so the
                # caller's one-line handling (e.g. OSError -> OutputError) sees a clean exception
                err.__cause__ = None
                raise err.with_traceback(None) from None
        if on_done is not None:
            on_done(n_items, n_items)
        return [results[i] for i in range(n_items)]
    finally:
        _TASK.clear()

_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3


def _libc():
    """glibc, or None where it cannot be loaded (not Linux, or another C library)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        # the symbols already loaded into this process (glibc's among them); find_library would run
        # `ldconfig -p` in a subprocess, a few milliseconds in every forked worker
        return ctypes.CDLL(None)
    except OSError:
        return None


def release_free_heap() -> None:
    """Give free heap pages back to the kernel (glibc's ``malloc_trim``).

    Called in forked workers: reusing the parent's free chunks would copy each page on first write
    (copy-on-write) instead of mapping a fresh zero page.
    """
    libc = _libc()
    if libc is not None and hasattr(libc, "malloc_trim"):
        libc.malloc_trim(0)


def tune_allocator() -> bool:
    """Let glibc keep freed memory for reuse instead of returning it to the kernel at once.

    The generator makes many short-lived arrays of a few MB. By default glibc serves each from a fresh
    ``mmap`` and unmaps it on free, so every array pays page faults again: measured on Multi3500x8,
    1.1 s of system time instead of 0.3 s. Returns whether the tuning was applied (glibc only).
    """
    libc = _libc()
    if libc is None or not hasattr(libc, "mallopt"):
        return False
    mallopt = libc.mallopt
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    ok = mallopt(_M_MMAP_THRESHOLD, 1 << 30)
    ok &= mallopt(_M_TRIM_THRESHOLD, 1 << 30)
    ok &= mallopt(_M_TOP_PAD, 64 << 20)
    return bool(ok)
