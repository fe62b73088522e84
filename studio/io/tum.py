"""TUM trajectory text: ``timestamp tx ty tz qx qy qz qw`` per line.

Writing: whole-second timestamps are written with ``%.17g`` (``0``, ``1``, ... as kollagen writes
node indices); other timestamps exactly from their nanoseconds (``1634567890.123456789``). Other
numbers use ``%.17g``; a positive zero in tz, qx or qy is written ``0.0`` (kollagen's planar files).

Reading accepts space- or comma-separated columns, ``#`` comments and one header line, and returns
a :class:`~studio.core.trajectory.Trajectory` (int64 nanosecond stamps, normalised quaternions), or
with :func:`read_tum_rows` the rows in file order for a caller that sorts them itself.
"""

from __future__ import annotations

import io
import math
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import numpy as np

from studio.core.errors import FormatError
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import SE3_POSE_ZERO_LITERAL, _open_text, _row_norms
from studio.io.textfmt import (
    Field,
    Floats,
    Ints,
    TextColumn,
    concat,
    digit_matrix,
    float_columns,
    format_lines,
    int_column,
    literal,
    row_blocks,
    write_text,
)

__all__ = ["write_tum", "read_tum", "read_tum_rows", "tum_text", "format_stamps"]

_DECIMAL = re.compile(r"^([+-]?)(\d*)(?:\.(\d*))?$")


