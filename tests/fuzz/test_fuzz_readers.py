"""The fuzzing entry point, bounded for CI's slow profile (``pytest --runslow``): about 30 s in all."""

from __future__ import annotations

import pytest

from tests.fuzz.fuzz_readers import MULTI, READERS, fuzz


@pytest.mark.slow
def test_readers_survive_30_seconds_of_fuzzing():
    report = fuzz(30.0)
    assert set(report.tried) == {*READERS, MULTI}
    assert all(n > 0 for n in report.tried.values()), report.tried
    assert not report.failures, "\n".join(
        f"{f.reader}: {f.error} [{f.where}] input {f.data[:300]!r}" for f in report.distinct.values()
    )


def test_fuzzer_counts_and_catches_a_broken_reader(monkeypatch):
    """A quick check of the harness itself: a reader that raises a bare ValueError is a failure."""
    from tests.fuzz import fuzz_readers

    def broken(path):
        raise ValueError("boom")

    monkeypatch.setitem(
        fuzz_readers.READERS, "tum", fuzz_readers.Target("tum", broken, (b"x",), fuzz_readers.tum_texts)
    )
    report = fuzz(0.5, seed=3, readers=["tum"])
    assert report.tried["tum"] > 0
    assert len(report.failures) == report.tried["tum"]
    assert all(f.where.startswith("ValueError at test_fuzz_readers.py:") for f in report.failures)
