"""Numbers checked where they enter: option values refused with the option's name."""

from __future__ import annotations

import math

from studio.core.errors import ConfigError

__all__ = ["check_option", "LARGEST", "SMALLEST"]

#: Any length, time, sigma or limit beyond this is a typo, not a request (and overflows squares).
LARGEST = 1e9
#: Any positive value below this underflows the computations it feeds (e.g. ``--lc-radius 1e-300``).
SMALLEST = 1e-9


def check_option(option: str, value: float, *, allow_zero: bool = True) -> float:
    """``value`` if it is finite and 0 (when allowed) or within [SMALLEST, LARGEST]; else a
    one-line :class:`ConfigError` naming ``option``."""
    name = None if option.startswith("-") else option  # a library option: the CLI shows its flag
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ConfigError(f"{option}: expected a finite number >= 0, got {value!r}", option=name)
    if value == 0 and allow_zero:
        return value
    if not SMALLEST <= value <= LARGEST:
        raise ConfigError(
            f"{option}: {value!r} is outside {SMALLEST:g}..{LARGEST:g}" + (" (0 turns it off)" if allow_zero else ""),
            option=name,
        )
    return value
