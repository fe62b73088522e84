"""Process-level helpers: run independent pieces of work on several cores (forked processes), results in input order.

Agents' random walks and the inter-agent pairs each use their own random stream, so they can run in
any order on any core and still give the same bytes. Work is handed out by index, to this process and to
forked children: the data stays in the parent's memory (copy-on-write), only the results travel back.

Also the allocator tuning of the command line (glibc only; never done on import).
"""

from __future__ import annotations

import contextlib
import ctypes
import mmap
import os
import pickle
import signal
import struct
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any, NoReturn, TypeVar

__all__ = ["parallel_map", "run_team", "default_jobs", "available_cores", "tune_allocator", "release_free_heap"]

T = TypeVar("T")
_TASK: list[tuple[Callable[[int], Any], Any, Any, int]] = []
"""The running map: ``(func, claim counter, finished counter, n_items)`` (:class:`_SharedCounter`);
forked workers see it as it was at the fork."""


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

    The parallel path does more work than one process (forking, a heap and its page faults per
    process: twice the page faults and 5-20 % more CPU time on Multi10000x5 at R = 6 m), which pays
    off only with idle cores; on a machine whose cores are all taken it made ``studio synth`` up to
    1.25x slower than ``--jobs 1`` (benchmarks/bench_busy.py), so there it runs in one process.
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


def _become_worker() -> None:
    """A forked worker's first steps: Ctrl-C reaches the whole process group, but only the parent
    handles it (and stops the workers); SIGTERM (how the parent stops a worker) ends a worker at once,
    whatever handler it inherited; SIGINT, held during the fork, is let through (to be ignored); the
    parent's free heap is given back (see :func:`release_free_heap`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    release_free_heap()


# --------------------------------------------------------------------------------------------------
# Messages between processes: length-prefixed pickles through pipes


_HEADER = struct.Struct("<Q")


def _send(fd: int, obj: Any) -> None:
    """One message through a pipe: its length, then its pickle (made first: a pickling error writes
    nothing)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _send_outcome(fd: int, kind: str, value: Any) -> None:
    """A worker's ``("ok", results)`` or ``("error", exception)``; one that cannot be pickled goes as
    a RuntimeError saying so."""
    try:
        _send(fd, (kind, value))
    except Exception as err:  # noqa: BLE001 - a result or an error that cannot be pickled
        _send(fd, ("error", RuntimeError(f"a worker's result could not be sent back: {err}")))


def _recv(fd: int) -> Any:
    """The next message of :func:`_send` from a pipe; ``_EOF`` if the other end closed it first."""
    head = _read_exactly(fd, _HEADER.size)
    if head is None:
        return _EOF
    body = _read_exactly(fd, _HEADER.unpack(head)[0])
    return _EOF if body is None else pickle.loads(body)


def _read_exactly(fd: int, size: int) -> bytearray | None:
    buf = bytearray(size)
    view, got = memoryview(buf), 0
    while got < size:
        n = os.readv(fd, [view[got:]])
        if n == 0:
            return None
        got += n
    return buf


_EOF = object()


def _raise_here(error: BaseException) -> NoReturn:
    """A worker's error, as if raised here: no traceback or cause from the other process, so the
    caller's one-line handling (e.g. OSError -> OutputError) sees a clean exception."""
    error.__cause__ = None
    raise error.with_traceback(None) from None


def _how_it_ended(status: int) -> str:
    code = os.waitstatus_to_exitcode(status)
    return f"signal {-code}" if code < 0 else f"exit code {code}"


class _LeaderGone(Exception):
    """In a worker: the leader closed its pipe (it stopped the job); the worker just ends."""


class _ErrorSent(Exception):
    """In a worker: its error went to the leader already; the worker just ends."""


# --------------------------------------------------------------------------------------------------
# A team: this process and the workers it forked, linked by pipes


