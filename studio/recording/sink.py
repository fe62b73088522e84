"""Closing a recording written in this process so that a stuck sink cannot hang the command.

On a full disk Rerun's file sink can stop writing without ending the stream; ``disconnect()`` then
waits forever (seen in ``studio record`` and ``studio convert`` onto a full tmpfs). Every recording
written in-process is closed by :func:`close_recording`: the flush is waited for in short slices
while the file still grows, given up once it has stood still for :data:`STALL_TIMEOUT_S`, and a
stream that did not flush is never disconnected (its threads are left to the process's end). The
solve recording goes further and writes in a forked process (``studio.recording.solve``).

A stream given up is also kept referenced (:data:`_GIVEN_UP`) until the process ends. Rerun's
``RecordingStream.__del__`` disconnects every *orphaned* stream (one no Python object refers to any
more), flushing each: once a given-up stream's object was collected, the next recording closed
anywhere in the process (a test run's later test) waited forever on the stuck sink's flush inside
the garbage collector (a CI run hung in tests/replay after the full-disk tests).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from studio.core.errors import OutputError

__all__ = ["closing", "close_recording", "FLUSH_SLICE_S", "STALL_TIMEOUT_S", "first_line", "disk_full_note"]

#: Seconds of one flush attempt; attempts repeat while the recording's file grows.
FLUSH_SLICE_S = 1.0
#: Seconds the recording's file may stay the same size while a flush is pending before the write
#: is given up as stuck (Rerun's writer appends every few milliseconds while it can).
STALL_TIMEOUT_S = 5.0
#: Streams whose flush was given up: never orphaned, so Rerun never tries to disconnect them.
_GIVEN_UP: list[Any] = []


def close_recording(rec: Any, target: Path, *, shown: Path, failing: bool = False) -> None:
    """Flush ``rec`` (a RecordingStream saving to ``target``) and disconnect it; an OutputError naming
    ``shown`` when the flush makes no progress for :data:`STALL_TIMEOUT_S` (``rec`` then stays
    connected: disconnecting a stuck sink never returns). ``failing``: another error is on its way
    out (the write is abandoned anyway): a stuck flush is left without a second error."""
    size, still_s = -1, 0.0
    while True:
        try:
            rec.flush(timeout_sec=FLUSH_SLICE_S)
            break
        except RuntimeError as err:
            try:
                now = target.stat().st_size
            except OSError:
                now = -1
            size, still_s = (size, still_s + FLUSH_SLICE_S) if now == size else (now, 0.0)
            if still_s >= STALL_TIMEOUT_S:
                _GIVEN_UP.append(rec)
                if failing:
                    return
                raise OutputError(
                    f"{shown}: Rerun could not write the recording ({first_line(err)}){disk_full_note(target)}"
                ) from None
    rec.disconnect()


@contextlib.contextmanager
def closing(rec: Any, target: Path, *, shown: Path) -> Iterator[Any]:
    """``with closing(rec, target, shown=...):`` log into ``rec``; on leaving it is closed by
    :func:`close_recording` (after an error too, without hiding that error)."""
    try:
        yield rec
    except BaseException:
        close_recording(rec, target, shown=shown, failing=True)
        raise
    close_recording(rec, target, shown=shown)


def first_line(err: BaseException) -> str:
    """The first non-blank line of ``err`` (at most 160 characters), or its type's name."""
    return next((ln.strip() for ln in str(err).splitlines() if ln.strip()), type(err).__name__)[:160]


def disk_full_note(target: Path) -> str:
    """`` (No space left on device)`` when ``target``'s file system has less than 1 MiB free."""
    try:
        st = os.statvfs(target.parent)
    except OSError:
        return ""
    return " (No space left on device)" if st.f_bavail * st.f_frsize < (1 << 20) else ""
