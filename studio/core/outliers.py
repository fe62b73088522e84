"""The one outlier planter: loop closures that keep their measurement but point at a wrong vertex.

Both users plant the same way: the synthetic generator (``generator/outliers.py``: per-class
fractions, ``random`` and ``aliasing`` kinds) and the graph builder of real data
(``converters/build.py``: one fraction, a vertex far from both true endpoints). Each loop closure is
a row ``a_from v_from a_to v_to``; a planted one gets a new ``v_to`` of the same agent ``a_to``, drawn
uniformly (one ``rng.integers``) among the vertices a :class:`WrongVertexRule` allows. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["WrongVertexRule", "wrong_vertex", "plant_wrong_vertices", "outlier_scores"]


@dataclass(frozen=True)
class WrongVertexRule:
    """Which vertices of the true ``to`` vertex's agent may replace it (distances [m])."""

    name: str
    """The outlier kind the rule plants (``random``, ``aliasing``, ...)."""
    min_to_m: float = 0.0
    """Smallest distance from the true ``to`` vertex."""
    max_to_m: float = math.inf
    """Largest distance from the true ``to`` vertex."""
    min_from_m: float = 0.0
    """Smallest distance from the ``from`` vertex (0: not checked)."""
    look_alike: Callable[[int], np.ndarray] | None = None
    """Agent -> one id per vertex: only vertices with the true ``to`` vertex's id qualify."""


def wrong_vertex(
    rule: WrongVertexRule,
    rng: np.random.Generator,
    positions: Sequence[np.ndarray],
    a_from: int,
    v_from: int,
    a_to: int,
    v_to: int,
) -> int | None:
    """A wrong ``to`` vertex of agent ``a_to`` for the loop closure ``(a_from, v_from) -> (a_to, v_to)``,
    or None when no vertex qualifies (``rng`` is then not drawn from).

    ``positions[k]`` are agent k's (n, 3) true positions. The ``from`` vertex itself never qualifies.
    """
    pos = positions[a_to]
    d_to = np.linalg.norm(pos - pos[v_to], axis=1)
    ok = d_to >= rule.min_to_m
    if rule.max_to_m < math.inf:
        ok &= d_to <= rule.max_to_m
    if rule.look_alike is not None:
        ids = rule.look_alike(a_to)
        ok &= ids == ids[v_to]
    if rule.min_from_m > 0:
        ok &= np.linalg.norm(pos - positions[a_from][v_from], axis=1) >= rule.min_from_m
    if a_from == a_to:
        ok[v_from] = False
    cand = np.flatnonzero(ok)
    return None if len(cand) == 0 else int(cand[rng.integers(len(cand))])


def plant_wrong_vertices(
    rng: np.random.Generator,
    ends: np.ndarray,
    order: Sequence[int],
    passes: Sequence[tuple[WrongVertexRule, int]],
    positions: Sequence[np.ndarray],
) -> tuple[dict[int, int], dict[int, str]]:
    """Plant outliers among the loop closures ``ends`` ((n, 4) rows ``a_from v_from a_to v_to``).

    Each pass ``(rule, quota)`` walks ``order`` (edge indices), skipping planted edges, and plants
    with ``rule`` until it has planted its quota plus what the previous pass fell short of; an edge
    the rule finds no vertex for stays true. Returns the new ``to`` vertex and the rule's name per
    planted edge.
    """
    new_to: dict[int, int] = {}
    kind_of: dict[int, str] = {}
    deficit = 0
    for rule, quota in passes:
        want = quota + deficit
        for e in order:
            if want == 0:
                break
            if e in new_to:
                continue
            t = wrong_vertex(rule, rng, positions, *(int(x) for x in ends[e]))
            if t is not None:
                new_to[e], kind_of[e] = t, rule.name
                want -= 1
        deficit = want
    return new_to, kind_of


def outlier_scores(rejected: np.ndarray, labelled: np.ndarray) -> dict[str, float | int | None]:
    """A robust method's rejections scored against a dataset's outlier labels, as COSMO-Bench and
    riMESA score them. Both are rows ``a_from v_from a_to v_to``; a closure is the same whichever way
    it is written. ``precision``: labelled closures among the rejected ones over the rejected ones;
    ``recall``: rejected labelled closures over the labelled ones (None where the count is 0)."""

    def closures(rows: np.ndarray) -> set[tuple[int, ...]]:
        out: set[tuple[int, ...]] = set()
        for a, v, b, w in np.asarray(rows, dtype=np.int64).reshape(-1, 4).tolist():
            out.add(min((a, v, b, w), (b, w, a, v)))
        return out

    rej, lab = closures(rejected), closures(labelled)
    hit = len(rej & lab)
    return {
        "rejected": len(rej),
        "labelled": len(lab),
        "rejected_labelled": hit,
        "precision": hit / len(rej) if rej else None,
        "recall": hit / len(lab) if lab else None,
    }
