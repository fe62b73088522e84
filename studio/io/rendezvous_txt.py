"""Swarm-SLAM's simulated rendezvous schedule (lajoiepy/cslam,
``src/back_end/utils/simulated_rendezvous.cpp``): one line per robot,
``ROBOT_ID,start,end,start,end,...``.

As Swarm-SLAM reads it: no header; ``ROBOT_ID`` the robot's integer id (0-based; here the
position of the agent in the dataset's order); ``start``/``end`` whole seconds from the start of
the run (Swarm-SLAM adds its start time to them), a window inclusive at both ends; a robot is
"alive" (can communicate) inside one of its windows, and a robot without a line never is. Two
robots talk when both are alive. Each Swarm-SLAM robot reads only its own line, so a schedule may
name more robots than a run has (cslam_experiments' ``config/rendezvous/`` files name up to six):
lines for robots the dataset does not have are ignored, with one warning naming them. Otherwise
this reader is stricter than Swarm-SLAM's: a line must have pairs of non-negative integers,
windows in order and not overlapping, each robot once; empty lines are skipped. Errors name
``file:line``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import IO

import numpy as np

from studio.core.comms import check_windows
from studio.core.errors import ConfigError, FormatError
from studio.core.types import PathLike
from studio.core.units import MAX_STAMP_S
from studio.io.g2o import _open_text
from studio.io.numbers import text_int

_DIGITS = re.compile(r"[+-]?[0-9]+")

__all__ = ["read_rendezvous", "write_rendezvous", "rendezvous_text"]


def read_rendezvous(
    source: PathLike | IO[str], num_robots: int, *, warn: Callable[[str], None] | None = None
) -> tuple[np.ndarray, ...]:
    """Per robot ``0..num_robots-1``, its ``(k, 2)`` int64 windows ``[start, end]`` in seconds;
    ``warn`` gets one line naming the robots of other lines (ignored, as Swarm-SLAM does)."""
    text, name = _open_text(source)
    windows: dict[int, np.ndarray] = {}
    where: dict[int, str] = {}
    others: dict[int, str] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        place = f"{name}:{number}"
        fields = [f.strip() for f in line.split(",")]
        if fields and fields[-1] == "":
            fields = fields[:-1]
        # plain digits only: Swarm-SLAM's std::stoi reads "1_0" as 1, Python's int() as 10
        if not all(_DIGITS.fullmatch(f) for f in fields):
            raise FormatError(
                f"{place}: expected ROBOT_ID,start,end,... as integers (decimal digits), got {line[:60]!r}"
            )
        robot = text_int(fields[0], place, what="robot id")
        values = [robot] + [
            text_int(f, place, lo=-int(MAX_STAMP_S), hi=int(MAX_STAMP_S), what="time [s]") for f in fields[1:]
        ]
        if robot < 0:
            raise FormatError(f"{place}: robot id {robot} is negative (ids are 0-based)")
        if robot in windows or robot in others:
            raise FormatError(f"{place}: robot {robot} already has a line ({where.get(robot) or others[robot]})")
        times = values[1:]
        if len(times) % 2:
            raise FormatError(f"{place}: robot {robot} has an odd number of times (a window needs start and end)")
        w = np.asarray(times, dtype=np.int64).reshape(-1, 2)
        try:
            check_windows((w,), [place])
        except ConfigError as err:
            raise FormatError(str(err)) from None
        if robot >= num_robots:
            others[robot] = place
            continue
        windows[robot] = w
        where[robot] = place
    if others and warn is not None:
        warn(
            f"{name}: ignored the lines of robots {', '.join(map(str, sorted(others)))}, which the dataset does not "
            f"have (robots 0..{num_robots - 1}), as Swarm-SLAM's robots read only their own line"
        )
    empty = np.zeros((0, 2), dtype=np.int64)
    return tuple(windows.get(k, empty) for k in range(num_robots))


def rendezvous_text(windows_s: tuple[np.ndarray, ...]) -> str:
    """The file's text: one line per robot (a robot without windows gets no line)."""
    lines = []
    for robot, w in enumerate(windows_s):
        if len(w):
            lines.append(",".join([str(robot), *(str(int(v)) for v in np.asarray(w).reshape(-1))]))
    return "".join(line + "\n" for line in lines)


def write_rendezvous(target: PathLike, windows_s: tuple[np.ndarray, ...]) -> None:
    with open(target, "w", encoding="utf-8", newline="\n") as f:
        f.write(rendezvous_text(windows_s))
