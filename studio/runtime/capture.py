"""A child process's output captured up to a cap: the first and last bytes of each stream are kept,
the middle is counted and dropped, so a program that prints gigabytes (an external solver, a
verbose tool) never holds more than a few KiB of the studio's memory."""

from __future__ import annotations

import os
import selectors
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

__all__ = ["CappedRun", "run_capped", "DEFAULT_CAP_BYTES"]

#: Bytes kept of each stream: half from its start, half from its end.
DEFAULT_CAP_BYTES = 64 * 1024
_CHUNK_BYTES = 64 * 1024


@dataclass(frozen=True)
class CappedRun:
    """How a child ended and what it printed (each stream's text cut to the cap, marked where cut)."""

    argv: tuple[str, ...]
    returncode: int
    stdout: str
    stderr: str
    stdout_bytes: int
    """Bytes the child wrote to stdout in all (kept or not)."""
    stderr_bytes: int

    @property
    def cut(self) -> bool:
        """Whether some output was dropped."""
        return "bytes cut ...]" in self.stdout or "bytes cut ...]" in self.stderr


class _Kept:
    """The first and last ``cap / 2`` bytes of a stream, and its length."""

    def __init__(self, cap_bytes: int) -> None:
        self.half = max(1, cap_bytes // 2)
        self.head = bytearray()
        self.tail = bytearray()
        self.total = 0

    def add(self, chunk: bytes) -> None:
        self.total += len(chunk)
        room = self.half - len(self.head)
        if room > 0:
            self.head += chunk[:room]
            chunk = chunk[room:]
        if chunk:
            self.tail += chunk
            if len(self.tail) > 2 * self.half:  # trimmed now and then, not on every chunk
                del self.tail[: len(self.tail) - self.half]

    def text(self) -> str:
        tail = self.tail[-self.half :]
        dropped = self.total - len(self.head) - len(tail)
        middle = f"\n[... {dropped:,} bytes cut ...]\n" if dropped > 0 else ""
        return self.head.decode("utf-8", "replace") + middle + bytes(tail).decode("utf-8", "replace")


def run_capped(
    argv: Sequence[str],
    *,
    cap_bytes: int = DEFAULT_CAP_BYTES,
    env: Mapping[str, str] | None = None,
    timeout_s: float | None = None,
) -> CappedRun:
    """Run ``argv`` (stdin closed), keeping at most ``cap_bytes`` of each of stdout and stderr.

    Raises :class:`OSError` when the program cannot be started and :class:`subprocess.TimeoutExpired`
    (the child killed) after ``timeout_s``; on any exception (Ctrl-C too) the child is killed and
    reaped."""
    proc = subprocess.Popen(
        list(argv), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env
    )
    kept = {"stdout": _Kept(cap_bytes), "stderr": _Kept(cap_bytes)}
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    try:
        with selectors.DefaultSelector() as sel:
            assert proc.stdout is not None and proc.stderr is not None
            sel.register(proc.stdout, selectors.EVENT_READ, "stdout")
            sel.register(proc.stderr, selectors.EVENT_READ, "stderr")
            while sel.get_map():
                wait = None if deadline is None else deadline - time.monotonic()
                if wait is not None and wait <= 0:
                    raise subprocess.TimeoutExpired(list(argv), timeout_s or 0.0)
                for key, _ in sel.select(wait):
                    chunk = os.read(key.fd, _CHUNK_BYTES)
                    if chunk:
                        kept[key.data].add(chunk)
                    else:
                        sel.unregister(key.fileobj)
        wait = None if deadline is None else max(0.0, deadline - time.monotonic())
        returncode = proc.wait(wait)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
    return CappedRun(
        tuple(argv),
        returncode,
        kept["stdout"].text(),
        kept["stderr"].text(),
        kept["stdout"].total,
        kept["stderr"].total,
    )
