"""Numbers checked where they enter: option values refused with the option's name."""

from __future__ import annotations

import math

from studio.core.errors import ConfigError
from studio.core.units import MAX_MAGNITUDE, MIN_MAGNITUDE

__all__ = ["check_option"]


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
