"""How many processes the parallel path uses when the caller does not say."""

from __future__ import annotations

import pytest

from studio.core import parallel


@pytest.mark.parametrize(("cores", "others", "expected"), [
    (2, 0, 2),   # quiet machine: every core
    (2, 1, 1),   # one core taken
    (2, 5, 1),   # saturated: one process, never zero
    (8, 3, 5),
    (4, None, 4),  # /proc/loadavg unreadable: every core
])
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
