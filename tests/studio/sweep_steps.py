"""Custom sweep steps for the tests (``steps = ["tests.studio.sweep_steps:die_once"]``)."""

from __future__ import annotations

import os
from pathlib import Path


def die_once(cell_dir: Path, dataset: Path, row: dict) -> dict:
    """Kill the worker process the first time a cell reaches this step (a marker outside the cell
    remembers it): the dataset is then on disk but the cell is unfinished."""
    marker = cell_dir.parent.parent / "killed" / cell_dir.name
    if not marker.exists():
        marker.parent.mkdir(exist_ok=True)
        marker.write_text(str(os.getpid()))
        os._exit(17)
    return {"survived_kill": True}


def boom(cell_dir: Path, dataset: Path, row: dict) -> dict:
    """A step with a bug (not a StudioError): the cell records it and the sweep goes on."""
    if row["param:number_of_steps"] == 30:
        raise ValueError("a bug in a user's step\nsecond line")
    return {"boom_ok": 1}


def die_always(cell_dir: Path, dataset: Path, row: dict) -> dict:
    """Kill the worker process on every attempt."""
    os._exit(17)
