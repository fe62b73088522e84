"""Progress of long steps: the callback type library functions take, and its terminal rendering.

Library functions accept ``progress: Progress | None`` and call it as ``progress(step, done, total)``
(optionally with a ``unit``) whenever a count moves; a new ``step`` label starts a new line and
finishes the previous one. They never print. The CLI passes the callback of
:func:`terminal_progress`, which draws the steps with rich.progress (count, rate, elapsed time) on
stderr when stderr is a terminal, and passes ``None`` in a pipe or with ``--quiet``.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Protocol

__all__ = ["Progress", "report", "terminal_progress"]


class Progress(Protocol):
    """``progress(step, done, total, unit)``: ``done`` of ``total`` ``unit`` of ``step`` are finished."""

    def __call__(self, step: str, done: int, total: int, unit: str = ...) -> None: ...


def report(progress: Progress | None, step: str, done: int, total: int, unit: str = "") -> None:
    """Call ``progress`` when there is one (saves an ``if`` at every call site)."""
    if progress is not None:
        progress(step, done, total, unit)


def _may_be_terminal() -> bool:
    """Whether rich could take stderr for a terminal: it is one, or the environment tells rich to
    act as if (``FORCE_COLOR``, ``TTY_COMPATIBLE=1``). Asked before rich loads (about 25 ms), so a
    command in a pipe or a file does not pay for it."""
    isatty = getattr(sys.stderr, "isatty", None)
    if isatty is not None and isatty():
        return True
    return "FORCE_COLOR" in os.environ or os.environ.get("TTY_COMPATIBLE") == "1"


@contextlib.contextmanager
def terminal_progress(enabled: bool = True) -> Iterator[Progress | None]:
    """A :class:`Progress` drawing on stderr, or ``None`` when disabled or stderr is not a terminal.

    Each step is one line: ``step  ━━━━━━━━━━  done/total unit  rate unit/s  elapsed``.
    """
    if not enabled or not _may_be_terminal():
        yield None
        return
    from rich.console import Console

    console = Console(stderr=True)
    if not console.is_terminal or console.is_dumb_terminal:
        yield None
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
