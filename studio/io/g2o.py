"""g2o text files: ``VERTEX_SE2``/``EDGE_SE2`` and ``VERTEX_SE3:QUAT``/``EDGE_SE3:QUAT`` records.

One file is held as columns in a :class:`G2oDocument`. Numbers are written with ``%.17g`` (every
double round-trips). In SE(3) records, a positive zero in z, qx, qy or in an off-diagonal information
entry is written ``0.0``, as kollagen writes the planar data it lifts to 3D; that keeps files written
from planar graphs byte-identical to kollagen's. Vertices come first, then edges, in column order.

Reading accepts the same four records and ``FIX id...`` (the gauge: the vertices held fixed), and
skips blank lines, ``#`` comments and ``PARAMS``; anything else is a
:class:`~studio.core.errors.FormatError` naming ``file:line``. A quaternion within
:data:`~studio.core.units.QUAT_NORM_TOLERANCE` (1e-5) of unit length is normalised, as g2o, GTSAM and
SE-Sync do (SE-Sync's ``cubicle.g2o`` writes six decimals, off by up to 1.7e-6); the document counts
them (:attr:`G2oDocument.normalised_quaternions`) so a command can say so in one line. One farther
from unit length is refused naming its line. Files are UTF-8 (a byte-order mark is
skipped) of at most :data:`MAX_TEXT_BYTES` (1 GiB), checked before reading; the TUM and
``inter_agent_lc.dat`` readers share these rules.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from studio.core.errors import FormatError
from studio.core.model import PoseKind
from studio.core.types import PathLike
from studio.core.units import QUAT_NORM_TOLERANCE
from studio.io.input_files import read_input_bytes
from studio.io.textfmt import (
    Floats,
    Ints,
    format_lines,
    row_blocks,
    write_text,
)

__all__ = [
    "G2oDocument",
    "write_g2o",
    "read_g2o",
    "g2o_text",
    "g2o_pieces",
    "SE3_INFO_ZERO_LITERAL",
    "SE3_POSE_ZERO_LITERAL",
    "MAX_TEXT_BYTES",
    "normalised_note",
]

_TAGS = {
    PoseKind.SE2: ("VERTEX_SE2", "EDGE_SE2"),
    PoseKind.SE3: ("VERTEX_SE3:QUAT", "EDGE_SE3:QUAT"),
}
_TAG_KIND = {
    "VERTEX_SE2": PoseKind.SE2,
    "EDGE_SE2": PoseKind.SE2,
    "VERTEX_SE3:QUAT": PoseKind.SE3,
    "EDGE_SE3:QUAT": PoseKind.SE3,
}
_DIAG6 = set(np.cumsum([0, 6, 5, 4, 3, 2]).tolist())  # positions of diagonal entries in a 6x6 upper triangle
#: For each of the 21 SE(3) information entries, the text of a positive zero.
SE3_INFO_ZERO_LITERAL = [None if k in _DIAG6 else "0.0" for k in range(21)]
#: For x, y, z, qx, qy, qz, qw: the text of a positive zero (kollagen writes planar z, qx, qy as 0.0).
SE3_POSE_ZERO_LITERAL = [None, None, "0.0", "0.0", "0.0", None, None]


@dataclass(frozen=True, eq=False)
class G2oDocument:
    """The records of one g2o file, as columns."""

    kind: PoseKind
    vertex_ids: np.ndarray
    vertex_poses: np.ndarray
    edge_from: np.ndarray
    edge_to: np.ndarray
    edge_measurements: np.ndarray
    edge_information_upper: np.ndarray
    fixed_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """The ids of the file's ``FIX`` lines (the gauge), in file order."""
    normalised_quaternions: int = 0
    """How many quaternions reading normalised (off unit length by more than 1e-12, within 1e-5)."""


