"""Constants and shared defaults, each defined once (names carry their units)."""

from __future__ import annotations

__all__ = ["NS_PER_S", "DEFAULT_MAX_MEMORY_GB", "DEFAULT_MAX_OUTPUT_GB"]

#: Nanoseconds per second: timestamps are int64 nanoseconds inside the studio.
NS_PER_S = 1_000_000_000

#: Default memory limit [GB] of the commands that estimate their memory before working.
DEFAULT_MAX_MEMORY_GB = 8.0
#: Default limit [GB] of what ``studio synth`` may write.
DEFAULT_MAX_OUTPUT_GB = 20.0
