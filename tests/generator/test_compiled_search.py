"""The compiled module generator/_sampler.c: the loop-closure search and sampler (``closures``) against
kollagen's plain loop (per query the same cell, then every circle offset; one uniform per candidate,
three normals per accepted one), the walk's draws and the dead-reckoned headings against the numpy
and Python code they replace, and whole datasets with the compiled kernels and without."""

import dataclasses
import math

import numpy as np
import pytest

from studio.generator import loop_closures, walk
from studio.generator.loop_closures import _CircleTable, _columns, _compiled_search, _visits, discrete_circle
from studio.generator.rng import MT19937Stream, UniformTape
from studio.synth import generate, load_synth_config
from tests.generator.test_sampling import _plain_sample

pytestmark = pytest.mark.skipif(
    loop_closures._compiled_closures is None, reason="the compiled kernels were not built (no C compiler)"
)


def _plain_closures(qx, qy, tx, ty, table_pose, radius, probs, before_query, u):
    """kollagen's loop, hit by hit, with probabilities by rank + 1 (NaN: not a candidate); its
    candidates decided by the plain sampler of tests/generator/test_sampling.py."""
    where = {(x, y): m for x, y, m in zip(tx.tolist(), ty.tolist(), table_pose.tolist())}
    circle = discrete_circle(radius).tolist()
    order = [(0, 0, 0)] + [(dx, dy, r + 1) for r, (dx, dy) in enumerate(circle) if (dx, dy) != (0, 0)]
    candidates = []  # (query, table pose, probability) in visiting order
    for k, (x, y) in enumerate(zip(qx.tolist(), qy.tolist())):
        for dx, dy, r in order:
            m = where.get((x + dx, y + dy))
            if m is not None and not math.isnan(probs[r]) and not (before_query and m >= k):
                candidates.append((k, m, probs[r]))
    accepted, normals, _, used = _plain_sample(u, [p for _, _, p in candidates], None)
    return [candidates[h][0] for h in accepted], [candidates[h][1] for h in accepted], normals, used


@pytest.mark.parametrize("before_query", [False, True])
@pytest.mark.parametrize("trial", range(10))
def test_closures_match_kollagens_plain_loop(trial, before_query):
    rng = np.random.default_rng(trial)
    radius = int(rng.integers(1, 8))
    side = int(rng.integers(2, 25))
    # a walk's cells (repeats, negative coordinates, gaps between columns); the table is its first
    # (or last) visit of each cell, as the generator's maps keep them
    walk = np.cumsum(rng.integers(-1, 2, size=(int(rng.integers(1, 600)), 2)), axis=0)
    walk = np.clip(walk, -side, side) + rng.integers(-3, 4, size=2) * side
    cx, cy = walk[:, 0].astype(np.int64), walk[:, 1].astype(np.int64)
    visits = _visits(cx, cy, "first" if before_query else "last")
    qx, qy = (cx, cy) if before_query else tuple(rng.integers(-side, side, size=(2, 300)) + walk[0][:, None])
    circle = _CircleTable(radius)
    probs = np.exp(-rng.random(circle.size + 1) * rng.choice([1.0, 5.0, 20.0]))
    probs[rng.random(len(probs)) < 0.3] = np.nan  # excluded offsets (kollagen's intra-agent diagonals)
    probs[0] = rng.choice([0.0, 0.5, 1.0])
    seed = int(rng.integers(0, 2**31))
    u = UniformTape(MT19937Stream(seed)).head(4 * len(qx) * (circle.size + 1) + 1000).tolist()

    want = _plain_closures(qx, qy, cx[visits], cy[visits], visits, radius, probs.tolist(), before_query, u)
    k, m, normals, used = _compiled_search(
        qx, qy, _columns(cx, cy, visits), visits, circle, probs, before_query, seed, 0
    )

    assert len(want[0]) > 0
    assert (k.tolist(), m.tolist(), normals.ravel().tolist(), used) == want  # bit for bit