class _Team:
    """This process's view of its workers: the leader (``links`` to each worker: pid, the pipe from
    it, the pipe to it) or a worker (one link to the leader, pid 0). A :func:`parallel_map` forks a
    team for one map; :func:`run_team` forks one for a whole job."""

    def __init__(self, leader: bool, claim: Any, finished: Any, links: list[tuple[int, int, int]]) -> None:
        self.leader, self.claim, self.finished, self.links = leader, claim, finished, links
        self.reaped: set[int] = set()
        self.closed: set[int] = set()

    def fork(self, n_workers: int, child: Callable[[_Team], None]) -> None:
        """Fork up to ``n_workers`` workers, each running ``child`` with its own view of the team
        (``child`` never returns); fewer when no process is to be had (EAGAIN, ENOMEM): the ones
        started do the work."""
        for _ in range(n_workers):
            # Ctrl-C is held from the fork until the worker is on the list (in the worker: until it
            # ignores Ctrl-C; it would otherwise unwind the worker through this caller's code); a
            # Ctrl-C held here reaches this process right after
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                up_r, up_w = os.pipe()
                down_r, down_w = os.pipe()
                try:
                    pid = os.fork()
                except OSError:
                    for fd in (up_r, up_w, down_r, down_w):
                        os.close(fd)
                    return
                if pid == 0:
                    os.close(up_r)
                    os.close(down_w)
                    for _, r, w in self.links:  # the other workers' pipes: their EOF is theirs
                        os.close(r)
                        os.close(w)
                    child(_Team(False, self.claim, self.finished, [(0, down_r, up_w)]))
                os.close(up_w)
                os.close(down_r)
                self.links.append((pid, up_r, down_w))
            finally:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})

    def map(self, func: Callable[[int], T], n_items: int, on_done: Callable[[int, int], None] | None) -> list[T]:
        """One :func:`parallel_map` shared by a running team: every process claims items, the workers
        send their results to the leader, and the leader sends each worker the results it lacks (so
        every process goes on with all of them, as one process would)."""
        if not self.leader:
            on_done = None
        elif on_done is not None:
            on_done(0, n_items)
        report = None if on_done is None else (lambda: on_done(self.finished.value, n_items))
        _TASK.append((func, self.claim, self.finished, n_items))
        try:
            results = _claim_loop(report)
        except BaseException as err:
            if self.leader:
                raise
            _send_outcome(self.links[0][2], "error", err)
            raise _ErrorSent from None
        finally:
            _TASK.clear()
        if self.leader:
            theirs = self.receive(results)
            # every worker is past its claims and waits for the reply: the counters are free again
            self.claim.value = 0
            self.finished.value = 0
            for (_, _, to_worker), own in zip(self.links, theirs):
                _send(to_worker, {i: r for i, r in results.items() if i not in own})
            if on_done is not None:
                on_done(n_items, n_items)
        else:
            _, from_leader, to_leader = self.links[0]
            _send_outcome(to_leader, "ok", results)
            rest = _recv(from_leader)
            if rest is _EOF:
                raise _LeaderGone
            results.update(rest)
        return [results[i] for i in range(n_items)]

    def receive(self, results: dict[int, Any]) -> list[set[int]]:
        """In the leader: each worker's results into ``results`` (the items each sent); a worker's
        error (the first, in worker order) is raised once every worker has been heard."""
        error: BaseException | None = None
        theirs: list[set[int]] = []
        for pid, from_worker, _ in self.links:
            message = _recv(from_worker)
            if message is _EOF:
                _, status = os.waitpid(pid, 0)
                self.reaped.add(pid)
                message = (
                    "error",
                    RuntimeError(f"a worker process ended ({_how_it_ended(status)}) without sending its results"),
                )
            kind, value = message
            if kind == "ok":
                results.update(value)
                theirs.append(set(value))
            elif error is None:
                error = value
        if error is not None:
            _raise_here(error)
        return theirs

    def finish(self) -> None:
        """In the leader, once its work is done: close the pipes to the workers, take any last error
        they sent, and reap them."""
        error: BaseException | None = None
        for pid, from_worker, to_worker in self.links:
            self._close(to_worker)
            message = _recv(from_worker)
            self._close(from_worker)
            if pid in self.reaped:
                continue
            _, status = os.waitpid(pid, 0)
            self.reaped.add(pid)
            if error is not None:
                continue
            if message is not _EOF and message[0] == "error":
                error = message[1]
            elif os.waitstatus_to_exitcode(status) != 0:
                error = RuntimeError(f"a worker process ended ({_how_it_ended(status)})")
        if error is not None:
            _raise_here(error)

    def _close(self, fd: int) -> None:
        self.closed.add(fd)
        os.close(fd)

    def stop(self) -> None:
        """In the leader, after an error or Ctrl-C (or when done): terminate and reap the workers
        still running, close the pipes still open and free the shared counters."""
        live = [pid for pid, _, _ in self.links if pid not in self.reaped]
        for pid in live:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
        for fd in [fd for _, r, w in self.links for fd in (r, w) if fd not in self.closed]:
            self.closed.add(fd)
            with contextlib.suppress(OSError):
                os.close(fd)
        for pid in live:
            self.reaped.add(pid)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)
        for counter in (self.claim, self.finished):
            if isinstance(counter, _SharedCounter):
                counter.close()
        self.claim = self.finished = None


