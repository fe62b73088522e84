"""A replay's communication schedule as two CSV files (written by ``studio replay``).

``contacts.csv``: one row per contact window of a pair of robots, by pair then time::

    robot_a,robot_b,start_ns,end_ns

(robot names as in the dataset; ``start_ns``/``end_ns`` the first and last tick of the window,
inclusive, int64 nanoseconds on the dataset's clock).

``closures.csv``: one row per inter-agent loop closure, in ``inter_agent_lc.dat`` order::

    closure,robot_from,vertex_from,robot_to,vertex_to,measured_ns,from_learns_ns,to_learns_ns

(``measured_ns``: both poses visited; ``*_learns_ns``: when each robot learns it, -1 for never).

A header line starts each file; integers only, so the bytes are the same on every run.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from studio.core.comms import Schedule
from studio.core.types import PathLike

__all__ = ["CONTACTS_CSV", "CLOSURES_CSV", "contacts_text", "closures_text", "write_schedule"]

CONTACTS_CSV = "contacts.csv"
CLOSURES_CSV = "closures.csv"


def _csv_name(name: str) -> str:
    if any(c in name for c in ',"\n\r'):
        return '"' + name.replace('"', '""') + '"'
    return name


def contacts_text(schedule: Schedule) -> str:
    lines = ["robot_a,robot_b,start_ns,end_ns"]
    names = [_csv_name(r) for r in schedule.robots]
    for a, b, s, e in schedule.windows().tolist():
        lines.append(f"{names[a]},{names[b]},{int(schedule.ticks_ns[s])},{int(schedule.ticks_ns[e])}")
    return "\n".join(lines) + "\n"


def closures_text(schedule: Schedule, from_index: np.ndarray, to_index: np.ndarray) -> str:
    lines = ["closure,robot_from,vertex_from,robot_to,vertex_to,measured_ns,from_learns_ns,to_learns_ns"]
    names = [_csv_name(r) for r in schedule.robots]
    learns = schedule.delivered_ns.tolist()
    rows = zip(
        schedule.closure_from.tolist(),
        from_index.tolist(),
        schedule.closure_to.tolist(),
        to_index.tolist(),
        schedule.measured_ns.tolist(),
        learns,
    )
    for k, (fa, fv, ta, tv, measured, learned) in enumerate(rows):
        lines.append(f"{k},{names[fa]},{fv},{names[ta]},{tv},{measured},{learned},{learned}")
    return "\n".join(lines) + "\n"


def write_schedule(folder: PathLike, schedule: Schedule, from_index: np.ndarray, to_index: np.ndarray) -> None:
    folder = Path(folder)
    (folder / CONTACTS_CSV).write_text(contacts_text(schedule), encoding="utf-8")
    (folder / CLOSURES_CSV).write_text(closures_text(schedule, from_index, to_index), encoding="utf-8")
