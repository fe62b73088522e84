"""Ctrl-C held back while native code writes: a KeyboardInterrupt raised inside a Rerun call can
leave its writer thread waiting forever, so the interrupt is delivered when the section ends."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["interrupts_deferred"]


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold SIGINT during the block and hand it to the previous handler after it if one came (Python's
    default handler raises KeyboardInterrupt). Only in the main thread, and only where SIGINT is
    handled at all: elsewhere (other threads, workers that ignore it) the block runs as it is."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) in (
        signal.SIG_IGN,
        None,
    ):
        yield
        return
    received: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        received.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if received:
        if callable(previous):
            previous(signal.SIGINT, None)
        else:  # SIG_DFL: what the signal would have done
            signal.raise_signal(signal.SIGINT)
