"""kollagen's loop-closure search: candidates in its visiting order, sampled in bulk.

Candidates ("hits": an occupied grid cell inside the discrete circle around a pose) are enumerated
with a sorted-cell search (O(N + hits) instead of kollagen's O(N * R^2) map look-ups) and put in the
exact order kollagen visits them. Each hit consumes one uniform; between two accepted loop closures
the uniforms sit at fixed stream positions, so the unlikely hits are decided in bulk with numpy and
only the likely ones and the accepted ones (with their three normals) go through Python.

Where the studio was installed with a C compiler, the search and the sampling run as one compiled
pass instead (``closures`` in generator/_sampler.c, through :func:`_compiled_search`): the same hits
in the same order, each decided as it is found, no list of hits; the numpy and Python code stays as
the path without a compiler and as the reference the tests hold the kernel to.
"""

from __future__ import annotations

import functools
import math
from bisect import bisect_left
from collections.abc import Callable, Iterator, Sequence

import numpy as np

from studio.core.geometry import libm_cos_sin, relative_planar_pose
from studio.core.model import Edges, InterAgentEdges, PoseKind
from studio.generator.config import AgentConfig, SynthConfig
from studio.generator.rng import MT19937Stream, UniformTape, polar_normal
from studio.generator.walk import _round_half_away, _round_to_int, _Walk

try:  # the compiled kernels (pyproject.toml declares them; built where a C compiler is found)
    from studio.generator._sampler import cells as _compiled_cells
    from studio.generator._sampler import closures as _compiled_closures
    from studio.generator._sampler import cos_sin as _compiled_cos_sin
    from studio.generator._sampler import grid_cells as _compiled_grid_cells
    from studio.generator._sampler import measurements as _compiled_measurements
    from studio.generator._sampler import sample as _compiled_sample
except ImportError:  # no compiler at install: numpy and Python (the same bytes; tests run both)
    _compiled_measurements = None  # type: ignore[assignment]
    _compiled_sample = None  # type: ignore[assignment]
    _compiled_closures = None  # type: ignore[assignment]
    _compiled_cells = None  # type: ignore[assignment]
    _compiled_cos_sin = None  # type: ignore[assignment]
    _compiled_grid_cells = None  # type: ignore[assignment]


