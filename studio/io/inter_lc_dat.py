"""``inter_agent_lc.dat``: the inter-agent loop closures of a multi-g2o folder, one per line.

Columns: ``agent_from vertex_from agent_to vertex_to`` (agents 1-based, vertices 0-based within
their agent), then the measurement and information as in a g2o edge record: SE(3) rows
(``x y z qx qy qz qw`` + 21 information values, 32 columns; kollagen's default) or SE(2) rows
(``x y theta`` + 6, 13 columns). kollagen writes numbers with ``%f`` (six decimals) and a positive zero
in z, qx, qy or an off-diagonal information entry as ``0.0``; ``precision="full"`` writes ``%.17g``
instead so that reading gives back every bit.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import IO, Literal

import numpy as np

from studio.core.errors import FormatError
from studio.core.model import InterAgentEdges, PoseKind
from studio.core.types import PathLike
from studio.io.g2o import SE3_INFO_ZERO_LITERAL, SE3_POSE_ZERO_LITERAL, _open_text, _row_norms
from studio.io.textfmt import Floats, Ints, format_lines, row_blocks, write_text

__all__ = ["write_inter_lc_dat", "read_inter_lc_dat", "inter_lc_text", "Precision"]

Precision = Literal["kollagen", "full"]


def _inter_lc_pieces(inter: InterAgentEdges, precision: Precision) -> Iterator[np.ndarray]:
    """The text of the file, a block of lines at a time (each made when asked for)."""
    fmt = "%f" if precision == "kollagen" else "%.17g"
    for rows in row_blocks(len(inter)):
        if inter.kind is PoseKind.SE3:
            meas = Floats(inter.measurements[rows], [fmt] * 7, SE3_POSE_ZERO_LITERAL)
            info = Floats(inter.information_upper[rows], [fmt] * 21, SE3_INFO_ZERO_LITERAL, repeated_rows=True)
        else:
            meas = Floats(inter.measurements[rows], [fmt] * 3)
            info = Floats(
                inter.information_upper[rows], [fmt] * 6, [None, "0.0", "0.0", None, "0.0", None], repeated_rows=True
            )
        ids = [
            Ints(inter.from_agent[rows] + 1),
            Ints(inter.from_index[rows]),
            Ints(inter.to_agent[rows] + 1),
            Ints(inter.to_index[rows]),
        ]
        yield format_lines([*ids, meas, info])


def inter_lc_text(inter: InterAgentEdges, precision: Precision = "kollagen") -> bytes:
    """The bytes of the file."""
    return b"".join(piece.tobytes() for piece in _inter_lc_pieces(inter, precision))


def write_inter_lc_dat(target: PathLike | IO[str], inter: InterAgentEdges, precision: Precision = "kollagen") -> None:
    write_text(target, _inter_lc_pieces(inter, precision))


def read_inter_lc_dat(source: PathLike | IO[str], kind: PoseKind | None = None) -> InterAgentEdges:
    """Parse the file; ``kind`` (if given) is the pose kind the rows must have."""
    text, name = _open_text(source)
    rows, lines = [], []
    width = None
    for lineno, raw in enumerate(io.StringIO(text), start=1):
        parts = raw.split()
        if not parts or parts[0].startswith("#"):
            continue
        if len(parts) not in (13, 32):
            raise FormatError(f"{name}:{lineno}: expected 32 (SE3) or 13 (SE2) columns, found {len(parts)}")
        if width is None:
            width = len(parts)
        elif len(parts) != width:
            raise FormatError(f"{name}:{lineno}: {len(parts)} columns after rows of {width}")
        rows.append(parts)
        lines.append(lineno)
    file_kind = PoseKind.SE3 if width in (None, 32) else PoseKind.SE2
    if kind is not None and width is not None and file_kind is not kind:
        raise FormatError(f"{name}:{lines[0]}: {file_kind.value} rows in a {kind.value} dataset")
    kind = kind or file_kind
    if not rows:
        return InterAgentEdges.empty(kind)
    ids = np.zeros((len(rows), 4), dtype=np.int64)
    vals = np.zeros((len(rows), len(rows[0]) - 4))
    for r, (ln, parts) in enumerate(zip(lines, rows)):
        try:
            ids[r] = [int(t) for t in parts[:4]]
        except (ValueError, OverflowError):
            raise FormatError(f"{name}:{ln}: agent and vertex ids must be integers") from None
        try:
            vals[r] = [float(t) for t in parts[4:]]
        except ValueError:
            raise FormatError(f"{name}:{ln}: non-numeric measurement or information") from None
    if not np.isfinite(vals).all():
        k = int(np.flatnonzero(~np.isfinite(vals).all(axis=1))[0])
        raise FormatError(f"{name}:{lines[k]}: value is not finite")
    bad = np.flatnonzero((ids[:, 0] < 1) | (ids[:, 2] < 1) | (ids[:, 1] < 0) | (ids[:, 3] < 0))
    if bad.size:
        raise FormatError(f"{name}:{lines[bad[0]]}: agents are numbered from 1 and vertices from 0")
    w = kind.pose_width
    meas = vals[:, :w]
    if kind is PoseKind.SE3:
        norms = _row_norms(meas[:, 3:7])
        if np.any(norms < 1e-9):
            k = int(np.flatnonzero(norms < 1e-9)[0])
            raise FormatError(f"{name}:{lines[k]}: quaternion is zero")
        # six-decimal quaternions are not unit length to 1e-6; renormalise them
        off = np.abs(norms - 1.0) > 1e-12
        meas[off, 3:7] /= norms[off, None]
    return InterAgentEdges(kind, ids[:, 0] - 1, ids[:, 1], ids[:, 2] - 1, ids[:, 3], meas, vals[:, w:])
