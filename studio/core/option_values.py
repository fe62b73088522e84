"""Numbers checked where they enter: option values refused with the option's name."""

from __future__ import annotations

import math

from studio.core.errors import ConfigError
from studio.core.units import MAX_MAGNITUDE, MIN_MAGNITUDE

__all__ = ["check_option", "check_count", "MAX_COUNT"]

#: Largest whole-number option (ticks, iterations, seeds...): beyond it a value is a typo, and it
#: still fits every int64 the maths turns it into.
MAX_COUNT = 1_000_000_000


def check_option(option: str, value: float, *, allow_zero: bool = True) -> float:
    """``value`` if it is finite and 0 (when allowed) or within [MIN_MAGNITUDE, MAX_MAGNITUDE]; else a
    one-line :class:`ConfigError` naming ``option``."""
    name = None if option.startswith("-") else option  # a library option: the CLI shows its flag
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ConfigError(f"{option}: expected a finite number >= 0, got {value!r}", option=name)
    if value == 0 and allow_zero:
        return value
    if not MIN_MAGNITUDE <= value <= MAX_MAGNITUDE:
        raise ConfigError(
            f"{option}: {value!r} is outside {MIN_MAGNITUDE:g}..{MAX_MAGNITUDE:g}"
            + (" (0 turns it off)" if allow_zero else ""),
            option=name,
        )
    return value


def check_count(option: str, value: int, *, low: int = 1, high: int = MAX_COUNT) -> int:
    """``value`` if it is an integer (not a bool) in ``low..high``; else a one-line
    :class:`ConfigError` naming ``option`` (as :func:`check_option` names it)."""
    name = None if option.startswith("-") else option
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigError(f"{option}: expected an integer in {low}..{high}, got {value!r}", option=name)
    return value
