"""One bounded number reader for the text and JSON formats.

Python's ``int()`` and ``float()`` accept more than the formats do: underscore digits (``1_0`` is
10 to Python, 1 to Swarm-SLAM's ``std::stoi``), integers of thousands of digits, ``nan``; JSON's
decoder gives booleans (a ``bool`` is an ``int`` to Python) and strings where numbers belong. Every
reader of a number from a file goes through these functions: plain decimal digits, within the
bounds the caller gives (by default the documented ones of :mod:`studio.core.units`), each failure
one :class:`FormatError` line naming ``where`` (``file:line`` or a JSON path).
"""

from __future__ import annotations

import math
import re
from typing import Any

from studio.core.errors import FormatError
from studio.core.units import MAX_MAGNITUDE

__all__ = ["text_int", "text_float", "json_int", "json_float", "INT64_MAX", "INT64_MIN"]

INT64_MIN, INT64_MAX = -(1 << 63), (1 << 63) - 1
_INT = re.compile(r"[+-]?[0-9]{1,40}")
_FLOAT = re.compile(r"[+-]?(?:[0-9]{1,400}(?:\.[0-9]{0,400})?|\.[0-9]{1,400})(?:[eE][+-]?[0-9]{1,5})?")


def _in_range(value: int | float, lo: int | float, hi: int | float, where: str, what: str) -> None:
    if not lo <= value <= hi:
        raise FormatError(f"{where}: {what} {value!r} is outside [{lo!r}, {hi!r}]")


def text_int(text: str, where: str, *, lo: int = INT64_MIN, hi: int = INT64_MAX, what: str = "integer") -> int:
    """The integer written as ``text`` (decimal digits, an optional sign; no underscore, no
    fraction), within ``lo..hi`` (int64 by default)."""
    t = text.strip()
    if not _INT.fullmatch(t):
        shown = t if len(t) <= 40 else f"{t[:20]}...({len(t)} characters)"
        raise FormatError(f"{where}: expected an integer (decimal digits) for the {what}, got {shown!r}")
    value = int(t)
    _in_range(value, lo, hi, where, what)
    return value


def text_float(text: str, where: str, *, bound: float = MAX_MAGNITUDE, what: str = "number") -> float:
    """The finite number written as ``text`` (decimal, optional exponent; no underscore, no
    ``nan``/``inf``), of magnitude at most ``bound``."""
    t = text.strip()
    if not _FLOAT.fullmatch(t):
        shown = t if len(t) <= 40 else f"{t[:20]}...({len(t)} characters)"
        raise FormatError(f"{where}: expected a decimal number for the {what}, got {shown!r}")
    value = float(t)
    if not math.isfinite(value) or abs(value) > bound:
        raise FormatError(f"{where}: {what} {t} is beyond {bound:g} in magnitude")
    return value


def json_int(value: Any, where: str, *, lo: int = INT64_MIN, hi: int = INT64_MAX, what: str = "integer") -> int:
    """``value`` from a decoded JSON document as an integer within ``lo..hi``: a JSON integer, or
    a float with no fraction (``3.0``); never a boolean, a string or a fractional number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FormatError(f"{where}: expected an integer, got {_kind(value)}")
    if isinstance(value, float):
        if not math.isfinite(value) or value != math.floor(value):
            raise FormatError(f"{where}: expected an integer, got {value!r}")
        if not lo <= value <= hi:
            raise FormatError(f"{where}: {what} {value!r} is outside [{lo!r}, {hi!r}]")
        value = int(value)
    _in_range(value, lo, hi, where, what)
    return value


def json_float(value: Any, where: str, *, bound: float = MAX_MAGNITUDE, what: str = "number") -> float:
    """``value`` from a decoded JSON document as a finite float of magnitude at most ``bound``:
    a JSON number (an integer of any length is compared exactly), never a boolean or a string."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FormatError(f"{where}: expected a number, got {_kind(value)}")
    if isinstance(value, int):
        if abs(value) > bound:  # exact: a 5000-digit integer never reaches float()
            raise FormatError(f"{where}: {what} {_short(value)} is beyond {bound:g} in magnitude")
        return float(value)
    if not math.isfinite(value) or abs(value) > bound:
        raise FormatError(f"{where}: {what} {value!r} is beyond {bound:g} in magnitude")
    return value


def _short(value: int) -> str:
    digits = len(str(abs(value))) if value.bit_length() < 10_000 else value.bit_length() * 30103 // 100_000
    return str(value) if digits <= 30 else f"of about {digits} digits"


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value[:40]!r}"
    kinds: dict[type, str] = {dict: "an object", list: "an array"}
    return kinds.get(type(value), type(value).__name__)