def normalised_note(name: str, count: int) -> str:
    """The one line a command prints when reading normalised ``count`` quaternions of ``name``."""
    return (
        f"{name}: normalised {count} quaternion{'s' if count != 1 else ''} within {QUAT_NORM_TOLERANCE:g} "
        "of unit length (written with few decimals)"
    )


def _pose_fields(poses: np.ndarray, kind: PoseKind) -> Floats:
    if kind is PoseKind.SE2:
        return Floats(poses, ["%.17g"] * 3)
    return Floats(poses, ["%.17g"] * 7, SE3_POSE_ZERO_LITERAL)


def _info_fields(info: np.ndarray, kind: PoseKind) -> Floats:
    if kind is PoseKind.SE2:
        return Floats(info, ["%.17g"] * 6, repeated_rows=True)
    return Floats(info, ["%.17g"] * 21, SE3_INFO_ZERO_LITERAL, repeated_rows=True)


def g2o_pieces(doc: G2oDocument) -> Iterator[np.ndarray]:
    """The text of a g2o file in pieces (vertices, then edges, a block of lines at a time), as
    :func:`~studio.io.textfmt.format_lines` gives them; each piece is made when it is asked for."""
    vtag, etag = _TAGS[doc.kind]
    for rows in row_blocks(len(doc.vertex_ids)):
        yield format_lines([vtag, Ints(doc.vertex_ids[rows]), _pose_fields(doc.vertex_poses[rows], doc.kind)])
    for rows in row_blocks(len(doc.edge_from)):
        yield format_lines(
            [
                etag,
                Ints(doc.edge_from[rows]),
                Ints(doc.edge_to[rows]),
                _pose_fields(doc.edge_measurements[rows], doc.kind),
                _info_fields(doc.edge_information_upper[rows], doc.kind),
            ]
        )


def g2o_text(doc: G2oDocument) -> bytes:
    """The bytes of a g2o file."""
    return b"".join(piece.tobytes() for piece in g2o_pieces(doc))


def write_g2o(target: PathLike | IO[str], doc: G2oDocument) -> None:
    write_text(target, g2o_pieces(doc))


#: Text inputs larger than this are refused before reading: reading holds the file about four times
#: over (bytes, text, lines, columns), so 1 GiB keeps a read within the 8 GB memory bound of the
#: other commands; it is ten times the largest real input benchmarked (a 1,000,000-pose TUM file).
MAX_TEXT_BYTES = 1 << 30

_BOMS = (
    (b"\xff\xfe\x00\x00", "UTF-32"),
    (b"\x00\x00\xfe\xff", "UTF-32"),
    (b"\xff\xfe", "UTF-16"),
    (b"\xfe\xff", "UTF-16"),
)


def _open_text(source: PathLike | IO[str]) -> tuple[str, str]:
    """The text of a path or an open text stream, and the name errors use.

    Files are UTF-8 (ASCII in practice; a UTF-8 byte-order mark is skipped). A file over
    :data:`MAX_TEXT_BYTES`, UTF-16/32 text or other bytes are refused with a :class:`FormatError`.
    """
    if hasattr(source, "read"):
        return source.read(), getattr(source, "name", "<stream>")
    path = Path(source)
    data = read_input_bytes(path, limit=MAX_TEXT_BYTES, what="text inputs")  # a FIFO or device: refused
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8"), str(path)
    except UnicodeDecodeError as err:
        for bom, enc in _BOMS:
            if data.startswith(bom):
                raise FormatError(f"{path}:1: {enc} text, not UTF-8 (save it as UTF-8 or ASCII)") from None
        line = data[: err.start].count(b"\n") + 1
        column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
        raise FormatError(f"{path}:{line}: not UTF-8 text (byte 0x{data[err.start]:02x} at column {column})") from None