@pytest.mark.parametrize("before_query", [False, True])
def test_closures_match_the_plain_loop_on_a_table_too_tall_for_counts(before_query):
    # two blobs of cells 10^8 cells apart: no table of counts per y (its bounding box is too tall);
    # each column is searched by bisection, in a map that grows with its queries for an agent's own
    rng = np.random.default_rng(42)
    walk = np.cumsum(rng.integers(-1, 2, size=(500, 2)), axis=0)
    walk[250:, 1] += 10**8
    cx, cy = walk[:, 0].astype(np.int64), walk[:, 1].astype(np.int64)
    visits = _visits(cx, cy, "first" if before_query else "last")
    circle = _CircleTable(3)
    probs = np.exp(-rng.random(circle.size + 1) * 3.0)
    probs[rng.random(len(probs)) < 0.3] = np.nan
    u = UniformTape(MT19937Stream(9)).head(100_000).tolist()
    want = _plain_closures(cx, cy, cx[visits], cy[visits], visits, 3, probs.tolist(), before_query, u)
    got = _compiled_search(cx, cy, _columns(cx, cy, visits), visits, circle, probs, before_query, 9, 0)
    assert len(want[0]) > 10
    assert (got[0].tolist(), got[1].tolist(), got[2].ravel().tolist(), got[3]) == want


def _one_cell_search(p_same_cell: float, n_queries: int = 50):
    """Queries that each see one candidate, the table's one cell in their own cell (probability
    ``p_same_cell``): the kernel and the plain loop on the stream of seed 5."""
    cx = cy = np.zeros(1, dtype=np.int64)
    visits = _visits(cx, cy, "last")
    qx = qy = np.zeros(n_queries, dtype=np.int64)
    circle = _CircleTable(2)
    probs = np.full(circle.size + 1, np.nan)
    probs[0] = p_same_cell
    u = UniformTape(MT19937Stream(5)).head(20 * n_queries).tolist()
    got = _compiled_search(qx, qy, _columns(cx, cy, visits), visits, circle, probs, False, 5, 0)
    want = _plain_closures(qx, qy, cx, cy, visits, 2, probs.tolist(), False, u)
    return (got[0].tolist(), got[1].tolist(), got[2].ravel().tolist(), got[3]), want, u[0]


@pytest.mark.parametrize("offset", [-(2.0**-60), "below", 0.0, "above", 2.0**-60])
def test_a_probability_within_a_word_of_its_uniform_is_decided_on_the_uniform(offset):
    # the kernel decides a candidate on its uniform's high word against the probability's
    # threshold, and on the decoded uniform only where that word cannot tell: probabilities equal
    # to the first candidate's uniform or one double / 2^-60 either side of it take that path
    u0 = _one_cell_search(0.5)[2]
    p = {"below": math.nextafter(u0, 0.0), "above": math.nextafter(u0, 1.0)}.get(offset, None)
    p = u0 + offset if p is None else p
    assert math.floor(p * 2**32) == math.floor(u0 * 2**32)  # the same high word: the slow path
    got, want, _ = _one_cell_search(p)
    assert got == want
    assert (0 in got[0]) == (p > u0)  # the first query accepted exactly when its probability is above


@pytest.mark.parametrize("p", [0.0, -0.0, -0.5, 1.0, 1.5, math.inf, 5e-324, 1.0 - 2.0**-53])
def test_probabilities_at_and_outside_the_unit_interval(p):
    got, want, _ = _one_cell_search(p, 200)
    assert got == want
    if p <= 0:
        assert got[0] == []
    if p >= 1:  # every uniform is below 1: every query accepted
        assert got[0] == list(range(200))


def test_closures_read_the_stream_past_many_windows():
    # many candidates: the kernel decodes its stream's uniforms a window at a time
    cx = np.repeat(np.arange(40, dtype=np.int64), 40)
    cy = np.tile(np.arange(40, dtype=np.int64), 40)
    visits = _visits(cx, cy, "last")
    circle = _CircleTable(6)
    probs = np.full(circle.size + 1, 0.3)
    k, m, normals, used = _compiled_search(cx, cy, _columns(cx, cy, visits), visits, circle, probs, False, 3, 0)
    u = UniformTape(MT19937Stream(3)).head(used + 10).tolist()
    assert used > 100_000  # many windows of the kernel's uniforms
    assert (k.tolist(), m.tolist(), normals.ravel().tolist(), used) == _plain_closures(
        cx, cy, cx[visits], cy[visits], visits, 6, probs.tolist(), False, u
    )


