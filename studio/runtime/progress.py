"""Progress of long steps: the callback type library functions take, and its terminal rendering.

Library functions accept ``progress: Progress | None`` and call it as ``progress(step, done, total)``
(optionally with a ``unit``) whenever a count moves; a new ``step`` label starts a new line and
finishes the previous one. They never print. The CLI passes the callback of
:func:`terminal_progress`, which draws the steps with rich.progress (count, rate, elapsed time) on
stderr when stderr is a terminal; when stderr is a pipe or a file (a log), it prints one plain line
every few seconds instead (:func:`plain_progress`: ``progress: step 12/40 cells, 1m05s``), so a long
job in a log shows it is alive; with ``--quiet`` it passes ``None``.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Iterator
from typing import Protocol, TextIO

__all__ = ["PLAIN_INTERVAL_S", "Progress", "plain_progress", "report", "terminal_progress"]

#: Seconds between two plain progress lines off a terminal (the environment variable
#: ``STUDIO_PROGRESS_INTERVAL_S`` overrides it; the test suite sets it high, and low where it tests them).
PLAIN_INTERVAL_S = 5.0


class Progress(Protocol):
    """``progress(step, done, total, unit)``: ``done`` of ``total`` ``unit`` of ``step`` are finished."""

    def __call__(self, step: str, done: int, total: int, unit: str = ...) -> None: ...


def report(progress: Progress | None, step: str, done: int, total: int, unit: str = "") -> None:
    """Call ``progress`` when there is one (saves an ``if`` at every call site)."""
    if progress is not None:
        progress(step, done, total, unit)


def _may_be_terminal() -> bool:
    """Whether rich could take stderr for a terminal: it is one, or the environment tells rich to
    act as if (``FORCE_COLOR``, ``TTY_COMPATIBLE=1``). Asked before rich loads, so a
    command in a pipe or a file does not pay for it."""
    isatty = getattr(sys.stderr, "isatty", None)
    if isatty is not None and isatty():
        return True
    return "FORCE_COLOR" in os.environ or os.environ.get("TTY_COMPATIBLE") == "1"


def _interval_s() -> float:
    """The plain lines' interval: ``STUDIO_PROGRESS_INTERVAL_S`` when set to a positive number."""
    raw = os.environ.get("STUDIO_PROGRESS_INTERVAL_S", "")
    try:
        value = float(raw)
    except ValueError:
        return PLAIN_INTERVAL_S
    return value if value > 0 else PLAIN_INTERVAL_S


def _clock(seconds: float) -> str:
    """``42s``, ``3m05s``, ``1h02m``."""
    s = int(seconds)
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{s % 3600 // 60:02d}m"


@contextlib.contextmanager
def plain_progress(stream: TextIO, interval_s: float) -> Iterator[Progress]:
    """A :class:`Progress` for a log: every ``interval_s`` seconds, one plain line on ``stream`` with
    the latest step, its count and the time since the start (``progress: bench cells 3/16 cells,
    1m05s``), from a timer thread, so a step that goes quiet for minutes still shows the clock.
    Nothing is printed before the first interval has passed (a short command stays silent), no
    colours and no carriage returns."""
    start = time.monotonic()
    state: list[tuple[str, int, int, str]] = []
    lock = threading.Lock()
    stop = threading.Event()

    def update(step: str, done: int, total: int, unit: str = "") -> None:
        with lock:
            state[:] = [(step, done, total, unit)]

    def tick() -> None:
        while not stop.wait(interval_s):
            with lock:
                if not state:
                    continue
                step, done, total, unit = state[0]
            count = f"{done}/{total}" if total > 0 else f"{done}"
            line = f"progress: {step} {count}{' ' + unit if unit else ''}, {_clock(time.monotonic() - start)}"
            with contextlib.suppress(OSError, ValueError):  # a closed log does not stop the job
                stream.write(line + "\n")
                stream.flush()

    timer = threading.Thread(target=tick, name="studio-progress", daemon=True)
    timer.start()
    try:
        yield update
    finally:
        stop.set()
        timer.join()


@contextlib.contextmanager
def terminal_progress(enabled: bool = True) -> Iterator[Progress | None]:
    """A :class:`Progress` drawing on stderr; off a terminal, :func:`plain_progress`'s lines every
    few seconds; ``None`` when disabled.

    Each step is one line: ``step  ━━━━━━━━━━  done/total unit  rate unit/s  elapsed``.
    """
    if not enabled:
        yield None
        return
    if not _may_be_terminal():
        with plain_progress(sys.stderr, _interval_s()) as plain:
            yield plain
        return
    from rich.console import Console

    console = Console(stderr=True)
    if not console.is_terminal or console.is_dumb_terminal:
        with plain_progress(sys.stderr, _interval_s()) as plain:
            yield plain
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TaskID,
        TextColumn,
        TimeElapsedColumn,
    )
    from rich.progress import (
        Progress as RichProgress,
    )

    columns = (
        TextColumn("{task.description}"),
        BarColumn(bar_width=30),
        MofNCompleteColumn(),
        TextColumn("{task.fields[unit]}"),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
    )
    tasks: dict[str, TaskID] = {}
    current: list[str] = []

    with RichProgress(*columns, console=console, transient=False, refresh_per_second=8) as bar:

        def _rate(task_id: TaskID, unit: str) -> str:
            task = bar.tasks[task_id]
            elapsed = task.elapsed or 0.0
            if elapsed <= 0.0 or not task.completed:
                return ""
            return f"{task.completed / elapsed:,.0f} {unit or 'items'}/s"

        def update(step: str, done: int, total: int, unit: str = "") -> None:
            if step not in tasks:
                if current:  # a new step: the previous one is finished
                    prev = tasks[current[-1]]
                    t = bar.tasks[prev]
                    if t.total is not None and t.completed != t.total:
                        # its last items were done elsewhere (another process) since it last heard
                        bar.update(prev, completed=t.total)
                        bar.update(prev, rate=_rate(prev, t.fields.get("unit", "")))
                tasks[step] = bar.add_task(step, total=max(total, 0) or None, unit=unit, rate="")
                current.append(step)
            task_id = tasks[step]
            bar.update(task_id, completed=done, total=max(total, 0) or None)
            bar.update(task_id, rate=_rate(task_id, unit))

        yield update
        if current:
            last = tasks[current[-1]]
            t = bar.tasks[last]
            if t.total is not None:
                bar.update(last, completed=t.total)
