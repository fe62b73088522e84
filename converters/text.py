"""Numeric text tables as the real-data sources ship them (CSV or whitespace, ``#`` comments, one
header line), parsed with errors that name ``file:line``. Shared by the EuRoC, KITTI and
Kimera-Multi readers."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from studio.core.errors import FormatError
from studio.core.types import PathLike
from studio.io.input_files import read_input_bytes

__all__ = ["read_table", "read_text_bounded"]

#: Larger files are refused before reading (ground-truth files of real datasets are a few MB).
MAX_TABLE_BYTES = 1 << 30
#: the range of a nanosecond stamp (int64)
_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1


_QUAT_NAME = re.compile(r"^q(?:_?[a-z]*_)?([wxyz])$")


def _quaternion_order(header: str) -> str:
    """The quaternion components a header line names, in its order (``"wxyz"`` for
    ``#timestamp_kf,x,y,z,qw,qx,qy,qz`` or EuRoC's ``q_RS_w [], ...``); ``""`` when it names none."""
    names = [re.sub(r"\[.*?\]", "", f).strip().lower() for f in header.lstrip("#").split(",")]
    if len(names) == 1:
        names = header.lstrip("#").lower().split()
    return "".join(m.group(1) for m in map(_QUAT_NAME.match, names) if m)


def read_text_bounded(path: Path) -> str:
    """The whole of ``path`` as UTF-8 text (a BOM skipped), refused from its size before reading when
    larger than :data:`MAX_TABLE_BYTES`; every failure a one-line FormatError naming the file."""
    try:
        if path.stat().st_size > MAX_TABLE_BYTES:
            raise FormatError(f"{path}: larger than {MAX_TABLE_BYTES >> 30} GiB")
        return read_input_bytes(path).decode("utf-8-sig")  # a FIFO or device: refused, never waited on
    except UnicodeDecodeError as err:
        raise FormatError(f"{path}: not UTF-8 text (byte {err.start})") from None
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None


def read_table(
    path: PathLike,
    columns: int | tuple[int, ...],
    *,
    what: str,
    int_first: bool = False,
    header: bool = True,
    quaternion: str | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Rows of ``columns`` numbers (or any of several counts), as ``(values, first_column_int)``.

    ``int_first`` keeps the first column exactly as an int64 (nanosecond stamps) besides the float
    table. A first non-numeric line is a header; ``#`` lines are comments; commas or whitespace
    separate. ``what`` names the expected layout in messages. With ``quaternion`` (e.g. ``"wxyz"``),
    a header line (``#`` or not) before the data that names the quaternion's components in another
    order is refused, naming its line: the columns are read by position, so such a file would
    otherwise be read with its rotations scrambled.
    """
    path = Path(path)
    counts = (columns,) if isinstance(columns, int) else columns
    text = read_text_bounded(path)
    rows: list[list[float]] = []
    firsts: list[int] = []
    width = None
    seen = False
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and quaternion and not rows:
            order = _quaternion_order(line)
            if len(order) == 4 and sorted(order) == sorted(quaternion) and order != quaternion:
                raise FormatError(
                    f"{path}:{lineno}: the header orders the quaternion {' '.join(order)}; "
                    f"{what} has {' '.join(quaternion)}"
                )
        if not line or line.startswith("#"):
            continue
        parts = [p for p in line.replace(",", " ").split()]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            if not seen and header:
                seen = True  # one header line
                continue
            bad = next(p for p in parts if not _is_float(p))
            raise FormatError(f"{path}:{lineno}: {bad[:40]!r} is not a number ({what})") from None
        seen = True
        if len(values) not in counts or (width is not None and len(values) != width):
            expected = width if width is not None else " or ".join(map(str, counts))
            raise FormatError(f"{path}:{lineno}: expected {expected} columns ({what}), found {len(values)}")
        width = len(values)
        if int_first:
            token = parts[0]
            digits = token[1:] if token.startswith("-") else token
            if not (digits.isascii() and digits.isdigit()):
                raise FormatError(f"{path}:{lineno}: timestamp {token[:40]!r} is not an integer of nanoseconds")
            stamp_ns = int(token) if len(digits) <= 19 else None  # longer ones: beyond int64 (int() not tried)
            if stamp_ns is None or not _INT64_MIN <= stamp_ns <= _INT64_MAX:
                shown = token if len(token) <= 40 else f"{token[:20]}...({len(digits)} digits)"
                raise FormatError(
                    f"{path}:{lineno}: timestamp {shown!r} ns is beyond the int64 range (at most {_INT64_MAX} ns)"
                )
            firsts.append(stamp_ns)
        if not all(map(math.isfinite, values)):
            raise FormatError(f"{path}:{lineno}: value is not finite")
        rows.append(values)
    if not rows:
        raise FormatError(f"{path}: no data rows ({what})")
    return np.array(rows, dtype=np.float64), (np.array(firsts, dtype=np.int64) if int_first else None)


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True