@pytest.mark.parametrize("bad", ["probs", "col_start", "dtype"])
def test_closures_refuse_inconsistent_tables(bad):
    cx = np.arange(10, dtype=np.int64)
    visits = _visits(cx, cx, "last")
    x0, col_start, col_y = _columns(cx, cx, visits)
    circle = _CircleTable(3)
    probs = np.full(circle.size + 1, 0.5)
    args = [
        cx,
        cx,
        col_start,
        col_y,
        visits,
        x0,
        circle.ylim,
        circle.colbase,
        probs,
        False,
        1,
        0,
    ]
    if bad == "probs":
        args[8] = probs[:-1]
    elif bad == "col_start":
        args[2] = col_start[:-1]
    else:
        args[3] = col_y.astype(np.int32)
    with pytest.raises((ValueError, TypeError)):
        loop_closures._compiled_closures(*args)


def _arrays(graph):
    out = []
    for a in graph.agents:
        out += [a.initial, a.ground_truth, a.odometry.from_index, a.odometry.to_index, a.odometry.measurements]
        out += [a.loop_closures.from_index, a.loop_closures.to_index, a.loop_closures.measurements]
        out += [a.loop_closures.information_upper]
    i = graph.inter
    return out + [i.from_agent, i.from_index, i.to_agent, i.to_index, i.measurements, i.information_upper]


@pytest.mark.parametrize("radius_m", [1.0, 2.5, 5.0, 9.0])
def test_datasets_are_the_same_with_and_without_the_compiled_kernels(radius_m, monkeypatch):
    base = load_synth_config("tests/data/configs/small3x100.json")
    agents = tuple(
        dataclasses.replace(a, intra_loop_closure_radius=radius_m, same_position_intra_loop_closure_probability=0.7)
        for a in base.agents
    )
    cfg = dataclasses.replace(base, agents=agents, inter=dataclasses.replace(base.inter, loop_closure_radius=radius_m))
    for seed in range(3):
        compiled = _arrays(generate(cfg, seed=seed))
        with monkeypatch.context() as patch:
            patch.setattr(loop_closures, "_compiled_closures", None)
            patch.setattr(loop_closures, "_compiled_sample", None)
            patch.setattr(loop_closures, "_compiled_cells", None)
            patch.setattr(walk, "_compiled_walk", None)
            patch.setattr(walk, "_compiled_headings", None)
            patch.setattr(walk, "_compiled_trajectory", None)
            patch.setattr(loop_closures, "_compiled_cos_sin", None)
            patch.setattr(loop_closures, "_compiled_grid_cells", None)
            patch.setattr(loop_closures, "_compiled_measurements", None)
            plain = _arrays(generate(cfg, seed=seed))
        assert sum(len(v) for v in compiled[-6:]) > 0  # inter-agent closures were drawn
        assert len(compiled) == len(plain)
        for a, b in zip(compiled, plain):
            assert a.dtype == b.dtype and np.array_equal(a, b)  # every bit (no NaN in a dataset)


@pytest.mark.parametrize("trial", range(4))
def test_measurements_match_the_numpy_path(trial, monkeypatch):
    # headings far outside (-pi, pi], differences at the wrap (odd multiples of pi), walks of other
    # lengths, noise of any size: the compiled loop gives the numpy code's bits
    rng = np.random.default_rng(trial)

    def a_walk(n):
        theta = rng.choice([-3, -1, 1, 3, 101], size=n) * math.pi + rng.choice([0.0, 1e-12, 0.3], size=n)
        return walk._Walk(rng.normal(0, 50, n), rng.normal(0, 50, n), theta, np.zeros(n - 1, dtype=np.int64),
                          np.zeros(n - 1), np.zeros(n - 1))  # fmt: skip

    wf, wt = a_walk(300), a_walk(200)
    i_from, i_to = rng.integers(0, 300, 1000), rng.integers(0, 200, 1000)
    noise = rng.normal(0, 3, (1000, 3))
    got = loop_closures._measurements(wf, i_from, wt, i_to, noise, 0.1, 0.02)
    monkeypatch.setattr(loop_closures, "_compiled_measurements", None)
    want = loop_closures._measurements(wf, i_from, wt, i_to, noise, 0.1, 0.02)
    assert got.shape == (1000, 3) and np.array_equal(got, want)
    assert np.abs(got[:, 2] - noise[:, 2] * 0.02).max() <= math.pi + 1e-9  # the angle wrapped


