"""``range_bearing.txt``: range-bearing sightings of one agent by another, beside a multi-g2o folder.

``studio convert mrclam`` writes it from MR.CLAM's robot-to-robot measurements (docs/formats.md).
``#`` lines are comments; every other line is one sighting of 11 whitespace-separated columns::

    stamp_ns observer observer_vertex observed observed_vertex range_m bearing_rad \
        sigma_range_m sigma_bearing_rad observer_offset_ns observed_offset_ns

Agents are 1-based as in ``inter_agent_lc.dat`` (``agentK``), vertices 0-based within their agent;
each side is the agent's keyframe nearest in time to the sighting, and ``*_offset_ns`` is the
sighting's stamp minus that keyframe's stamp. The bearing is measured in the observer's body frame
from its x axis, counter-clockwise; numbers are written with ``%.17g`` so reading gives every bit back.
"""

from __future__ import annotations

from typing import IO

import numpy as np

from studio.core.errors import FormatError
from studio.core.model import PoseGraph, RangeBearing
from studio.core.types import PathLike
from studio.io.input_files import read_input_bytes
from studio.io.textfmt import float_columns, int_column, join_array, write_text

__all__ = ["RANGE_BEARING_NAME", "range_bearing_text", "write_range_bearing", "read_range_bearing"]

#: The file's name inside a dataset folder.
RANGE_BEARING_NAME = "range_bearing.txt"
_HEADER = (
    "# Range-bearing sightings of one agent by another (cslam-studio; docs/formats.md).\n"
    "# stamp_ns observer observer_vertex observed observed_vertex range_m bearing_rad "
    "sigma_range_m sigma_bearing_rad observer_offset_ns observed_offset_ns\n"
    "# agents 1-based (agentK), vertices 0-based: the agent's keyframe nearest in time; "
    "offset = stamp - keyframe stamp; bearing in the observer's body frame, counter-clockwise.\n"
)
_COLUMNS = 11


def range_bearing_text(rb: RangeBearing) -> bytes:
    """The bytes of the file (header included)."""
    if not len(rb):
        return _HEADER.encode("ascii")
    floats = float_columns(
        np.column_stack([rb.range_m, rb.bearing_rad, rb.sigma_range_m, rb.sigma_bearing_rad]), ["%.17g"] * 4
    )
    ints = [
        int_column(rb.stamps_ns),
        int_column(rb.observer_agent + 1),
        int_column(rb.observer_index),
        int_column(rb.observed_agent + 1),
        int_column(rb.observed_index),
    ]
    offsets = [int_column(rb.observer_offset_ns), int_column(rb.observed_offset_ns)]
    return _HEADER.encode("ascii") + bytes(join_array([*ints, *floats, *offsets]))


def write_range_bearing(target: PathLike | IO[str], rb: RangeBearing) -> None:
    write_text(target, range_bearing_text(rb))


def read_range_bearing(path: PathLike, graph: PoseGraph | None = None) -> RangeBearing:
    """Parse the file; with ``graph``, every agent and vertex must exist in it. Errors name
    ``file:line``."""
    ints: list[list[int]] = []
    floats: list[list[float]] = []
    sizes = [a.num_poses for a in graph.agents] if graph is not None else None
    try:
        lines = read_input_bytes(path).decode("utf-8").splitlines()  # a FIFO: refused, never waited on
    except (OSError, UnicodeDecodeError) as err:
        raise FormatError(f"{path}: cannot read ({err})") from None
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) != _COLUMNS:
            raise FormatError(f"{path}:{lineno}: expected {_COLUMNS} columns, found {len(parts)}")
        try:
            row_i = [int(p) for p in (*parts[0:5], *parts[9:11])]
            row_f = [float(p) for p in parts[5:9]]
        except ValueError:
            raise FormatError(f"{path}:{lineno}: not a sighting row ({line[:60]!r})") from None
        if not all(np.isfinite(row_f)):
            raise FormatError(f"{path}:{lineno}: value is not finite")
        if row_i[1] < 1 or row_i[3] < 1:
            raise FormatError(f"{path}:{lineno}: agents are 1-based")
        if row_f[0] < 0 or row_f[2] <= 0 or row_f[3] <= 0:
            raise FormatError(f"{path}:{lineno}: a range must be >= 0 and standard deviations > 0")
        if row_i[1] == row_i[3]:
            raise FormatError(f"{path}:{lineno}: agent {row_i[1]} sights itself")
        if sizes is not None:
            for agent, vertex in ((row_i[1], row_i[2]), (row_i[3], row_i[4])):
                if agent > len(sizes):
                    raise FormatError(f"{path}:{lineno}: agent {agent} is not in 1..{len(sizes)}")
                if not 0 <= vertex < sizes[agent - 1]:
                    raise FormatError(f"{path}:{lineno}: agent {agent} has no vertex {vertex}")
        ints.append(row_i)
        floats.append(row_f)
    if not ints:
        return RangeBearing.empty()
    i = np.array(ints, dtype=np.int64)
    fl = np.array(floats, dtype=np.float64)
    return RangeBearing(
        i[:, 0], i[:, 1] - 1, i[:, 2], i[:, 3] - 1, i[:, 4], fl[:, 0], fl[:, 1], fl[:, 2], fl[:, 3], i[:, 5], i[:, 6]
    )
