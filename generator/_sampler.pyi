"""Types of the compiled loop-closure sampler (generator/_sampler.c)."""

from collections.abc import Callable
from typing import Any

def sample(
    probs: Any, uniforms: Any, h: int, d: int, cached: float | None, /
) -> tuple[bytearray, bytearray, int, int, float | None, bool]: ...
def closures(
    qx: Any,
    qy: Any,
    col_start: Any,
    col_y: Any,
    col_m: Any,
    x0: int,
    ylim: Any,
    colbase: Any,
    probs: Any,
    before_query: bool,
    head: Callable[[int], Any],
    cached: float | None,
    /,
) -> tuple[bytearray, bytearray, bytearray, int, float | None]: ...