def format_stamps(stamps_ns: np.ndarray) -> TextColumn:
    """Timestamps in seconds: whole seconds as ``%.17g`` writes them, others with nine decimals."""
    stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
    if np.all(stamps_ns % NS_PER_S == 0):
        return float_columns((stamps_ns // NS_PER_S).astype(np.float64).reshape(-1, 1), ["%.17g"])[0]
    negative = stamps_ns < 0
    sec, frac = np.divmod(np.abs(stamps_ns), NS_PER_S)
    sign = TextColumn(np.where(negative, ord("-"), 0).astype(np.uint8).reshape(-1, 1), negative.astype(np.int64))
    decimals = TextColumn(digit_matrix(frac, 9), np.full(len(frac), 9, dtype=np.int64))
    return concat([sign, int_column(sec), literal("."), decimals])


def _stamp_field(stamps_ns: np.ndarray) -> Field:
    """:func:`format_stamps` as a field of :func:`~studio.io.textfmt.format_lines`."""
    if np.all(stamps_ns % NS_PER_S == 0):
        # whole seconds: %.17g writes an integral double below 1e17 as str(int) does (the seconds of
        # an int64 of nanoseconds are below 1e10), and integers are formatted faster
        return Ints(stamps_ns // NS_PER_S)
    return format_stamps(stamps_ns)


def _tum_pieces(traj: Trajectory) -> Iterator[np.ndarray]:
    """The text of a TUM file, a block of lines at a time (each made when asked for)."""
    poses, stamps = traj.poses_xyz_quat_xyzw, traj.stamps_ns
    for rows in row_blocks(len(stamps)):
        yield format_lines([_stamp_field(stamps[rows]), Floats(poses[rows], ["%.17g"] * 7, SE3_POSE_ZERO_LITERAL)])


def tum_text(traj: Trajectory) -> bytes:
    """The bytes of a TUM file."""
    return b"".join(piece.tobytes() for piece in _tum_pieces(traj))


def write_tum(target: PathLike | IO[str], traj: Trajectory) -> None:
    write_text(target, _tum_pieces(traj))


def _nanosecond_hint(token: str) -> str:
    """A hint for a stamp that reads as nanoseconds (EuRoC and TUM VI ``data.csv`` files, ROS stamps)."""
    digits = token.lstrip("+-")
    if digits.isdecimal() and len(digits) >= 16:
        return (
            f" ({token[:40]} looks like nanoseconds, TUM stamps are seconds; a EuRoC or TUM VI data.csv, "
            "whose quaternion is w x y z, is read by `studio convert euroc`)"
        )
    return ""


def _stamp_ns(token: str) -> int:
    if token.isdecimal():  # whole seconds (kollagen's node indices): the common case, fast
        return int(token) * NS_PER_S
    m = _DECIMAL.match(token)
    if m and (m.group(2) or m.group(3)):
        sign = -1 if m.group(1) == "-" else 1
        whole = int(m.group(2) or 0)
        frac = (m.group(3) or "")[:9].ljust(9, "0")
        return sign * (whole * NS_PER_S + int(frac))
    value = float(token)  # exponent notation
    if not np.isfinite(value):
        raise ValueError(token)
    return int(round(value * NS_PER_S))


def read_tum(source: PathLike | IO[str], *, name: str | None = None) -> Trajectory:
    """Parse a TUM file whose stamps increase; errors name ``file:line``.

    The trajectory is named ``name``, or after the file (its stem), or ``trajectory`` for a stream.
    """
    stamps, poses, where = _parse(source, require_increasing=True)
    if name is None:
        name = Path(source).stem if isinstance(source, (str, os.PathLike)) else "trajectory"
    return Trajectory.from_poses(name, stamps, poses, where)


def read_tum_rows(source: PathLike | IO[str]) -> tuple[np.ndarray, np.ndarray]:
    """``(stamps_ns, poses)`` of a TUM file in file order, even where the stamps do not increase (the
    caller sorts and de-duplicates them, see :func:`studio.core.trajectory.clean_trajectory`)."""
    stamps, poses, _ = _parse(source, require_increasing=False)
    return stamps, poses


def _parse(source: PathLike | IO[str], *, require_increasing: bool) -> tuple[np.ndarray, np.ndarray, str]:
    text, name = _open_text(source)
    fast = _read_tum_fast(text, require_increasing)
    if fast is not None:
        return fast[0], fast[1], name
    stamps: list[int] = []
    rows: list[list[float]] = []
    lines: list[int] = []
    seen_data = False
    for lineno, raw in enumerate(io.StringIO(text), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 8:
            if not seen_data and parts and not _looks_numeric(parts[0]):
                seen_data = True  # one header line
                continue
            raise FormatError(f"{name}:{lineno}: expected 8 columns (t x y z qx qy qz qw), found {len(parts)}")
        try:
            stamp = _stamp_ns(parts[0])
        except (ValueError, OverflowError):
            if not seen_data and not stamps and not _looks_numeric(parts[0]):
                seen_data = True  # a header, not a number such as `nan` or `inf`
                continue
            raise FormatError(f"{name}:{lineno}: timestamp {parts[0][:40]!r} is not a number") from None
        try:
            vals = [float(p) for p in parts[1:]]
        except ValueError:
            bad = next(p for p in parts[1:] if not _is_float(p))
            raise FormatError(f"{name}:{lineno}: {bad[:40]!r} is not a number") from None
        if not all(map(math.isfinite, vals)):
            raise FormatError(f"{name}:{lineno}: value is not finite")
        if not -(2**63) <= stamp < 2**63:
            raise FormatError(f"{name}:{lineno}: timestamp out of range{_nanosecond_hint(parts[0])}")
        seen_data = True
        stamps.append(stamp)
        rows.append(vals)
        lines.append(lineno)
    if not rows:
        raise FormatError(f"{name}: no poses")
    poses = np.array(rows, dtype=np.float64)
    norms = _row_norms(poses[:, 3:7])
    zero = np.flatnonzero(norms < 1e-9)
    if zero.size:
        raise FormatError(f"{name}:{lines[zero[0]]}: quaternion is zero")
    far = np.flatnonzero(np.abs(norms - 1.0) > 1e-12)
    if far.size:
        poses[far, 3:7] /= norms[far, None]
    st = np.array(stamps, dtype=np.int64)
    dec = np.flatnonzero(np.diff(st) <= 0) if require_increasing else np.zeros(0, dtype=np.int64)
    if len(dec):
        k = int(dec[0]) + 1
        raise FormatError(f"{name}:{lines[k]}: timestamps must increase")
    return st, poses, name


_FAST_MIN_CHARS = 1 << 18


def _read_tum_fast(text: str, require_increasing: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """Bulk parse of a large, regular file with pandas' C parser (exact: round-trip floats, stamps
    from their digits). Returns None when anything is irregular (exponent stamps, NaN, a wrong
    column count, a zero quaternion, ...) so that the line-by-line parser names the offending line.
    """
    if len(text) < _FAST_MIN_CHARS or text.count("#") != text.count("\n#") + text.startswith("#"):
        return None
    import pandas as pd

    skip = 0
    first = ""
    header = False
    for raw in io.StringIO(text):  # comments and at most one header line before the first data line
        line = raw.strip()
        if not line or line.startswith("#"):
            skip += 1
            continue
        tokens = line.replace(",", " ").split()
        if not tokens:  # a line of separators only: let the line parser name it
            return None
        if not _looks_numeric(tokens[0]):
            if header:
                return None
            header = True
            skip += 1
            continue
        first = line
        break
    # the C parser is fastest with a one-character separator; irregular spacing takes \s+
    if "," in first:
        sep = ","
    elif "  " in text or "\t" in text or " \n" in text:
        sep = r"\s+"
    else:
        sep = " "
    # pandas 3 parses floats exactly by default (and deprecates the option); pandas 2 needs round_trip
    exact = {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
    try:
        df = pd.read_csv(
            io.BytesIO(text.encode("utf-8")),
            sep=sep,
            header=None,
            comment="#",
            skiprows=skip,
            dtype={0: str},
            engine="c",
            **exact,
        )
    except (ValueError, pd.errors.ParserError):
        return None
    if df.shape[1] != 8 or len(df) == 0:
        return None
    try:
        poses = df.iloc[:, 1:].to_numpy(dtype=np.float64)
    except (ValueError, TypeError):
        return None
    if not np.isfinite(poses).all():
        return None
    stamps = _stamps_from_digits(df[0].to_numpy(dtype=str))
    if stamps is None:
        return None
    norms = _row_norms(poses[:, 3:7])
    if np.any(norms < 1e-9) or (require_increasing and np.any(np.diff(stamps) <= 0)):
        return None
    far = np.flatnonzero(np.abs(norms - 1.0) > 1e-12)
    if far.size:
        poses[far, 3:7] /= norms[far, None]
    return stamps, poses


_POW10 = 10 ** np.arange(19, dtype=np.int64)


def _stamps_from_digits(tokens: np.ndarray) -> np.ndarray | None:
    """Exact int64 nanoseconds of decimal tokens ``SSSSSSSSSS[.FFFFFFFFF...]`` (digits beyond the
    ninth decimal dropped, as the line parser does), vectorised over their bytes; None for anything
    else (signs, exponents, more than 10 whole digits, tokens over 32 characters)."""
    try:
        b = np.asarray(tokens).astype("S32")
    except UnicodeEncodeError:
        return None
    width = b.dtype.itemsize
    c = b.view(np.uint8).reshape(len(b), width)
    if c[:, -1].any():  # possibly truncated by the 32-byte width
        return None
    is_dot = c == ord(".")
    is_digit = (c >= ord("0")) & (c <= ord("9"))
    if not np.all(is_dot | is_digit | (c == 0)) or np.any(is_dot.sum(axis=1) > 1):
        return None
    length = np.count_nonzero(c, axis=1)
    dot = np.where(is_dot.any(axis=1), is_dot.argmax(axis=1), length)
    if np.any(length - (dot < length) == 0) or np.any(dot > 10) or np.any((dot == 10) & (c[:, 0] >= ord("9"))):
        return None
    out = np.zeros(len(b), dtype=np.int64)
    for i in range(min(width, 20)):  # whole digits (<= 10) and nine decimals lie in the first 20 bytes
        e = 9 + dot - i - (i < dot)
        use = is_digit[:, i] & (e >= 0)
        out += np.where(use, (c[:, i].astype(np.int64) - 48) * _POW10[np.clip(e, 0, 18)], 0)
    return out


def _is_float(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


def _looks_numeric(tok: str) -> bool:
    return _is_float(tok)
