"""Types of the compiled generator kernels (generator/_sampler.c)."""

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
    seed: int,
    skip: int,
    /,
) -> tuple[bytearray, bytearray, bytearray, int]: ...
def walk(seed: int, n_steps: int, frag: int, retro: bool, /) -> tuple[bytearray, bytearray, bytearray, int]: ...
def headings(odom_ang: Any, /) -> tuple[bytearray, bytearray, bytearray]: ...
def cells(cx: Any, cy: Any, last: bool, max_cells: int, /) -> tuple[bytearray, int, bytearray, bytearray] | None: ...
def cos_sin(a: Any, /) -> tuple[bytearray, bytearray]: ...
def trajectory(
    turns: Any,
    npos: Any,
    nang: Any,
    frag: int,
    stepsize: float,
    std_pos: float,
    std_ang: float,
    th_tab: Any,
    dx_tab: Any,
    dy_tab: Any,
    turn_tab: Any,
    /,
) -> tuple[bytearray, bytearray, bytearray, bytearray, bytearray, bytearray]: ...
def grid_cells(x: Any, y: Any, frag: float, stepsize: float, /) -> tuple[bytearray, bytearray]: ...
def measurements(
    x_from: Any,
    y_from: Any,
    th_from: Any,
    i_from: Any,
    x_to: Any,
    y_to: Any,
    th_to: Any,
    i_to: Any,
    noise: Any,
    std_pos: float,
    std_ang: float,
    /,
) -> bytearray: ...
