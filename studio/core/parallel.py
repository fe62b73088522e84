"""Process-level helpers: run independent pieces of work on several cores (forked processes), results in input order.

Agents' random walks and the inter-agent pairs each use their own random stream, so they can run in
any order on any core and still give the same bytes. Work is handed out by index, to this process and to
forked children: the data stays in the parent's memory (copy-on-write), only the results travel back.

Also the allocator tuning of the command line (glibc only; never done on import).
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import pickle
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
    worker: about 3x the page faults and 5-20 % more CPU time on Multi10000x5 at R = 6 m), which pays
    off only with idle cores; on a machine whose cores are all taken it made ``studio synth`` up to
    1.14x slower than ``--jobs 1`` (benchmarks/bench_busy.py), so there it runs in one process.
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


def _worker(fd: int) -> None:
    """A forked worker's whole life: claim items, send ``("ok", results)`` or ``("error", exception)``
    through the pipe ``fd``, and leave with ``os._exit`` (never returning into the caller's code,
    never running its exit handlers or flushing its buffers)."""
    code = 1
    try:
        # Ctrl-C reaches the whole process group; only the parent handles it (and stops the workers).
        # SIGTERM (how the parent stops a worker) ends a worker at once, whatever handler it inherited.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        release_free_heap()
        try:
            payload: tuple[str, Any] = ("ok", _claim_loop())
        except BaseException as err:  # noqa: BLE001 - any error goes back to the parent
            payload = ("error", err)
        try:
            data = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as err:  # noqa: BLE001 - a result or an error that cannot be pickled
            data = pickle.dumps(("error", RuntimeError(f"a worker's result could not be sent back: {err}")))
        with os.fdopen(fd, "wb") as pipe:
            pipe.write(data)
        code = 0
    finally:
        os._exit(code)


def _stop(workers: list[tuple[int, int]]) -> None:
    """Terminate and reap workers still running and close their pipes (after an error or Ctrl-C here)."""
    for pid, fd in workers:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGTERM)
        if fd >= 0:
            with contextlib.suppress(OSError):
                os.close(fd)
    for pid, _ in workers:
        with contextlib.suppress(ChildProcessError):
            os.waitpid(pid, 0)


def _collect(workers: list[tuple[int, int]], results: dict[int, Any]) -> None:
    """Read each worker's message to its end (a worker exits after writing it), reap it, and add its
    results; a worker's error is raised (the first, in worker order) once every worker is reaped."""
    error: BaseException | None = None
    while workers:
        pid, fd = workers.pop(0)
        try:
            with os.fdopen(fd, "rb") as pipe:
                data = pipe.read()
        except BaseException:
            _stop([(pid, -1)])  # the pipe is closed; the worker may still run
            raise
        _, status = os.waitpid(pid, 0)
        if data:
            kind, value = pickle.loads(data)
        else:
            code = os.waitstatus_to_exitcode(status)
            how = f"signal {-code}" if code < 0 else f"exit code {code}"
            kind, value = "error", RuntimeError(f"a worker process ended ({how}) without sending its results")
        if kind == "ok":
            results.update(value)
        elif error is None:
            error = value
    if error is not None:
        # the worker's error, as if raised here: no traceback or cause from the other process, so the
        # caller's one-line handling (e.g. OSError -> OutputError) sees a clean exception
        error.__cause__ = None
        raise error.with_traceback(None) from None


def parallel_map(func: Callable[[int], T], n_items: int, jobs: int | None = None, *,
                 on_done: Callable[[int, int], None] | None = None) -> list[T]:
    """``[func(0), ..., func(n_items - 1)]``, computed by this process and up to ``jobs - 1`` forked ones.

    Every process claims the next item from a shared counter (items in order, so the long ones put
    first are shared out first). This process takes part: its heap is warm, while a forked worker
    pays a page fault for every fresh page it writes (measured: worker tasks ran up to twice as long
    as the same tasks here). ``on_done(done, n_items)``, if given, is called in this process with the
    number of items finished by all processes: after each of its own items, and at the end.

    Workers are plain forks that send their results back through a pipe (``multiprocessing.Pool``,
    with its helper threads and queues, took about 20 ms per map to start and stop). An item's error
    is raised here as the item raised it; on an error or Ctrl-C here the workers are terminated and
    reaped.
    """
    jobs = default_jobs() if jobs is None else jobs
    jobs = min(jobs, n_items)
    if on_done is not None:
        on_done(0, n_items)
    if jobs <= 1 or not hasattr(os, "fork") or _TASK:
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
    workers: list[tuple[int, int]] = []
    try:
        for _ in range(jobs - 1):
            # Ctrl-C is held from the fork until the worker is on the list (in the worker: until it
            # ignores Ctrl-C; it would otherwise unwind the worker through this caller's code); a
            # Ctrl-C held here reaches this process right after
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                read_fd, write_fd = os.pipe()
                try:
                    pid = os.fork()
                except OSError:  # no process to be had (EAGAIN, ENOMEM): the ones started do the work
                    os.close(read_fd)
                    os.close(write_fd)
                    break
                if pid == 0:
                    os.close(read_fd)
                    _worker(write_fd)
                workers.append((pid, read_fd))
                os.close(write_fd)
            finally:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        results = _claim_loop(report)
        _collect(workers, results)
        if on_done is not None:
            on_done(n_items, n_items)
        return [results[i] for i in range(n_items)]
    finally:
        _stop(workers)
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