class _SharedCounter:
    """An integer shared with the processes forked after it is made, and its lock: the value in an
    anonymous shared mapping, the lock a pipe holding one token byte (taking the lock reads the
    byte, giving it back writes it). The ``multiprocessing.Value`` it replaces took 13-28 ms of a
    command's serial start-up to import and make (two of them), for a few dozen claims a run.

    ``value`` and :meth:`get_lock` are what the claim loop uses; :meth:`close` (in the process that
    made it, once its workers are gone) frees the mapping and the pipe."""

    def __init__(self) -> None:
        self._map = mmap.mmap(-1, 8)  # MAP_SHARED | MAP_ANONYMOUS: the forked workers see its writes
        self._cell = memoryview(self._map).cast("q")
        self._take, self._give = os.pipe()
        os.write(self._give, b"\0")

    @property
    def value(self) -> int:
        return int(self._cell[0])

    @value.setter
    def value(self, v: int) -> None:
        self._cell[0] = v

    @contextlib.contextmanager
    def get_lock(self) -> Iterator[None]:
        os.read(self._take, 1)  # waits while another process holds the token
        try:
            yield
        finally:
            os.write(self._give, b"\0")

    def close(self) -> None:
        self._cell.release()
        self._map.close()
        os.close(self._take)
        os.close(self._give)


def _shared_counters() -> tuple[_SharedCounter, _SharedCounter]:
    """The claim and finished counters, shared with the processes forked after."""
    return _SharedCounter(), _SharedCounter()


def parallel_map(
    func: Callable[[int], T],
    n_items: int,
    jobs: int | None = None,
    *,
    on_done: Callable[[int, int], None] | None = None,
) -> list[T]:
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

    Within :func:`run_team`, the team's processes share the items instead (``jobs`` is then the
    team's), and every one of them gets every result.
    """
    if _TEAM and _TEAM[0].links and not _TASK:
        return _TEAM[0].map(func, n_items, on_done)
    if _TEAM:
        jobs = 1  # a team of one: every map runs here
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
    team = _Team(True, *_shared_counters(), [])
    _TASK.append((func, team.claim, team.finished, n_items))
    report = None if on_done is None else (lambda: on_done(team.finished.value, n_items))
    try:
        team.fork(jobs - 1, _map_worker)
        results = _claim_loop(report)
        team.receive(results)
        team.finish()
        if on_done is not None:
            on_done(n_items, n_items)
        return [results[i] for i in range(n_items)]
    finally:
        team.stop()
        _TASK.clear()


def _map_worker(team: _Team) -> None:
    """A :func:`parallel_map` worker's whole life: claim items, send ``("ok", results)`` or
    ``("error", exception)`` to the parent, and leave with ``os._exit`` (never returning into the
    caller's code, never running its exit handlers or flushing its buffers)."""
    code = 1
    try:
        _become_worker()
        try:
            outcome: tuple[str, Any] = ("ok", _claim_loop())
        except BaseException as err:  # noqa: BLE001 - any error goes back to the parent
            outcome = ("error", err)
        _send_outcome(team.links[0][2], *outcome)
        code = 0
    finally:
        os._exit(code)


_TEAM: list[_Team] = []
"""The team this process belongs to while its job runs (see :func:`run_team`)."""


def run_team(job: Callable[[bool], T], jobs: int | None = None) -> T:
    """``job(True)`` here, while ``jobs - 1`` forked copies of this process run ``job(False)``.

    Every :func:`parallel_map` the job calls is shared by the team, and each process goes on with all
    its results. So the job must call the same maps in the same order in every process (deterministic
    code does); its other work is done by every process (cheap steps such as a generator's walks),
    and side effects outside the maps' items are the caller's to guard with the flag (True: this
    process, whose result is returned; the copies' results are dropped).

    Forking once, before the job's data exists, instead of once per map: a map's fork shares the
    parent's heap with the child, and every page either then writes afterwards is copied (measured on
    Multi10000x5: 16k page faults in the parent while the files were written, on top of the
    worker's own), and a second map forks again into a cold heap. A team's workers keep their heap
    from map to map; only the results cross, through pipes.

    An error in a worker is raised here (at the map it happened in); on an error or Ctrl-C here the
    workers are terminated and reaped. Without ``fork`` or with one job (or when no fork is to be
    had), ``job(True)`` runs alone and its maps run here; inside a running map or team it runs as
    any code there does.
    """
    if _TEAM or _TASK:
        return job(True)
    jobs = default_jobs() if jobs is None else jobs
    team = _Team(True, None, None, [])  # alone until a worker is forked
    try:
        if jobs > 1 and hasattr(os, "fork"):
            team.claim, team.finished = _shared_counters()
            team.fork(jobs - 1, lambda own: _team_worker(job, own))
        _TEAM.append(team)
        try:
            result = job(True)
        finally:
            _TEAM.clear()
        team.finish()
        return result
    finally:
        team.stop()


def _team_worker(job: Callable[[bool], Any], team: _Team) -> None:
    """A team worker's whole life: ``job(False)``, then ``os._exit`` (an error goes to the leader)."""
    code = 1
    try:
        _become_worker()
        _TEAM.append(team)
        try:
            job(False)
            code = 0
        except (_LeaderGone, _ErrorSent):
            pass
        except BaseException as err:  # noqa: BLE001 - any error goes to the leader
            with contextlib.suppress(BaseException):
                _send_outcome(team.links[0][2], "error", err)
    finally:
        os._exit(code)


_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3


def _libc() -> ctypes.CDLL | None:
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
