"""Closing a recording whose writer is stuck (a full disk) ends in one OutputError and never calls
``disconnect`` (which waits forever on a stuck sink: seen hanging `studio record` in CI)."""

from __future__ import annotations

import pytest

from studio.core.errors import OutputError
from studio.recording import sink


class _Stuck:
    """A RecordingStream stand-in whose flush never completes."""

    def __init__(self, grow_first: int = 0, target=None) -> None:
        self.flushes = 0
        self.disconnected = False
        self.grow_first = grow_first
        self.target = target

    def flush(self, *, timeout_sec: float) -> None:
        self.flushes += 1
        if self.target is not None and self.flushes <= self.grow_first:
            with open(self.target, "ab") as f:  # the writer still makes progress
                f.write(b"x")
        raise RuntimeError("flush timed out\nmore detail")

    def disconnect(self) -> None:
        self.disconnected = True


class _Fine(_Stuck):
    def flush(self, *, timeout_sec: float) -> None:
        self.flushes += 1


@pytest.fixture
def quick(monkeypatch):
    monkeypatch.setattr(sink, "FLUSH_SLICE_S", 0.01)
    monkeypatch.setattr(sink, "STALL_TIMEOUT_S", 0.05)


def test_a_stuck_flush_is_one_output_error_and_no_disconnect(quick, tmp_path):
    target = tmp_path / "x.rrd"
    target.write_bytes(b"")
    rec = _Stuck()
    with pytest.raises(OutputError, match=r"x.rrd: Rerun could not write the recording \(flush timed out\)"):
        sink.close_recording(rec, target, shown=target)
    assert not rec.disconnected
    # and never orphaned: Rerun's RecordingStream.__del__ disconnects (flushes) every orphaned
    # stream, which on a stuck sink waited forever inside a later garbage collection
    import gc
    import weakref

    kept = weakref.ref(rec)
    del rec
    gc.collect()
    assert kept() is not None and kept() in sink._GIVEN_UP
    # the stall is counted from the last growth: a writer that still grows is waited for
    grower = _Stuck(grow_first=4, target=target)
    with pytest.raises(OutputError):
        sink.close_recording(grower, target, shown=target)
    assert grower.flushes > 4 + 4  # four growing slices, then the stall's slices


def test_an_error_on_its_way_out_is_not_replaced(quick, tmp_path):
    target = tmp_path / "x.rrd"
    rec = _Stuck()
    with pytest.raises(ValueError, match="the original"):
        with sink.closing(rec, target, shown=target):
            raise ValueError("the original")
    assert not rec.disconnected and rec in sink._GIVEN_UP


def test_a_recording_that_flushes_is_disconnected(tmp_path):
    rec = _Fine()
    with sink.closing(rec, tmp_path / "x.rrd", shown=tmp_path / "x.rrd"):
        pass
    assert rec.flushes == 1 and rec.disconnected


def test_a_forked_write_reports_the_studios_own_error_and_a_bugs_type(tmp_path):
    """write_bounded's writer is a forked process: its exception cannot travel, so its line does.
    A studio error stays the command's line; any other failure (a bug in the logging code) names
    its type instead of passing for a full disk; a write that works leaves its file."""
    target = tmp_path / "x.rrd"

    def studio_error(t):
        raise OutputError(f"{t}: a check of the writer's own failed")

    def bug(t):
        raise ZeroDivisionError("division by zero")

    def fine(t):
        t.write_bytes(b"written")

    with pytest.raises(OutputError) as caught:
        sink.write_bounded(studio_error, target, shown=target)
    assert str(caught.value) == f"{target}: a check of the writer's own failed"
    with pytest.raises(OutputError) as caught:
        sink.write_bounded(bug, target, shown=tmp_path / "shown.rrd")
    assert str(caught.value) == (
        f"{tmp_path / 'shown.rrd'}: the recording could not be written (ZeroDivisionError: division by zero)"
    )
    sink.write_bounded(fine, target, shown=target)
    assert target.read_bytes() == b"written"
