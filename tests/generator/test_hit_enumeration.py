"""Loop-closure candidates in kollagen's visiting order, against a plain per-query circle walk."""

import numpy as np
import pytest

from studio.generator.loop_closures import _CircleTable, _enumerate_hits, _Hits, discrete_circle


def _plain_hits(qx, qy, tx, ty, radius):
    """kollagen's loop: per query, the same cell, then every circle offset in DiscreteCircle's order."""
    where = {(x, y): m for m, (x, y) in enumerate(zip(tx.tolist(), ty.tolist()))}
    offsets = [(dx, dy) for dx, dy in discrete_circle(radius).tolist() if (dx, dy) != (0, 0)]
    rank_of = {tuple(o): r for r, o in enumerate(discrete_circle(radius).tolist())}
    hits = []
    for k, (x, y) in enumerate(zip(qx.tolist(), qy.tolist())):
        if (x, y) in where:
            hits.append((k, where[(x, y)], -1))
        for dx, dy in offsets:
            if (x + dx, y + dy) in where:
                hits.append((k, where[(x + dx, y + dy)], rank_of[(dx, dy)]))
    return hits


@pytest.mark.parametrize("block_hits", [1 << 16, 1, 37])
@pytest.mark.parametrize("dense", [True, False, "small"])
@pytest.mark.parametrize("trial", range(6))
def test_hits_match_the_plain_circle_walk(trial, dense, block_hits, monkeypatch):
    # the sorted-cell search unless "small": then every (query, table) pair compared at once
    monkeypatch.setattr("studio.generator.loop_closures._SMALL_PAIRS", 1 << 40 if dense == "small" else -1)
    if not dense:  # the binary-search path used for sparse, far-flung cells
        monkeypatch.setattr("studio.generator.loop_closures._DENSE_COUNT_FACTOR", 0)
    # per-hit columns made a few queries at a time (one query per block with 1)
    monkeypatch.setattr("studio.generator.loop_closures._LAYOUT_BLOCK_HITS", block_hits)
    rng = np.random.default_rng(trial)
    radius = int(rng.integers(1, 7))
    side = int(rng.integers(3, 30))
    cells = rng.integers(-side, side, size=(int(rng.integers(1, 400)), 2))
    tx, ty = np.unique(cells, axis=0)[rng.permutation(len(np.unique(cells, axis=0)))].T
    qx, qy = rng.integers(-side - radius, side + radius, size=(2, int(rng.integers(1, 200))))
    n = min(len(qx[::3]), len(tx))
    qx[: 3 * n : 3], qy[: 3 * n : 3] = tx[:n], ty[:n]  # many same-cell hits

    k, m, rank = _enumerate_hits(qx, qy, tx, ty, _CircleTable(radius))

    want = _plain_hits(qx, qy, tx, ty, radius)
    assert len(want) > 0
    assert list(zip(k.tolist(), m.tolist(), rank.tolist())) == want


@pytest.mark.parametrize("block_hits", [1 << 16, 1, 37])
@pytest.mark.parametrize("small", [False, True])
@pytest.mark.parametrize("trial", range(6))
def test_packed_hits_give_the_same_probabilities_and_pairs(trial, small, block_hits, monkeypatch):
    monkeypatch.setattr("studio.generator.loop_closures._LAYOUT_BLOCK_HITS", block_hits)
    monkeypatch.setattr("studio.generator.loop_closures._SMALL_PAIRS", 1 << 40 if small else -1)
    rng = np.random.default_rng(100 + trial)
    radius = int(rng.integers(1, 7))
    side = int(rng.integers(3, 30))
    cells = np.unique(rng.integers(-side, side, size=(int(rng.integers(1, 400)), 2)), axis=0)
    tx, ty = cells[rng.permutation(len(cells))].T
    qx, qy = rng.integers(-side - radius, side + radius, size=(2, int(rng.integers(1, 200))))
    n = min(len(qx[::3]), len(tx))
    qx[: 3 * n : 3], qy[: 3 * n : 3] = tx[:n], ty[:n]
    circle = _CircleTable(radius)
    prob_by_rank = rng.random(circle.size + 1)

    k, m, rank = _enumerate_hits(qx, qy, tx, ty, circle)
    hits = _Hits(qx, qy, tx, ty, circle, prob_by_rank)

    assert hits.probs.tolist() == prob_by_rank[rank + 1].tolist()
    some = np.sort(rng.choice(len(k), size=min(len(k), 50), replace=False))
    hk, hm = hits.pairs(some)
    assert hk.tolist() == k[some].tolist() and hm.tolist() == m[some].tolist()
    assert [len(v) for v in hits.pairs(np.zeros(0, dtype=np.int64))] == [0, 0]


def test_no_table_or_no_query_gives_no_hits():
    one = np.array([0])
    none = np.array([], dtype=np.int64)
    for args in ((one, one, none, none), (none, none, one, one)):
        k, m, rank = _enumerate_hits(*args, _CircleTable(3))
        assert len(k) == len(m) == len(rank) == 0
        assert len(_Hits(*args, _CircleTable(3), np.ones(30)).probs) == 0


@pytest.mark.parametrize("far", [0, 40_000, 3_000_000_000])
def test_small_pair_search_equals_the_sorted_cell_search_near_and_far(far, monkeypatch):
    """The all-pairs search in 32-bit integers (cells close together) and in 64-bit ones (cells
    2**15 or more apart, where 32-bit squared distances would overflow) gives the sorted-cell
    search's hits."""
    rng = np.random.default_rng(7)
    cells = np.unique(rng.integers(-20, 20, size=(300, 2)), axis=0)
    cells[-1] += far  # one cell far away (no hit near it unless a query is there too)
    tx, ty = cells[rng.permutation(len(cells))].T
    qx, qy = rng.integers(-25, 25, size=(2, 150))
    qx[-1], qy[-1] = cells[-1] + 1  # a query beside the far cell
    circle = _CircleTable(5)
    monkeypatch.setattr("studio.generator.loop_closures._SMALL_PAIRS", -1)
    want = _enumerate_hits(qx, qy, tx, ty, circle)
    monkeypatch.setattr("studio.generator.loop_closures._SMALL_PAIRS", 1 << 40)
    got = _enumerate_hits(qx, qy, tx, ty, circle)
    assert all(a.tolist() == b.tolist() for a, b in zip(got, want))
    assert len(want[0]) > 1000
