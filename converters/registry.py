"""The source formats ``studio convert`` knows: an explicit dict from name to reader.

Every reader has one signature: ``reader(inputs, *, agents=(), warn=None, progress=None) -> list[Trajectory]``
where ``inputs`` are the paths given on the command line and ``agents`` the ``NAME=SPEC`` strings of
``--agent`` (bags only). Readers that need heavy libraries import them when called.
"""

from __future__ import annotations

import os
from typing import Callable, Sequence

from studio.converters.airmuseum import read_airmuseum
from studio.converters.s3e import read_s3e
from studio.core.trajectory import Trajectory, Warn
from studio.converters.tum import read_tum_sources
from studio.core.errors import ConfigError

__all__ = ["READERS", "get_reader", "source_names"]

Reader = Callable[..., list[Trajectory]]


def _read_bag(inputs: Sequence[str | os.PathLike], *, agents: Sequence[str] = (),
              warn: Warn | None = None, progress=None) -> list[Trajectory]:
    from studio.converters.rosbag import read_bag_sources

    return read_bag_sources(inputs, agents=agents, warn=warn, progress=progress)


READERS: dict[str, Reader] = {
    "tum": read_tum_sources,
    "s3e": read_s3e,
    "airmuseum": read_airmuseum,
    "bag": _read_bag,
}


def source_names() -> list[str]:
    return list(READERS)


def get_reader(name: str) -> Reader:
    try:
        return READERS[name]
    except KeyError:
        raise ConfigError(f"unknown source format {name!r} (known: {', '.join(READERS)})") from None
