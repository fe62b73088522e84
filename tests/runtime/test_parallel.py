"""How many processes the parallel path uses when the caller does not say."""

from __future__ import annotations

import pytest

from studio.runtime import parallel


@pytest.mark.parametrize(
    ("cores", "others", "expected"),
    [
        (2, 0, 2),  # quiet machine: every core
        (2, 1, 1),  # one core taken
        (2, 5, 1),  # saturated: one process, never zero
        (8, 3, 5),
        (4, None, 4),  # /proc/loadavg unreadable: every core
    ],
)
def test_default_jobs_leaves_busy_cores_alone(monkeypatch, cores, others, expected):
    monkeypatch.setattr(parallel, "available_cores", lambda: cores)
    monkeypatch.setattr(parallel, "_other_runnable", lambda: others)
    assert parallel.default_jobs() == expected


def test_other_runnable_reads_this_machine():
    busy = parallel._other_runnable(samples=3, interval_s=0.0)
    assert busy is None or busy >= 0


def test_parallel_map_results_in_order_for_any_jobs():
    for jobs in (None, 1, 2, 3):
        assert parallel.parallel_map(lambda k: k * k, 7, jobs) == [k * k for k in range(7)]


def test_parallel_map_runs_items_here_and_in_workers():
    import os
    import time

    def where(k: int) -> int:
        time.sleep(0.05)  # long enough that both processes get items, even on a loaded machine
        return os.getpid()

    pids = parallel.parallel_map(where, 20, jobs=2)
    assert os.getpid() in pids  # this process took part
    assert len(set(pids)) == 2  # and exactly one forked worker did the rest


@pytest.mark.skipif(not hasattr(parallel.os, "fork"), reason="no fork here")
def test_every_item_is_claimed_once_and_the_counters_are_freed(tmp_path):
    # the claim counter (a shared mapping locked by a pipe's token byte) hands each item to exactly
    # one process, under contention; maps and teams leave no descriptor behind
    import operator
    import os

    def fds() -> int:
        return len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else 0

    log = tmp_path / "claims.txt"

    def run(k: int) -> int:
        fd = os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
        os.write(fd, b"%d %d\n" % (k, os.getpid()))
        os.close(fd)
        return k

    before = fds()
    for _ in range(20):
        log.unlink(missing_ok=True)
        assert parallel.parallel_map(run, 400, jobs=3) == list(range(400))
        claims = [line.split() for line in log.read_text().splitlines()]
        assert sorted(int(item) for item, _ in claims) == list(range(400))  # each item run once
        negated = parallel.run_team(lambda leader: parallel.parallel_map(operator.neg, 50), jobs=2)
        assert negated == list(range(0, -50, -1))
    assert fds() == before