def test_measurements_refuse_a_pose_out_of_range():
    w = walk._Walk(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(2, dtype=np.int64), np.zeros(2), np.zeros(2))
    with pytest.raises(IndexError, match="out of range"):
        loop_closures._measurements(w, np.array([0, 3]), w, np.array([1, 2]), np.zeros((2, 3)), 1.0, 1.0)


@pytest.mark.parametrize("skip", [1, 2, 3, 625, 1249])
def test_closures_read_the_stream_from_any_word(skip):
    # an agent's walk reads an odd number of words now and then (its integer draws take one each):
    # the intra-agent search's uniforms are the word pairs from there
    rng = np.random.default_rng(skip)
    walk = np.cumsum(rng.integers(-1, 2, size=(400, 2)), axis=0)
    cx, cy = walk[:, 0].astype(np.int64), walk[:, 1].astype(np.int64)
    visits = _visits(cx, cy, "first")
    circle = _CircleTable(4)
    probs = np.full(circle.size + 1, 0.2)
    stream = MT19937Stream(-7)
    stream.advance(skip)
    u = UniformTape(stream).head(200_000).tolist()
    got = _compiled_search(cx, cy, _columns(cx, cy, visits), visits, circle, probs, True, -7, skip)
    want = _plain_closures(cx, cy, cx[visits], cy[visits], visits, 4, probs.tolist(), True, u)
    assert len(want[0]) > 10
    assert (got[0].tolist(), got[1].tolist(), got[2].ravel().tolist(), got[3]) == want


def test_a_stream_advanced_past_its_drawn_words_reads_on_from_there():
    stream = MT19937Stream(11)
    stream.words(3)  # a block drawn
    stream.advance(10_000)  # another reader (the compiled search) read far past it
    assert np.array_equal(stream.words(5), MT19937Stream(11).words(10_005)[10_000:])


@pytest.mark.parametrize("frag", [1, 3, 4])
@pytest.mark.parametrize("retro", [False, True])
@pytest.mark.parametrize("seed", [0, 1, -5, 2**31 - 1])
def test_walk_draws_are_the_python_draws(seed, retro, frag, monkeypatch):
    n_steps = 700
    got_stream = MT19937Stream(seed)
    got = walk._walk_draws(got_stream, n_steps, frag, retro)
    monkeypatch.setattr(walk, "_compiled_walk", None)
    want_stream = MT19937Stream(seed)
    want = walk._walk_draws(want_stream, n_steps, frag, retro)
    assert got_stream.position == want_stream.position > 5 * n_steps * frag
    assert set(got[0].tolist()) == ({-1, 0, 1, 2} if retro else {-1, 0, 1})
    for a, b in zip(got, want):
        assert a.dtype == b.dtype and a.tolist() == b.tolist()  # bit for bit
    # the stream goes on from where the walk left it
    assert np.array_equal(got_stream.words(8), want_stream.words(8))


def test_headings_are_the_python_recurrence(monkeypatch):
    rng = np.random.default_rng(4)
    odom_ang = np.concatenate([rng.normal(0, 0.3, 3000), rng.choice([-np.pi / 2, 0.0, np.pi / 2, np.pi], 3000)])
    odom_ang[::7] += rng.normal(0, 20.0, len(odom_ang[::7]))  # far outside (-pi, pi]
    odom_pos = rng.random(len(odom_ang))
    got = walk._dead_reckon(odom_pos, odom_ang)
    monkeypatch.setattr(walk, "_compiled_headings", None)
    want = walk._dead_reckon(odom_pos, odom_ang)
    assert np.abs(got[2]).max() <= np.pi
    for a, b in zip(got, want):
        assert a.tolist() == b.tolist()  # bit for bit