def _row_norms(values: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row (as ``np.linalg.norm``), without overflow: rows with 1e300-sized
    entries give 1.4e300, not inf and a RuntimeWarning."""
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        norms: np.ndarray = np.linalg.norm(values, axis=1)
    big = ~np.isfinite(norms)
    if big.any():
        rows = values[big]
        scale = np.abs(rows).max(axis=1)
        norms[big] = scale * np.linalg.norm(rows / scale[:, None], axis=1)
    return norms


_WIDTH = {  # tokens after the tag
    "VERTEX_SE2": 4,
    "EDGE_SE2": 2 + 3 + 6,
    "VERTEX_SE3:QUAT": 8,
    "EDGE_SE3:QUAT": 2 + 7 + 21,
}


def read_g2o(
    source: PathLike | IO[str],
    *,
    edges: bool = True,
    unknown: dict[str, int] | None = None,
    dangling: bool = False,
) -> G2oDocument:
    """Parse a g2o file; errors name ``file:line``.

    ``edges=False`` skips edge records unparsed (the document then has no edges): reading only the
    vertices of a large file is several times faster. ``unknown``, where given, counts the records
    of other types (``EDGE_SE2_XY``, ``VERTEX_XY``) by tag instead of refusing them. ``dangling``
    accepts edges to vertices the file does not define (files of edges only; a robot's file that
    omits the separator vertices of its inter-robot edges).
    """
    text, name = _open_text(source)
    groups: dict[str, tuple[list[int], list[list[str]]]] = {}
    fixed: list[tuple[int, str]] = []
    kind = None
    for lineno, raw in enumerate(io.StringIO(text), start=1):
        if not edges and raw.startswith("EDGE_"):
            continue
        parts = raw.split()
        if not parts or parts[0].startswith("#"):
            continue
        tag = parts[0]
        if tag == "FIX":
            fixed.extend((lineno, tok) for tok in parts[1:])
            continue
        if tag not in _WIDTH:
            if unknown is not None:
                unknown[tag[:40]] = unknown.get(tag[:40], 0) + 1
                continue
            if tag.startswith("PARAMS"):
                continue
            raise FormatError(f"{name}:{lineno}: unknown record {tag[:40]!r}")
        if kind is None:
            kind = _TAG_KIND[tag]
        elif _TAG_KIND[tag] is not kind:
            raise FormatError(f"{name}:{lineno}: {tag} mixed with {kind.value} records")
        if len(parts) - 1 != _WIDTH[tag]:
            raise FormatError(f"{name}:{lineno}: {tag} needs {_WIDTH[tag]} fields, found {len(parts) - 1}")
        lines, rows = groups.setdefault(tag, ([], []))
        lines.append(lineno)
        rows.append(parts[1:])
    if kind is None:
        raise FormatError(f"{name}: no vertices or edges")
    vtag, etag = _TAGS[kind]
    vlines, vrows = groups.get(vtag, ([], []))
    elines, erows = groups.get(etag, ([], []))
    npose = kind.pose_width
    vids = _ints(vrows, 0, 1, vlines, name).reshape(-1)
    vposes = _floats(vrows, 1, 1 + npose, vlines, name)
    eids = _ints(erows, 0, 2, elines, name)
    emeas = _floats(erows, 2, 2 + npose, elines, name)
    einfo = _floats(erows, 2 + npose, 2 + npose + kind.information_width, elines, name)
    uniq, counts = np.unique(vids, return_counts=True)
    if np.any(counts > 1):
        dup = int(uniq[np.argmax(counts > 1)])
        where = [ln for ln, v in zip(vlines, vids.tolist()) if v == dup][1]
        raise FormatError(f"{name}:{where}: vertex {dup} is defined twice")
    loops = np.flatnonzero(eids[:, 0] == eids[:, 1]) if len(eids) else eids[:0, 0]
    if len(loops):  # a pose related to itself constrains nothing but contradicts any non-identity measurement
        r = int(loops[0])
        raise FormatError(f"{name}:{elines[r]}: edge from vertex {int(eids[r, 0])} to itself (a self-loop)")
    if len(eids) and not dangling:
        known = np.isin(eids, vids)
        if not known.all():
            r, c = np.argwhere(~known)[0]
            raise FormatError(f"{name}:{elines[r]}: edge refers to unknown vertex {int(eids[r, c])}")
    fixed_ids = _fixed_ids(fixed, vids, eids, name, dangling=dangling)
    normalised = 0
    if kind is PoseKind.SE3:
        normalised = _normalise_quats(vposes, vlines, name) + _normalise_quats(emeas, elines, name)
    return G2oDocument(kind, vids, vposes, eids[:, 0].copy(), eids[:, 1].copy(), emeas, einfo, fixed_ids, normalised)


def _fixed_ids(
    fixed: list[tuple[int, str]], vids: np.ndarray, eids: np.ndarray, name: str, *, dangling: bool
) -> np.ndarray:
    """The ids of the ``FIX`` lines, each a vertex of the file (or, in a file of edges only, an edge's end)."""
    ids = np.zeros(len(fixed), dtype=np.int64)
    for k, (lineno, tok) in enumerate(fixed):
        try:
            ids[k] = int(tok)
        except (ValueError, OverflowError):
            raise FormatError(f"{name}:{lineno}: FIX: vertex id {tok[:40]!r} is not a 64-bit integer") from None
    known = vids if len(vids) or not dangling else eids.reshape(-1)
    missing = np.flatnonzero(~np.isin(ids, known))  # one sorted search: a file of many FIX ids stays fast
    if missing.size:
        k = int(missing[0])
        raise FormatError(f"{name}:{fixed[k][0]}: FIX names vertex {ids[k]}, which the file does not have")
    return ids


def _normalise_quats(poses: np.ndarray, lines: list[int], name: str) -> int:
    """Normalise in place the quaternions ``poses[:, 3:7]`` off unit length by more than 1e-12 and at
    most :data:`QUAT_NORM_TOLERANCE`; return how many. The rest stay as written, so that a file written
    with every digit reads back bit for bit."""
    if not len(poses):
        return 0
    norms = _row_norms(poses[:, 3:7])
    off = np.abs(norms - 1.0)
    bad = np.flatnonzero(~(off <= QUAT_NORM_TOLERANCE))
    if bad.size:
        raise FormatError(
            f"{name}:{lines[bad[0]]}: quaternion is not unit length (norm {norms[bad[0]]:.9g}; "
            f"at most {QUAT_NORM_TOLERANCE:g} off is normalised)"
        )
    fix = off > 1e-12
    poses[fix, 3:7] /= norms[fix, None]
    return int(np.count_nonzero(fix))


def _ints(rows: list[list[str]], a: int, b: int, lines: list[int], name: str) -> np.ndarray:
    width = b - a
    if not rows:
        return np.zeros((0, width), dtype=np.int64)
    try:
        return np.array([r[a:b] for r in rows], dtype=np.int64).reshape(-1, width)
    except (ValueError, OverflowError):
        for ln, r in zip(lines, rows):
            for tok in r[a:b]:
                try:
                    v = int(tok)
                except ValueError:
                    raise FormatError(f"{name}:{ln}: vertex id {tok[:40]!r} is not an integer") from None
                if not -(2**63) <= v < 2**63:
                    raise FormatError(f"{name}:{ln}: vertex id {tok[:40]} is out of range") from None
        raise


def _floats(rows: list[list[str]], a: int, b: int | None, lines: list[int], name: str) -> np.ndarray:
    if not rows:
        width = (b - a) if b is not None else 0
        return np.zeros((0, width))
    sub = [r[a:b] for r in rows]
    try:
        arr = np.array([[float(t) for t in r] for r in sub], dtype=np.float64)
    except ValueError:
        for ln, r in zip(lines, sub):
            for tok in r:
                try:
                    float(tok)
                except ValueError:
                    raise FormatError(f"{name}:{ln}: {tok[:40]!r} is not a number") from None
        raise
    finite = np.isfinite(arr).all(axis=1)
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise FormatError(f"{name}:{lines[k]}: value is not finite")
    return arr
