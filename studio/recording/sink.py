"""Writing a recording so that a stuck or failing Rerun sink cannot hang nor garble the command.

Every recording the studio writes goes through :func:`write_bounded`: the write runs in a forked
process the command watches and stops at the first write error Rerun logs, when the file stops
growing, or after :data:`WRITE_TIMEOUT_S`; a failure is one :class:`OutputError`. Written in the
command's own process, a disk that fills made Rerun's ``save()`` block forever on its dead file sink
(4-16 kB left), raise (0 kB: a traceback) or leave a given-up stream that Rerun's exit handler then
waited on forever (128 kB), all seen with ``evaluate --rrd`` on 2026-12-02.

Inside the writer, :func:`closing` / :func:`close_recording` close the stream: the flush is waited
for in short slices while the file still grows, given up once it has stood still for
:data:`STALL_TIMEOUT_S`, and a stream that did not flush is never disconnected (``disconnect()`` on a
stuck sink waits forever). A stream given up is also kept referenced (:data:`_GIVEN_UP`) until the
process ends: Rerun's ``RecordingStream.__del__`` disconnects every *orphaned* stream, flushing each,
and once a given-up stream's object was collected the next recording closed anywhere in the process
waited forever on the stuck sink's flush inside the garbage collector.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from studio.core.errors import OutputError, StudioError

__all__ = [
    "closing",
    "close_recording",
    "write_bounded",
    "FLUSH_SLICE_S",
    "STALL_TIMEOUT_S",
    "FULL_DISK_STALL_S",
    "WRITE_TIMEOUT_S",
    "first_line",
    "disk_full_note",
]

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
    except RuntimeError as err:  # Rerun's writer failed in ``save`` or a log call (a full disk)
        close_recording(rec, target, shown=shown, failing=True)
        raise OutputError(
            f"{shown}: Rerun could not write the recording ({first_line(err)}){disk_full_note(target)}"
        ) from None
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


#: Seconds a recording's writing process may take at most, flush included.
WRITE_TIMEOUT_S = 600.0
#: Seconds the file may stand still, on a file system with under 1 MiB free (:func:`disk_full_note`),
#: before the writer is taken as stuck: Rerun appends every few milliseconds while it can.
FULL_DISK_STALL_S = 1.0
#: ``RUST_LOG`` of the writing process when the command line runs with Rerun's writer logs off: its
#: file sink's errors reach the watcher (which stops the writer at the first one) and nobody else.
_WRITER_RUST_LOG = "error"


def write_bounded(write: Callable[[Path], None], target: Path, *, shown: Path) -> None:
    """Run ``write(target)`` (which writes a recording with Rerun) so that it cannot hang nor print:
    in a forked process whose stdout goes nowhere and whose stderr (Rerun's own ANSI log lines of a
    failed write) only this process reads, that leaves by ``os._exit`` (a stuck sink's exit handlers
    never run) and is killed at the first write error Rerun logs (a full disk: no flush timeout nor
    stall waited out), or after :data:`WRITE_TIMEOUT_S`. A failure is one :class:`OutputError`
    naming ``shown`` and the cause.

    A fork works where Rerun is already loaded here too: its fork handler
    (``cleanup_if_forked_child``) drops the streams the child inherits, and a stream the child
    makes starts its own threads (20 forks after three saved and read-back recordings in the parent:
    each child wrote a complete file in 11-15 ms). Only without ``os.fork`` does the write run here,
    its flush bounded by :func:`close_recording`'s stall rule (``rec.save`` itself can then still
    block on a disk that fills while it writes the header).
    """
    import signal
    import sys

    if not hasattr(os, "fork"):
        try:
            write(target)
        except RuntimeError as err:
            raise OutputError(f"{shown}: Rerun could not write the recording ({first_line(err)})") from None
        return
    # the caller's own RUST_LOG (not the command line's quiet default): Rerun's lines are theirs
    from studio.runtime.library_logs import RERUN_LOG_FILTER

    relay = os.environ.get("RUST_LOG") not in (None, RERUN_LOG_FILTER)
    read_end, write_end = os.pipe()  # the writer's stderr: Rerun's log lines of a failed write
    pid = os.fork()
    if pid == 0:  # the writer
        code = 1
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and kills us
            os.close(read_end)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(write_end, 2)
            if not relay:
                os.environ["RUST_LOG"] = _WRITER_RUST_LOG  # read when Rerun loads, below
            write(target)
            code = 0
        except BaseException as err:  # noqa: BLE001 - any failure is the exit code; the parent reports it
            code = 3
            # the line for the parent to raise: the studio's own error as it stands, any other but
            # Rerun's (a RuntimeError: reported from its log and the file) with its type, so that
            # a bug in the logging code is never taken for a full disk
            line = None
            if isinstance(err, StudioError):
                line = " ".join(str(err).split())
            elif not isinstance(err, (RuntimeError, KeyboardInterrupt)):
                line = f"{shown}: the recording could not be written ({type(err).__name__}: {first_line(err)})"
            if line is not None:
                with contextlib.suppress(OSError):
                    os.write(2, f"\n{_WRITER_ERROR}{line}\n".encode())
        finally:
            os._exit(code)
    os.close(write_end)
    os.set_blocking(read_end, False)
    try:
        status, stalled, failed, log = _watch_writer(pid, target, read_end)
    finally:
        os.close(read_end)
    if relay and log:
        sys.stderr.write(log.decode("utf-8", "replace"))
        sys.stderr.flush()
    if failed is not None:
        raise OutputError(f"{shown}: Rerun could not write the recording ({failed})")
    own = _WRITER_ERROR_LINE.search(log)
    if own is not None:
        raise OutputError(own.group(1).decode("utf-8", "replace"))
    if stalled:
        raise OutputError(
            f"{shown}: Rerun could not write the recording (its file stopped growing){disk_full_note(target)}"
        )
    if status is None:
        raise OutputError(f"{shown}: the recording was not written within {WRITE_TIMEOUT_S:g} s")
    if os.waitstatus_to_exitcode(status) != 0:
        raise OutputError(f"{shown}: Rerun could not write the recording{disk_full_note(target)}")


#: How the writing process passes the studio's own error line (an ``OutputError`` of its own
#: checks) to the watcher.
_WRITER_ERROR = "studio-writer-error: "
_WRITER_ERROR_LINE = re.compile(rb"\n" + re.escape(_WRITER_ERROR.encode()) + rb"([^\n]*)\n")
#: What Rerun's file sink logs when a write fails: ``Failed to write: <strerror> (os error N)``.
_WRITE_FAILED = re.compile(rb"Failed to write[^\n]*?\(os error (\d+)\)")
#: Bytes of the writer's log kept while watching it (the rest is read and dropped).
_LOG_CAP_BYTES = 64 * 1024


def _watch_writer(pid: int, target: Path, log_fd: int) -> tuple[int | None, bool, str | None, bytes]:
    """Wait for the writing process ``pid``: ``(wait status or None, stalled, failed write's cause,
    its log)``.

    It is killed (and reaped) at the first write error Rerun logs on ``log_fd`` (a full disk: at
    once, rather than after a flush timeout and a stalled file), when its file stops growing for
    :data:`STALL_TIMEOUT_S` (:data:`FULL_DISK_STALL_S` on a full file system), or after
    :data:`WRITE_TIMEOUT_S`."""
    import signal
    import time

    status: int | None = None
    stalled = False
    failed: str | None = None
    log = bytearray()
    try:
        deadline = time.monotonic() + WRITE_TIMEOUT_S
        size, changed = -1, time.monotonic()
        while status is None and time.monotonic() < deadline:
            with contextlib.suppress(BlockingIOError):
                while chunk := os.read(log_fd, 65536):
                    log = (log + chunk)[-_LOG_CAP_BYTES:]
            found = _WRITE_FAILED.search(log)
            if found is not None:
                failed = os.strerror(int(found.group(1)))
                break
            done, st = os.waitpid(pid, os.WNOHANG)
            status = st if done else None
            if status is None:
                time.sleep(0.01)
                try:
                    now_size = target.stat().st_size
                except OSError:
                    now_size = -1
                if now_size != size:
                    size, changed = now_size, time.monotonic()
                elif (still_s := time.monotonic() - changed) > STALL_TIMEOUT_S or (
                    still_s > FULL_DISK_STALL_S and disk_full_note(target)
                ):
                    stalled = True  # the file stopped growing: Rerun's sink is stuck (a full disk)
                    break
    finally:
        if status is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
    with contextlib.suppress(BlockingIOError, OSError):  # what it logged before it ended
        while chunk := os.read(log_fd, 65536):
            log = (log + chunk)[-_LOG_CAP_BYTES:]
    found = _WRITE_FAILED.search(log) if failed is None else None
    if found is not None:
        failed = os.strerror(int(found.group(1)))
    return (None if failed or stalled else status), stalled, failed, bytes(log)