@pytest.mark.parametrize("which", ["first", "last"])
@pytest.mark.parametrize("trial", range(6))
def test_cells_are_the_visits_by_column(trial, which):
    rng = np.random.default_rng(50 + trial)
    steps = rng.integers(-1, 2, size=(int(rng.integers(1, 3000)), 2))
    walk_cells = np.cumsum(steps, axis=0) + rng.integers(-(10**6), 10**6, size=2)
    cx, cy = np.ascontiguousarray(walk_cells.T, dtype=np.int64)
    visits, x0, col_start, col_y = loop_closures._compiled_cells(cx, cy, which == "last", 1 << 24)
    want = _visits(cx, cy, which)
    assert np.frombuffer(visits, dtype=np.int64).tolist() == want.tolist()
    wx0, wstart, wy = _columns(cx, cy, want)
    assert x0 == wx0
    assert np.frombuffer(col_start, dtype=np.int64).tolist() == wstart.tolist()
    assert np.frombuffer(col_y, dtype=np.int64).tolist() == wy.tolist()
    assert loop_closures._compiled_cells(cx, cy, which == "last", 0) is None  # a box too big for the grid


def test_cos_sin_are_libms():
    a = np.random.default_rng(1).normal(0, 10, 5000)
    c, s = loop_closures._compiled_cos_sin(a)
    assert np.frombuffer(c, dtype=np.float64).tolist() == [math.cos(v) for v in a.tolist()]
    assert np.frombuffer(s, dtype=np.float64).tolist() == [math.sin(v) for v in a.tolist()]


@pytest.mark.parametrize("stepsize", [1.0, 0.3, 2.5])
@pytest.mark.parametrize("frag", [1, 4, 7])
@pytest.mark.parametrize("retro", [False, True])
def test_walks_are_the_python_walks(retro, frag, stepsize, monkeypatch):
    base = load_synth_config("tests/data/configs/small3x100.json")
    cfg = dataclasses.replace(
        base, step_fragment=frag, stepsize=stepsize, allow_retrocession=retro, number_of_steps=300
    )
    agent = dataclasses.replace(cfg.agents[0], std_dev_position=0.07, std_dev_angle=0.003)
    got = walk._random_walk(MT19937Stream(41), cfg, agent)
    monkeypatch.setattr(walk, "_compiled_trajectory", None)
    want = walk._random_walk(MT19937Stream(41), cfg, agent)
    assert len(set(got.delta_theta.tolist())) == (4 if retro else 3)
    for name in ("x", "y", "theta", "delta_theta", "odom_pos", "odom_ang"):
        a, b = getattr(got, name), getattr(want, name)
        assert a.dtype == b.dtype and a.tolist() == b.tolist(), name  # bit for bit


@pytest.mark.parametrize("stepsize", [1.0, 0.3, 2.5])
def test_grid_cells_round_as_c_rounds(stepsize, monkeypatch):
    rng = np.random.default_rng(9)
    frag = 4
    # positions on the walk's lattice (exact halves among the cells), random ones, negatives, zeros
    x = np.concatenate([np.arange(-400, 400) * stepsize / frag, rng.normal(0, 50, 2000), [0.0, -0.0]])
    y = np.concatenate([np.arange(-400, 400) * stepsize / 8, rng.normal(0, 50, 2000), [-0.0, 0.0]])
    cfg = dataclasses.replace(
        load_synth_config("tests/data/configs/small3x100.json"), step_fragment=frag, stepsize=stepsize
    )
    got = loop_closures._grid_cells(x, y, cfg)
    monkeypatch.setattr(loop_closures, "_compiled_grid_cells", None)
    want = loop_closures._grid_cells(x, y, cfg)
    assert any(abs(v * frag / stepsize % 1) == 0.5 for v in y.tolist())  # ties were tried
    for a, b in zip(got, want):
        assert a.dtype == b.dtype and a.tolist() == b.tolist()