def test_parallel_map_reports_progress_up_to_the_end():
    seen: list[tuple[int, int]] = []
    parallel.parallel_map(lambda k: k, 9, jobs=2, on_done=lambda d, n: seen.append((d, n)))
    assert seen[0] == (0, 9) and seen[-1] == (9, 9)
    assert all(n == 9 and 0 <= d <= 9 for d, n in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_an_error_stops_every_process_from_claiming_more(tmp_path):
    def item(k: int) -> int:
        if k == 3:
            raise ValueError("item 3 is bad")
        (tmp_path / f"ran{k}").write_text("x")
        return k

    with pytest.raises(ValueError, match="item 3 is bad") as info:
        parallel.parallel_map(item, 400, jobs=2)
    assert info.value.__cause__ is None
    ran = len(list(tmp_path.iterdir()))
    assert ran < 50  # the claims stopped right after it (the pool's 400 items would all have run)
    assert not (tmp_path / "ran3").exists()


def test_a_refused_fork_leaves_the_work_to_this_process(monkeypatch):
    import errno
    import os

    def no_fork():
        raise OSError(errno.EAGAIN, "Resource temporarily unavailable")

    monkeypatch.setattr(os, "fork", no_fork)
    pids = parallel.parallel_map(lambda k: os.getpid(), 6, jobs=3)
    assert pids == [os.getpid()] * 6


def test_a_worker_that_dies_is_reported_in_one_line():
    import os
    import signal

    def item(k: int) -> int:
        if os.getpid() != parent and k >= 0:
            os.kill(os.getpid(), signal.SIGKILL)  # the worker vanishes without a word
        import time

        time.sleep(0.05)
        return k

    parent = os.getpid()
    with pytest.raises(RuntimeError, match=r"^a worker process ended \(signal 9\) without sending its results$"):
        parallel.parallel_map(item, 8, jobs=2)


# --------------------------------------------------------------------------------------------------
# Teams: one fork for a whole job, every map shared


def _two_maps(leader: bool) -> tuple[list[int], list[tuple[int, int]], int]:
    """A job of two maps, the second using every result of the first (as the writes use the graph)."""
    import os
    import time

    def square(k: int) -> int:
        time.sleep(0.02)  # long enough that both processes get items
        return k * k

    first = parallel.parallel_map(square, 12)
    total = sum(first)  # every process must see every result to get this right

    def tagged(k: int) -> tuple[int, int]:
        time.sleep(0.02)
        return total + first[k], os.getpid()

    second = parallel.parallel_map(tagged, 12)
    return first, second, os.getpid()


def test_a_team_shares_every_map_and_gives_each_process_every_result():
    import os

    first, second, pid = parallel.run_team(_two_maps, jobs=2)
    assert pid == os.getpid()  # the job's result is this process's
    assert first == [k * k for k in range(12)]
    total = sum(first)
    assert [v for v, _ in second] == [total + k * k for k in range(12)]  # the worker had all of `first`
    pids = {p for _, p in second}
    assert os.getpid() in pids and len(pids) == 2  # both processes took items of the second map


def test_a_team_of_one_runs_the_job_here():
    import os

    first, second, pid = parallel.run_team(_two_maps, jobs=1)
    assert first == [k * k for k in range(12)]
    assert {p for _, p in second} == {os.getpid()}


def test_only_the_leader_is_told_it_leads(tmp_path):
    def job(leader: bool) -> int:
        import os

        (tmp_path / f"{'leader' if leader else 'worker'}-{os.getpid()}").write_text("x")
        return sum(parallel.parallel_map(lambda k: k, 4))

    assert parallel.run_team(job, jobs=3) == 6
    names = sorted(p.name.split("-")[0] for p in tmp_path.iterdir())
    assert names == ["leader", "worker", "worker"]


def test_a_workers_error_in_a_team_map_is_raised_here():
    import os

    parent = os.getpid()

    def job(leader: bool) -> list[int]:
        def item(k: int) -> int:
            import time

            time.sleep(0.02)
            if os.getpid() != parent:
                raise ValueError(f"item {k} failed in the worker")
            return k

        return parallel.parallel_map(item, 10)

    with pytest.raises(ValueError, match=r"^item \d+ failed in the worker$") as info:
        parallel.run_team(job, jobs=2)
    assert info.value.__cause__ is None


def test_a_team_worker_that_dies_is_reported_in_one_line():
    import os
    import signal

    parent = os.getpid()

    def job(leader: bool) -> list[int]:
        def item(k: int) -> int:
            if os.getpid() != parent:
                os.kill(os.getpid(), signal.SIGKILL)
            import time

            time.sleep(0.05)
            return k

        return parallel.parallel_map(item, 8)

    with pytest.raises(RuntimeError, match=r"^a worker process ended \(signal 9\) without sending its results$"):
        parallel.run_team(job, jobs=2)


def test_an_error_here_stops_the_team(tmp_path):
    import os

    def job(leader: bool) -> None:
        parallel.parallel_map(lambda k: k, 4)
        if leader:
            raise OSError("disk full")
        (tmp_path / f"worker-{os.getpid()}").write_text("waiting")
        parallel.parallel_map(lambda k: k, 4)  # the worker waits here for the leader, in vain

    with pytest.raises(OSError, match="disk full"):
        parallel.run_team(job, jobs=2)
    workers = [int(p.name.split("-")[1]) for p in tmp_path.iterdir()]
    for pid in workers:  # stopped and reaped: no such process any more
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_a_refused_fork_leaves_the_team_job_to_this_process(monkeypatch):
    import errno
    import os

    def no_fork():
        raise OSError(errno.EAGAIN, "Resource temporarily unavailable")

    monkeypatch.setattr(os, "fork", no_fork)
    first, second, pid = parallel.run_team(_two_maps, jobs=3)
    assert first == [k * k for k in range(12)]
    assert {p for _, p in second} == {os.getpid()}


def test_team_workers_end_when_their_leader_is_killed(tmp_path):
    import subprocess
    import sys
    import time

    script = (
        "import os, signal, time\n"
        "from pathlib import Path\n"
        "from studio.runtime import parallel\n"
        f"folder = Path({str(tmp_path)!r})\n"
        "leader = os.getpid()\n"
        "def item(k):\n"
        "    if os.getpid() != leader:\n"
        "        (folder / f'worker-{os.getpid()}').touch()\n"
        "    time.sleep(0.05)\n"
        "    if os.getpid() == leader and k >= 4:\n"
        "        os.kill(leader, signal.SIGKILL)  # the leader dies in the middle of the map\n"
        "    return k\n"
        "parallel.run_team(lambda lead: parallel.parallel_map(item, 40), jobs=2)\n"
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == -9
    workers = {int(p.name.split("-")[1]) for p in tmp_path.iterdir()}
    assert workers  # the worker took items before the leader died
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(pid) for pid in workers):
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in workers)  # it noticed and ended (no orphan left running)


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:  # a zombie (not yet reaped by init) has ended too
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:  # gone meanwhile
        return False