def _cos_sin(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """libm's cos and sin of ``theta``: one compiled loop, or :func:`libm_cos_sin` without the kernel."""
    if _compiled_cos_sin is None:
        return libm_cos_sin(theta)
    c, s = _compiled_cos_sin(np.ascontiguousarray(theta, dtype=np.float64))
    return np.frombuffer(c, dtype=np.float64), np.frombuffer(s, dtype=np.float64)


__all__ = ["discrete_circle", "agent_pairs", "intra_loop_closures"]


def discrete_circle(radius: int) -> np.ndarray:
    """kollagen's ``DiscreteCircle``: ``(k, 2)`` integer offsets in its iteration order.

    x runs from -radius to radius; for each x, y takes 0, 1, -1, 2, -2, ... while y^2 <= r^2 - x^2.
    """
    xs = np.arange(-radius, radius + 1, dtype=np.int64)
    ylim = np.array([math.isqrt(radius * radius - x * x) for x in xs.tolist()], dtype=np.int64)
    counts = 2 * ylim + 1
    x = np.repeat(xs, counts)
    k = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    y = (k + 1) // 2 * np.where(k % 2 == 1, 1, -1)
    return np.column_stack([x, y])


def agent_pairs(n: int) -> list[tuple[int, int]]:
    """The pairs kollagen's ``get_all_pairs`` yields (lexicographic), for n >= 2."""
    return [(a, b) for a in range(n) for b in range(a + 1, n)]


# --------------------------------------------------------------------------------------------------
# Loop-closure candidates and their sampling


def _grid_cells(x: np.ndarray, y: np.ndarray, cfg: SynthConfig) -> tuple[np.ndarray, np.ndarray]:
    frag, stepsize = float(cfg.step_fragment), cfg.stepsize
    if _compiled_grid_cells is not None:
        cx, cy = _compiled_grid_cells(
            np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(y, dtype=np.float64), frag, stepsize
        )
        return np.frombuffer(cx, dtype=np.int64), np.frombuffer(cy, dtype=np.int64)
    return _round_half_away(x * frag / stepsize), _round_half_away(y * frag / stepsize)


class _CircleTable:
    """kollagen's discrete circle: the rank of each offset in its visiting order.

    Rank -1 is the same-cell check that comes before the circle; ranks 0.. follow ``DiscreteCircle``
    (the centre offset itself is skipped there).
    """

    def __init__(self, radius: int) -> None:
        self.radius = radius
        circle = discrete_circle(radius)
        size = 2 * radius + 1
        self.rank = np.full((size, size), -2, dtype=np.int64)
        self.rank[circle[:, 0] + radius, circle[:, 1] + radius] = np.arange(len(circle))
        self.rank[radius, radius] = -1
        self.rank32 = self.rank.astype(np.int32)
        self.size = len(circle)
        #: squared offset length and "diagonal or centre" per rank + 1
        d2 = np.zeros(self.size + 1, dtype=np.int64)
        d2[1:] = circle[:, 0] ** 2 + circle[:, 1] ** 2
        self.d2_by_rank = d2
        diag = np.ones(self.size + 1, dtype=bool)
        diag[1:] = (circle[:, 0] != 0) & (circle[:, 1] != 0)
        self.diagonal_by_rank = diag
        self.ylim = np.array(
            [math.isqrt(radius * radius - dx * dx) for dx in range(-radius, radius + 1)], dtype=np.int64
        )
        #: the circle rank of each column's (dx, 0) offset, the first the circle visits in it
        self.colbase = np.cumsum(2 * self.ylim + 1) - (2 * self.ylim + 1)

    def probabilities(self, same_cell: float, scale: float, radius_m: float) -> np.ndarray:
        """Probability per rank + 1: ``same_cell`` for the same-cell check, else kollagen's
        ``scale * exp(-5 (dx^2 + dy^2) / r^2)`` (offsets in cells, radius in metres). Read-only:
        tables of the same arguments are made once (a small dataset would spend a tenth of its
        time on them)."""
        return _probabilities(self.radius, float(same_cell), float(scale), float(radius_m))

    @staticmethod
    def of_radius(radius: int) -> _CircleTable:
        """The table of ``radius``, made once per process (read-only)."""
        return _circle_table(radius)


@functools.lru_cache(maxsize=64)
def _circle_table(radius: int) -> _CircleTable:
    table = _CircleTable(radius)
    for v in (table.rank, table.rank32, table.d2_by_rank, table.diagonal_by_rank, table.ylim, table.colbase):
        v.setflags(write=False)
    return table


@functools.lru_cache(maxsize=256)
def _probabilities(radius: int, same_cell: float, scale: float, radius_m: float) -> np.ndarray:
    d2 = _circle_table(radius).d2_by_rank
    # math.exp per value: numpy's exp may differ from libm's in the last bit
    p = np.array([scale * math.exp(-5.0 * v / (radius_m * radius_m)) for v in d2.tolist()])
    p[0] = same_cell
    p.setflags(write=False)
    return p


def _visits(cx: np.ndarray, cy: np.ndarray, which: str) -> np.ndarray:
    """For each distinct grid cell, the index of its ``"first"`` or ``"last"`` visit (kollagen's
    intra-agent map keeps the first visit, its inter-agent map the last)."""
    key = (cx - cx.min()) * (int(cy.max() - cy.min()) + 1) + (cy - cy.min())
    if which == "first":
        return np.unique(key, return_index=True)[1]
    return len(key) - 1 - np.unique(key[::-1], return_index=True)[1]


_MAX_COLUMNS = 1 << 24
"""The widest table (in grid columns) the compiled search lays out; a wider one takes numpy's."""


def _columns(cx: np.ndarray, cy: np.ndarray, visits: np.ndarray) -> tuple[int, np.ndarray, np.ndarray] | None:
    """The table cells ``visits`` (in cell order, as :func:`_visits` gives them) by grid column for the
    compiled search: ``(x0, col_start, col_y)``, column ``x - x0`` holding ``col_start[x - x0]`` ..
    ``col_start[x - x0 + 1] - 1``; or None when the table spans more than :data:`_MAX_COLUMNS`."""
    tx = cx[visits]
    x0 = int(tx[0])
    width = int(tx[-1]) - x0 + 1
    if width > _MAX_COLUMNS:
        return None
    col_start = np.zeros(width + 1, dtype=np.int64)
    np.cumsum(np.bincount(tx - x0, minlength=width), out=col_start[1:])
    return x0, col_start, np.ascontiguousarray(cy[visits], dtype=np.int64)


_MAX_GRID_CELLS = 1 << 24
"""The largest bounding box (in grid cells) the compiled cell table lays a walk's visits out in."""


def _visited_columns(
    cx: np.ndarray, cy: np.ndarray, which: str
) -> tuple[np.ndarray, tuple[int, np.ndarray, np.ndarray] | None]:
    """:func:`_visits` of a walk's cells and, where the compiled search runs, the same cells by column
    (:func:`_columns`); both in one compiled pass over a grid of the walk's bounding box where that box
    is small next to the walk (``cells`` in generator/_sampler.c)."""
    if _compiled_cells is not None and _compiled_closures is not None:
        cap = min(_MAX_GRID_CELLS, max(1 << 16, 64 * len(cx)))
        got = _compiled_cells(
            np.ascontiguousarray(cx, dtype=np.int64), np.ascontiguousarray(cy, dtype=np.int64), which == "last", cap
        )
        if got is not None:
            visits_b, x0, col_start, col_y = got
            return np.frombuffer(visits_b, dtype=np.int64), (
                x0,
                np.frombuffer(col_start, dtype=np.int64),
                np.frombuffer(col_y, dtype=np.int64),
            )
    visits = _visits(cx, cy, which)
    return visits, _columns(cx, cy, visits) if _compiled_closures is not None else None


def _compiled_search(
    qx: np.ndarray,
    qy: np.ndarray,
    table: tuple[int, np.ndarray, np.ndarray],
    table_pose: np.ndarray,
    circle: _CircleTable,
    prob_by_rank: np.ndarray,
    before_query: bool,
    seed: int,
    skip: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The hit search and :func:`_sample` in one compiled pass (``closures`` in
    ``generator/_sampler.c``), reading the uniforms of ``std::mt19937(seed)`` from word ``skip`` on
    (the kernel runs the same Mersenne Twister as :class:`MT19937Stream`): the accepted hits' queries
    and table poses, their ``(n, 3)`` normals and the uniforms used. NaN probabilities and, with
    ``before_query``, table poses not before the query are no candidates."""
    x0, col_start, col_y = table
    k, m, normals, used = _compiled_closures(
        np.ascontiguousarray(qx, dtype=np.int64),
        np.ascontiguousarray(qy, dtype=np.int64),
        col_start,
        col_y,
        np.ascontiguousarray(table_pose, dtype=np.int64),
        x0,
        circle.ylim,
        circle.colbase,
        np.ascontiguousarray(prob_by_rank, dtype=np.float64),
        before_query,
        seed,
        skip,
    )
    return (
        np.frombuffer(k, dtype=np.int64),
        np.frombuffer(m, dtype=np.int64),
        np.frombuffer(normals, dtype=np.float64).reshape(-1, 3),
        used,
    )


_DENSE_COUNT_FACTOR = 32
""":func:`_enumerate_hits` counts keys with a table over the whole key space when that space is at most
this many times the number of its look-ups (then a table entry is far cheaper than a binary search)."""


def _count_below(sorted_keys: np.ndarray, space: int, lookups: int) -> Callable[[np.ndarray], np.ndarray]:
    """``v -> the number of sorted_keys below v`` for integer arrays v in ``[0, space]``."""
    if space <= _DENSE_COUNT_FACTOR * lookups:
        below = np.zeros(space + 1, dtype=np.int64)
        np.cumsum(np.bincount(sorted_keys, minlength=space), out=below[1:])
        return lambda v: below[v]
    return lambda v: np.searchsorted(sorted_keys, v, side="left")


def _hit_layout(
    qx: np.ndarray, qy: np.ndarray, tx: np.ndarray, ty: np.ndarray, circle: _CircleTable
) -> _HitLayout | None:
    """Where every hit of :func:`_enumerate_hits` comes from and where it goes, or None without hits.

    Returns a :class:`_HitLayout`: the table sorted by key is ``order``; query q's hits start at place
    ``query_first[q]``; its blocks give, for hit e (in the order the ranges are laid end to end), the
    sorted-table entry ``pos[e]``, the flat circle offset ``offset[e]`` (``(dx + R) (2R + 1) + dy +
    R``) and the place ``dest[e]`` in kollagen's visiting order.

    Cells become keys ``x * stride + y``, so each (query, circle column dx) pair is one range of the
    sorted table keys; the ranges laid end to end give the hits by query, column and dy. The circle
    visits a column's dy as 0, 1, -1, 2, -2, ...: a hit's place in its column is found by counting the
    keys between it and its mirror image (``dy -> -dy``), and the same-cell hit moves to the front of
    its query; so the hits are scattered straight to their places, without a sort.
    """
    R = circle.radius
    nq = len(qx)
    if len(tx) == 0 or nq == 0:
        return None
    xmin = min(int(qx.min()), int(tx.min())) - R
    ymin = min(int(qy.min()), int(ty.min())) - R
    stride = max(int(qy.max()), int(ty.max())) - ymin + R + 1
    width = max(int(qx.max()), int(tx.max())) + R - xmin + 1
    tkey = (tx - xmin) * stride + (ty - ymin)
    order = np.argsort(tkey)
    skey = tkey[order]
    below = _count_below(skey, width * stride, nq * (2 * R + 1))
    # one segment per (query, column): the keys of its column's cells within the circle
    centre = ((qx - xmin) * stride + (qy - ymin))[:, None] + np.arange(-R, R + 1, dtype=np.int64) * stride
    centre = centre.ravel()
    ylim = np.tile(circle.ylim, nq)
    start = below(centre - ylim)
    counts = below(centre + ylim + 1) - start
    first = np.cumsum(counts) - counts  # the segment's first hit
    total = int(first[-1] + counts[-1])
    if total == 0:
        return None
    shift = start - first  # hit e of a segment is sorted-table entry e + shift
    # the same-cell hit (column dx = 0, dy = 0) goes first in its query, before the columns dx < 0
    seg_first = first.reshape(nq, 2 * R + 1)
    query_first = seg_first[:, 0].copy()
    at = below(centre[R :: 2 * R + 1])
    same = below(centre[R :: 2 * R + 1] + 1) > at
    same_hit = (seg_first[:, R] + at - start[R :: 2 * R + 1])[same]
    seg_first[:, :R] += same[:, None]  # now the segment's first place
    # flat offset (dx + R) (2R + 1) + dy + R, with dy = key - centre
    column = np.tile(np.arange(2 * R + 1, dtype=np.int64) * (2 * R + 1) + R, nq)
    per_segment = (shift, counts, first, 2 * centre + 1, column - centre)
    return _HitLayout(order, skey, below, per_segment, query_first, same_hit, query_first[same], 2 * R + 1, total)


class _HitLayout:
    """:func:`_hit_layout`'s per-segment tables, expanded to per-hit columns a block of queries at a
    time (:meth:`blocks`), so that a block's dozen passes over its hits run in the CPU's cache."""

    def __init__(
        self,
        order: np.ndarray,
        skey: np.ndarray,
        below: Callable[[np.ndarray], np.ndarray],
        per_segment: tuple[np.ndarray, ...],
        query_first: np.ndarray,
        same_hit: np.ndarray,
        same_dest: np.ndarray,
        columns: int,
        total: int,
    ) -> None:
        self.order, self.query_first, self.total = order, query_first, total
        self._skey, self._below, self._per_segment = skey, below, per_segment
        self._same_hit, self._same_dest, self._columns = same_hit, same_dest, columns

    def blocks(self, max_hits: int) -> Iterator[tuple[int, int, np.ndarray, np.ndarray, np.ndarray]]:
        """``(h0, h1, pos, offset, dest)`` per block of whole queries holding about ``max_hits`` hits
        (a query with more is a block of its own): its hits ``h0 <= e < h1`` (in the order the
        ranges are laid end to end), which also fill places ``h0 .. h1 - 1`` of the visiting order."""
        qf = self.query_first
        starts = np.searchsorted(qf, np.arange(0, self.total, max_hits), side="right") - 1  # sorted
        # its distinct values (np.unique would import numpy.ma in every process of a team)
        cut = starts[np.r_[True, starts[1:] != starts[:-1]]].tolist() if len(starts) else []
        bounds = cut + [len(qf)]
        for q0, q1 in zip(bounds[:-1], bounds[1:]):
            s0, s1 = q0 * self._columns, q1 * self._columns
            h0 = int(qf[q0])
            h1 = int(qf[q1]) if q1 < len(qf) else self.total
            if h1 == h0:
                continue
            shift, counts, first, mirror, column = (v[s0:s1] for v in self._per_segment)
            pos = np.arange(h0, h1, dtype=np.int64) + np.repeat(shift, counts)  # index in skey
            key = self._skey[pos]
            # place in the column: with w the keys below the mirror bound c - dy + 1, a hit with dy > 0
            # has pos - w keys before it in the column's order, one with dy <= 0 (so w > pos) w - 1 - pos
            t = pos - self._below(np.repeat(mirror, counts) - key)
            dest = t ^ (t >> 63)  # t if t >= 0, else -t - 1
            dest += np.repeat(first, counts)
            i0, i1 = np.searchsorted(self._same_hit, [h0, h1])
            dest[self._same_hit[i0:i1] - h0] = self._same_dest[i0:i1]
            offset = np.repeat(column, counts) + key
            yield h0, h1, pos, offset, dest


_LAYOUT_BLOCK_HITS = 1 << 16
"""Hits per block of :meth:`_HitLayout.blocks` (each per-hit column then takes 512 KiB)."""

_SMALL_PAIRS = 1 << 17
"""At most this many (query, table) pairs: :func:`_small_hits` compares every pair at once, a dozen
numpy calls in all, instead of :func:`_hit_layout`'s sorted-cell search (whose per-call overhead
is most of the cost of a small dataset). The two give the same hits in the same order."""


def _pair_dtype(qx: np.ndarray, qy: np.ndarray, tx: np.ndarray, ty: np.ndarray) -> type[np.signedinteger] | None:
    """The integer type :func:`_small_hits` compares these cells in (32-bit for cells within
    ``2**15`` of each other, whose squared distances cannot overflow it; else 64-bit), or None when
    it cannot (few pairs but cells ``2**31`` or more apart: the sorted-cell search takes them)."""
    if len(qx) * len(tx) > _SMALL_PAIRS:
        return None
    if len(qx) == 0 or len(tx) == 0:
        return np.int64
    span = max(int(qx.max()), int(tx.max())) - min(int(qx.min()), int(tx.min()))
    span = max(span, max(int(qy.max()), int(ty.max())) - min(int(qy.min()), int(ty.min())))
    return np.int32 if span < 1 << 15 else np.int64 if span < 1 << 31 else None


def _small_hits(
    qx: np.ndarray,
    qy: np.ndarray,
    tx: np.ndarray,
    ty: np.ndarray,
    circle: _CircleTable,
    dtype: type[np.signedinteger],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_enumerate_hits` by comparing every (query, table) pair in ``dtype``
    (:func:`_pair_dtype`): ``(k, m, rank)`` in kollagen's visiting order (by query, then rank; table
    cells are distinct, so a query's ranks are too). The sort key is 32-bit where it fits."""
    R = circle.radius
    side = 2 * R + 1
    if len(qx) == 0 or len(tx) == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z, z
    dx = tx.astype(dtype)[None, :] - qx.astype(dtype)[:, None]
    dy = ty.astype(dtype)[None, :] - qy.astype(dtype)[:, None]
    flat = dx * side
    flat += dy  # the offset's flat index less the centre's (wraps only far outside the circle)
    dx *= dx
    dy *= dy
    dx += dy
    at = np.flatnonzero(dx <= R * R)  # the discrete circle: |dy| <= isqrt(R^2 - dx^2); by query, then table
    offsets = flat.ravel()[at] + (R * side + R)
    width = circle.size + 1
    if len(qx) * width >= 1 << 31:
        k, m = np.divmod(at, len(tx))
        rank = circle.rank.ravel()[offsets]
        order = np.argsort(k * width + rank + 1, kind="stable")
        return k[order], m[order], rank[order]
    # in 32 bits (pairs and keys fit): the key of a hit is query * width + rank + 1, from which the
    # sorted hits' queries and ranks come back by one division (fewer, narrower gathers)
    at32 = at.astype(np.int32)
    key = at32 // np.int32(len(tx))  # the query
    key *= np.int32(width)
    key += circle.rank32.ravel()[offsets]
    key += np.int32(1)
    order = np.argsort(key, kind="stable")  # the keys come by query already: a merge sort's best case
    key = key[order]
    k = key // np.int32(width)
    rank = key - k * np.int32(width)
    rank -= np.int32(1)
    m = at32[order]
    m -= k * np.int32(len(tx))
    return k, m, rank


def _enumerate_hits(
    qx: np.ndarray, qy: np.ndarray, tx: np.ndarray, ty: np.ndarray, circle: _CircleTable
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (query k, table m) pair whose cells are at most the circle's radius apart.

    Returns ``(k, m, rank)`` sorted in kollagen's visiting order: by query, then the same-cell check,
    then the circle's order. Table cells must be distinct. (See :func:`_hit_layout`; few pairs:
    :func:`_small_hits`.)
    """
    dtype = _pair_dtype(qx, qy, tx, ty)
    if dtype is not None:
        return _small_hits(qx, qy, tx, ty, circle, dtype)
    layout = _hit_layout(qx, qy, tx, ty, circle)
    if layout is None:
        z = np.zeros(0, dtype=np.int64)
        return z, z, z
    total = layout.total
    counts = np.diff(layout.query_first, append=total)
    k = np.repeat(np.arange(len(qx), dtype=np.int64), counts)
    m = np.empty(total, dtype=np.int64)
    rank = np.empty(total, dtype=np.int64)
    flat_rank = circle.rank.ravel()
    for _, _, pos, offset, dest in layout.blocks(_LAYOUT_BLOCK_HITS):
        m[dest] = layout.order[pos]
        rank[dest] = flat_rank[offset]
    return k, m, rank


class _Hits:
    """The hits of :func:`_enumerate_hits` as their probabilities, with (query, table) pairs read
    only for the hits asked for.

    Each hit keeps its sorted-table index and circle offset packed in one integer, so putting the hits
    in visiting order is one scatter; the (k, m) columns of every hit are never made.
    """

    def __init__(
        self,
        qx: np.ndarray,
        qy: np.ndarray,
        tx: np.ndarray,
        ty: np.ndarray,
        circle: _CircleTable,
        prob_by_rank: np.ndarray,
    ) -> None:
        self._small: tuple[np.ndarray, np.ndarray] | None = None
        dtype = _pair_dtype(qx, qy, tx, ty)
        if dtype is not None:  # few pairs: every hit's (k, m) is cheap to keep
            k, m, rank = _small_hits(qx, qy, tx, ty, circle, dtype)
            self._small = k, m
            self.probs = prob_by_rank[rank + 1]
            return
        layout = _hit_layout(qx, qy, tx, ty, circle)
        if layout is None:
            self.probs = np.zeros(0)
            return
        self._order, self._query_first = layout.order, layout.query_first
        bits = self._bits = (circle.rank.size - 1).bit_length()
        packed = self._packed = np.empty(layout.total, dtype=np.int64)
        self.probs = np.empty(layout.total)
        #: per flat offset: the probability of its rank (offsets outside the circle never occur)
        by_offset = prob_by_rank[circle.rank.ravel() + 1]
        for h0, h1, pos, offset, dest in layout.blocks(_LAYOUT_BLOCK_HITS):
            packed[dest] = (pos << bits) | offset
            self.probs[h0:h1] = by_offset[packed[h0:h1] & ((1 << bits) - 1)]

    def pairs(self, hits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(k, m)`` of the given hits (indices in visiting order)."""
        if len(hits) == 0:
            z = np.zeros(0, dtype=np.int64)
            return z, z
        if self._small is not None:
            return self._small[0][hits], self._small[1][hits]
        k = np.searchsorted(self._query_first, hits, side="right") - 1
        m = self._order[self._packed[hits] >> self._bits]
        return k, m


_VISIT_PROBABILITY = 0.1
"""Hits at least this likely are decided one by one in :func:`_sample`. Deciding one costs about a
tenth of the numpy scan that each acceptance among the others costs: the speed depends on it, never
the result."""

_SCAN_HITS = 1 << 14
"""The longest stretch of hits :func:`_sample` compares with its uniforms at once."""

_SPARE_UNIFORMS = 1024
"""Uniforms :func:`_sample` decodes beyond its estimate before it has to grow its buffer."""


def _sample(
    tape: UniformTape, probs: np.ndarray, cached: float | None
) -> tuple[np.ndarray, np.ndarray, float | None, int]:
    """Decide every hit with one uniform each, in order; an accepted hit draws three normals.

    Returns (accepted hit indices, (n, 3) normals, cache state after the last draw, uniforms used).
    The compiled kernel (``generator/_sampler.c``) where the build made it, else
    :func:`_sample_python`: the same decisions and the same normals bit for bit.
    """
    if _compiled_sample is None:
        return _sample_python(tape, probs, cached)
    n_hits = len(probs)
    probs = np.ascontiguousarray(probs, dtype=np.float64)
    # one uniform per hit plus about 3.8 per accepted hit for its normals
    want = n_hits + 4 * int(probs.sum()) + _SPARE_UNIFORMS
    h, d = 0, 0
    accepted: list[np.ndarray] = []
    normals: list[np.ndarray] = []
    while True:
        acc, nor, h, d, cached, complete = _compiled_sample(probs, tape.head(want)[:want], h, d, cached)
        accepted.append(np.frombuffer(acc, dtype=np.int64))
        normals.append(np.frombuffer(nor, dtype=np.float64))
        if complete:
            break
        want *= 2  # the uniforms ran out: go on from the last accepted hit with more
    if len(accepted) == 1:
        return accepted[0], normals[0].reshape(-1, 3), cached, n_hits + d
    return np.concatenate(accepted), np.concatenate(normals).reshape(-1, 3), cached, n_hits + d


def _sample_python(
    tape: UniformTape, probs: np.ndarray, cached: float | None
) -> tuple[np.ndarray, np.ndarray, float | None, int]:
    """:func:`_sample` in Python and numpy, where the compiled kernel was not built.

    kollagen accepts hit h when its probability exceeds the next uniform; each accepted hit then draws
    three normals (libstdc++'s polar method, one value cached between calls), which use a variable
    number of uniforms. Between two accepted hits, hit h therefore reads uniform ``h + d`` for one
    offset ``d``. The likely hits (same-cell checks) are few and accepted about every other time: they
    are decided one by one; the many unlikely hits up to the next likely acceptance are compared with
    their uniforms by one numpy scan. So each accepted hit costs one scan and a few Python steps.

    Returns (accepted hit indices, (n, 3) normals, cache state after the last draw, uniforms used).
    """
    n_hits = len(probs)
    visit = np.flatnonzero(probs >= _VISIT_PROBABILITY).tolist() + [n_hits]  # ends with a sentinel
    pv = np.ascontiguousarray(probs, dtype=np.float64).data  # indexing a memoryview gives floats fast
    scan_hits = _SCAN_HITS
    accepted: list[int] = []
    normals: list[float] = []
    h, d = 0, 0  # next hit, and the offset of its uniform
    iv = 0  # next hit to visit
    # one uniform per hit plus about 3.8 per accepted hit for its normals
    want = n_hits + 4 * int(probs.sum()) + _SPARE_UNIFORMS
    while True:
        u = tape.head(want)[:want]
        uv = u.data
        try:
            while h < n_hits:
                end = min(n_hits, h + scan_hits)
                if end + d > want:
                    raise IndexError  # these hits need uniforms beyond the buffer
                found = False
                while visit[iv] < end:
                    v = visit[iv]
                    if pv[v] > uv[v + d]:
                        end, found = v, True
                        break
                    iv += 1
                if end > h:
                    # the likely hits before end were just rejected with this offset: a scan of all
                    # hits finds the first unlikely one accepted
                    scan = probs[h:end] > u[h + d : end + d]
                    first = int(scan.argmax())
                    if scan[first]:
                        end, found = h + first, True
                if not found:
                    h = end
                    continue
                q = end + d + 1  # the normals start after the accepted hit's uniform
                if cached is None:
                    n1, n2, q = polar_normal(uv, q)
                    n3, keep, q = polar_normal(uv, q)
                else:
                    n1 = cached
                    n2, n3, q = polar_normal(uv, q)
                    keep = None
                accepted.append(end)
                normals += (n1, n2, n3)
                cached = keep
                h, d = end + 1, q - end - 1
                iv = bisect_left(visit, h)  # visits past a scanned acceptance are decided again
            break
        except IndexError:  # the buffer ended: grow it and go on from the last accepted hit
            want *= 2
    return np.array(accepted, dtype=np.int64), np.array(normals).reshape(-1, 3), cached, n_hits + d


def _intra_loop_closures(stream: MT19937Stream, walk: _Walk, cfg: SynthConfig, agent: AgentConfig) -> Edges:
    cx, cy = _grid_cells(walk.x, walk.y, cfg)
    n = len(cx)
    radius = _round_to_int(agent.intra_loop_closure_radius * cfg.step_fragment / cfg.stepsize)
    circle = _CircleTable.of_radius(radius)
    visits, columns = _visited_columns(cx, cy, "first")  # each cell's first visit, in cell order
    table = circle.probabilities(
        agent.same_position_intra_loop_closure_probability,
        agent.intra_loop_closure_probability_scaling,
        agent.intra_loop_closure_radius,
    )
    # kollagen's quirk: intra-agent loop closures only look at the diagonal circle offsets (and the
    # same cell); NaN marks the others, so one look-up gives a hit's probability or its exclusion
    allowed = np.where(circle.diagonal_by_rank, table, np.nan)
    if columns is not None:
        i_to, j_from, noise, used = _compiled_search(
            cx, cy, columns, visits, circle, allowed, True, stream.seed, stream.position
        )
        stream.advance(2 * used)
        return _intra_edges(walk, agent, i_to, j_from, noise)
    first = np.sort(visits)  # cells in order of their first visit
    # kollagen's map only holds cells first visited before the current pose. Poses are taken in
    # blocks; a block looks only at cells first visited before its end, so few hits are discarded.
    # Only the kept hits' probabilities and poses outlive their block (a block's hits take about ten
    # times as much memory, and fresh memory is what a cold process pays for most).
    probs, to_pose, from_pose = [], [], []
    # (a small walk is one block: its every (pose, cell) pair is compared at once)
    n_blocks = 1 if n * len(first) <= _SMALL_PAIRS else min(n, 16)
    bounds = np.linspace(0, n, num=n_blocks + 1).astype(np.int64)
    for lo, hi in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        # (one block: every cell, in cell order, which sorts its hits faster; the hits are the same)
        known = visits if n_blocks == 1 else first[: np.searchsorted(first, hi)]
        k, m, rank = _enumerate_hits(cx[lo:hi], cy[lo:hi], cx[known], cy[known], circle)
        p = allowed[rank + 1]
        m = known[m]  # the table entry's pose
        k += lo  # the query's pose
        kept = np.flatnonzero((m < k) & ~np.isnan(p))  # cells seen before, allowed offsets
        probs.append(p[kept])
        to_pose.append(k[kept])
        from_pose.append(m[kept])
        del k, m, rank, p, kept
    acc, noise, _, used = _sample(UniformTape(stream), np.concatenate(probs), None)
    stream.advance(2 * used)
    return _intra_edges(walk, agent, np.concatenate(to_pose)[acc], np.concatenate(from_pose)[acc], noise)


def _contiguous_f8(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _contiguous_i8(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


def _measurements(
    w_from: _Walk, i_from: np.ndarray, w_to: _Walk, i_to: np.ndarray, noise: np.ndarray, std_pos: float, std_ang: float
) -> np.ndarray:
    """``(n, 3)`` loop-closure measurements: pose ``i_to`` of ``w_to`` in the frame of pose ``i_from``
    of ``w_from`` (kollagen's order, :func:`~studio.core.geometry.relative_planar_pose`), plus the
    normals ``noise`` times the standard deviations; one compiled loop (``measurements`` in
    generator/_sampler.c) where the module was built."""
    if _compiled_measurements is not None:
        f8, i8 = _contiguous_f8, _contiguous_i8
        out = _compiled_measurements(
            f8(w_from.x), f8(w_from.y), f8(w_from.theta), i8(i_from),
            f8(w_to.x), f8(w_to.y), f8(w_to.theta), i8(i_to),
            f8(noise), std_pos, std_ang,
        )  # fmt: skip
        return np.frombuffer(out, dtype=np.float64).reshape(-1, 3)
    th_from = w_from.theta[i_from]
    dX, dY, dT = relative_planar_pose(
        w_from.x[i_from],
        w_from.y[i_from],
        th_from,
        w_to.x[i_to],
        w_to.y[i_to],
        w_to.theta[i_to],
        cos_sin_from=_cos_sin(th_from),
    )
    meas = np.column_stack([dX + noise[:, 0] * std_pos, dY + noise[:, 1] * std_pos, dT + noise[:, 2] * std_ang])
    return meas.reshape(-1, 3)


def _intra_edges(walk: _Walk, agent: AgentConfig, i_to: np.ndarray, j_from: np.ndarray, noise: np.ndarray) -> Edges:
    """The accepted intra-agent loop closures (pose ``j_from`` to ``i_to``) with their normals."""
    sp, sa = agent.std_dev_intra_loop_closure_position, agent.std_dev_intra_loop_closure_angle
    meas = _measurements(walk, j_from, walk, i_to, noise, sp, sa)
    info = _diag_information(
        len(i_to), agent.estimated_information_intra_position, agent.estimated_information_intra_angle
    )
    return Edges(PoseKind.SE2, j_from, i_to, meas, info)


class _InterPairs:
    """kollagen's inter-agent loop closures as one task per agent pair, for any process to run.

    ``pairs(i)`` computes pair ``i`` (of ``len(pairs)``, in kollagen's order) from the walks held at
    construction; :meth:`edges` puts the pairs' results together. The caller may run the tasks in
    forked processes, alongside other work (see :func:`studio.generator.kollagen.generate`).
    """

    def __init__(
        self, walks: Sequence[_Walk], cells: Sequence[tuple[np.ndarray, np.ndarray]], cfg: SynthConfig
    ) -> None:
        p = cfg.inter
        self._inter = p
        self._walks, self._cells = walks, cells
        radius = _round_to_int(p.loop_closure_radius * cfg.step_fragment / cfg.stepsize)
        self._circle = _CircleTable.of_radius(radius)
        self._prob_by_rank = self._circle.probabilities(
            p.same_position_loop_closure_probability, p.loop_closure_probability_scaling, p.loop_closure_radius
        )
        self._pairs = agent_pairs(len(walks))
        # kollagen seeds a new generator for every pair with the same seed: all pairs read one tape
        self._stream = MT19937Stream(p.random_number_generator_seed)
        self._tape = UniformTape(self._stream, owns=True)

    def __len__(self) -> int:
        return len(self._pairs)

    def release(self) -> None:
        """Hand the inter-agent stream's generator back (see :meth:`MT19937Stream.release`)."""
        self._stream.release()

    def __call__(self, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = self._inter
        a, b = self._pairs[index]
        wa, wb = self._walks[a], self._walks[b]
        (ax, ay), (bx, by) = self._cells[a], self._cells[b]
        # kollagen's map keeps the last visit of each cell of agent a
        last, columns = _visited_columns(ax, ay, "last")
        if columns is not None:
            i_from, j_to, noise, _ = _compiled_search(
                bx, by, columns, last, self._circle, self._prob_by_rank, False, self._stream.seed, 0
            )
        else:
            hits = _Hits(bx, by, ax[last], ay[last], self._circle, self._prob_by_rank)
            acc, noise, _, _ = _sample(self._tape, hits.probs, None)
            i_from, m = hits.pairs(acc)
            j_to = last[m]
        meas = _measurements(wb, i_from, wa, j_to, noise, p.std_dev_loop_closure_position, p.std_dev_loop_closure_angle)
        return np.full(len(i_from), b), i_from, np.full(len(i_from), a), j_to, meas

    def edges(self, done: Sequence[tuple[np.ndarray, ...]]) -> InterAgentEdges:
        """The pairs' results (in pair order) as kollagen's inter-agent loop closures."""
        p = self._inter
        cols = {c: [d[k] for d in done] for k, c in enumerate(("fa", "fi", "ta", "ti", "m"))}
        meas = np.concatenate(cols["m"])
        info = _diag_information(len(meas), p.estimated_information_position, p.estimated_information_angle)
        return InterAgentEdges(
            PoseKind.SE2,
            np.concatenate(cols["fa"]),
            np.concatenate(cols["fi"]),
            np.concatenate(cols["ta"]),
            np.concatenate(cols["ti"]),
            meas,
            info,
        )


def _diag_information(n: int, position: float, angle: float) -> np.ndarray:
    info = np.zeros((n, 6))
    info[:, 0] = position
    info[:, 3] = position
    info[:, 5] = angle
    return info


intra_loop_closures = _intra_loop_closures
