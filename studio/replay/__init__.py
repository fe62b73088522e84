"""``studio replay``: a multi-robot dataset lived through in time (:mod:`studio.replay.pipeline`, the
library function; :mod:`studio.replay.backends`, the back-ends; :mod:`studio.replay.registry`, their
names).

The package itself loads nothing heavy: the command line reads the back-ends' names and defaults from
the registry at start-up, and ``from studio.replay import replay`` (or any name of the pipeline's
``__all__``) imports the pipeline, with numpy and the solvers, when it is first asked for.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from studio.replay.registry import DEFAULT_BACKENDS

if TYPE_CHECKING:
    from studio.replay.pipeline import REPLAY_JSON, BackendRun, ReplayResult, build_schedule, replay

__all__ = ["replay", "ReplayResult", "BackendRun", "build_schedule", "DEFAULT_BACKENDS", "REPLAY_JSON"]

_PIPELINE = ("replay", "ReplayResult", "BackendRun", "build_schedule", "REPLAY_JSON")


def __getattr__(name: str) -> Any:
    if name in _PIPELINE:
        return getattr(importlib.import_module("studio.replay.pipeline"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
