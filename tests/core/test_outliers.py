"""The one outlier planter (studio/core/outliers.py) shared by the generator and the graph builder."""

from __future__ import annotations

import numpy as np

from studio.core.outliers import WrongVertexRule, plant_wrong_vertices, wrong_vertex


def _line(n: int) -> np.ndarray:
    """n poses 1 m apart on the x axis."""
    return np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])


def test_a_wrong_vertex_keeps_its_distances_and_is_never_the_from_vertex():
    positions = [_line(30), _line(30) + [0.0, 5.0, 0.0]]
    rule = WrongVertexRule("band", min_to_m=3.0, max_to_m=6.0)
    rng = np.random.default_rng(0)
    seen = {wrong_vertex(rule, rng, positions, 0, 14, 0, 10) for _ in range(200)}
    # 3..6 m from vertex 10 are 4..7 and 13..16, less 14, the from vertex
    assert seen == {4, 5, 6, 7, 13, 15, 16}
    far = WrongVertexRule("far", min_to_m=8.0, min_from_m=8.0)
    seen = {wrong_vertex(far, rng, positions, 1, 2, 0, 20) for _ in range(200)}
    # the other agent's vertex 2 sits at (2, 5): >= 8 m from it means x >= 9 (sqrt(49 + 25) > 8);
    # >= 8 m from vertex 20 means x <= 12 or x >= 28
    assert seen == {9, 10, 11, 12, 28, 29}


def test_no_candidate_returns_none_and_draws_nothing():
    positions = [_line(5)]
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    assert wrong_vertex(WrongVertexRule("far", min_to_m=100.0), rng, positions, 0, 0, 0, 4) is None
    assert rng.bit_generator.state == state


def test_look_alike_ids_restrict_the_candidates():
    positions = [_line(12)]
    ids = np.array([0, 1, 2] * 4)
    rule = WrongVertexRule("alias", look_alike=lambda a: ids)
    rng = np.random.default_rng(1)
    seen = {wrong_vertex(rule, rng, positions, 0, 0, 0, 4) for _ in range(100)}
    assert seen == {1, 4, 7, 10}


def test_a_pass_that_falls_short_hands_its_deficit_to_the_next():
    positions = [_line(40)]
    ends = np.array([[0, 0, 0, 1], [0, 10, 0, 11], [0, 20, 0, 21], [0, 30, 0, 31]], dtype=np.int64)
    # "near" finds a vertex only for edges whose to vertex has a neighbour within 0.5 m: none does
    near = WrongVertexRule("near", min_to_m=0.1, max_to_m=0.5)
    any_ = WrongVertexRule("any", min_to_m=1.0)
    new_to, kind_of = plant_wrong_vertices(
        np.random.default_rng(0), ends, [3, 1, 0, 2], [(near, 2), (any_, 1)], positions
    )
    assert sorted(new_to) == [0, 1, 3] and set(kind_of.values()) == {"any"}
    assert all(new_to[e] != ends[e, 3] and new_to[e] != ends[e, 1] for e in new_to)
    # a single pass with a quota as large as the order tries every edge once
    new_to, _ = plant_wrong_vertices(np.random.default_rng(0), ends, [2, 0], [(any_, 2)], positions)
    assert sorted(new_to) == [0, 2]
