"""Labelled outlier loop closures (``"studio": {"outliers": {...}}``). Pure maths, no I/O.

A fraction of the intra-agent and of the inter-agent loop closures keep their measurement and
information but get a wrong ``to`` vertex (of the same agent as the true one):

* ``random``: a pose drawn uniformly among those between ``random_min_radius`` and ``random_radius``
  metres from the true ``to`` pose;
* ``aliasing`` (perceptual aliasing): a pose at least ``aliasing_min_distance`` metres from both true
  endpoints with the same heading (quarter turns) as the true ``to`` pose and the same local grid
  pattern: the cells the agent ever visits in the ``(2 w F + 1)^2`` window around it (same height,
  ``w = aliasing_window`` steps of ``F = step_fragment`` cells) are exactly those around the true one.

``round(fraction * n)`` loop closures of each class are made outliers, split between the kinds by
their weights (largest remainder). Loop closures are taken in one random order, aliasing first (it
needs a look-alike place, which many loop closures lack); a kind that cannot place its share hands
the shortfall to the other, so the total is exact whenever candidates exist and the kinds follow the
weights as closely as the walk allows (``PlantedOutliers.kinds`` says what was planted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph
from studio.core.outliers import WrongVertexRule, plant_wrong_vertices
from studio.generator.extensions import OUTLIER_KINDS, OutlierConfig

__all__ = ["PlantedOutliers", "plant_outliers", "local_patterns"]


@dataclass(frozen=True, eq=False)
class PlantedOutliers:
    graph: PoseGraph
    rows: np.ndarray
    """(k, 4) int64 ``agent_from vertex_from agent_to vertex_to`` (0-based agents), intra first."""
    kinds: tuple[str, ...]
    """The kind of each row."""
    asked: dict[str, int]
    """Outliers asked for per class (``intra``, ``inter``)."""


def _split(k: int, weights: dict[str, float]) -> dict[str, int]:
    names = [n for n in OUTLIER_KINDS if weights.get(n, 0.0) > 0]
    total = sum(weights[n] for n in names)
    exact = {n: k * weights[n] / total for n in names}
    out = {n: int(np.floor(exact[n])) for n in names}
    rest = k - sum(out.values())
    for n in sorted(names, key=lambda n: (-(exact[n] - out[n]), OUTLIER_KINDS.index(n)))[:rest]:
        out[n] += 1
    return out


def local_patterns(cells: np.ndarray, heading: np.ndarray, half: int) -> np.ndarray:
    """One id per pose: equal ids = same heading and same occupied cells in the window around it."""
    cells = np.asarray(cells, dtype=np.int64)
    lo = cells.min(axis=0) - half
    span = cells.max(axis=0) + half - lo + 1

    def key(c: np.ndarray) -> np.ndarray:
        c = c - lo
        ids: np.ndarray = (c[..., 0] * span[1] + c[..., 1]) * span[2] + c[..., 2]
        return ids

    occupied = np.unique(key(cells))
    off = np.arange(-half, half + 1)
    ox, oy = np.meshgrid(off, off, indexing="ij")
    offsets = np.column_stack([ox.ravel(), oy.ravel(), np.zeros(ox.size, dtype=np.int64)])
    keys = key(cells[:, None, :] + offsets[None, :, :])
    pos = np.clip(np.searchsorted(occupied, keys), 0, len(occupied) - 1)
    bits = occupied[pos] == keys
    rows = np.column_stack([heading.astype(np.int64) % 4, np.packbits(bits, axis=1).astype(np.int64)])
    return np.unique(rows, axis=0, return_inverse=True)[1].ravel()


def plant_outliers(
    graph: PoseGraph,
    positions: list[np.ndarray],
    cells: list[np.ndarray],
    headings: list[np.ndarray],
    step_fragment: int,
    cfg: OutlierConfig,
) -> PlantedOutliers:
    """Replace the ``to`` vertex of some loop closures (see the module doc).

    ``positions[k]`` (n, 3) are agent k's ground-truth positions [m], ``cells[k]`` its (n, 3) integer
    grid cells, ``headings[k]`` its heading in quarter turns. The intra-agent loop closures are
    chosen first, then the inter-agent ones (one random stream), then the graph is rewritten.
    """
    rng = np.random.default_rng([cfg.seed % 2**32, 21])
    rules = _rules(cells, headings, step_fragment, cfg)
    agents = list(graph.agents)
    intra_ends = _intra_ends(agents)
    new_intra, kinds_intra, asked_intra = _choose(
        rng, intra_ends, cfg.intra_fraction, dict(cfg.kinds), rules, positions
    )
    inter = graph.inter
    inter_ends = np.column_stack([inter.from_agent, inter.from_index, inter.to_agent, inter.to_index]).reshape(-1, 4)
    new_inter, kinds_inter, asked_inter = _choose(
        rng, inter_ends, cfg.inter_fraction, dict(cfg.kinds), rules, positions
    )

    rows: list[tuple[int, int, int, int]] = []
    kinds: list[str] = []
    agents = _rewire_intra(agents, new_intra, kinds_intra, rows, kinds)
    new_inter_edges = _rewire_inter(inter, new_inter, kinds_inter, rows, kinds)
    out = PoseGraph(graph.kind, tuple(agents), new_inter_edges, dict(graph.metadata))
    return PlantedOutliers(
        out, np.array(rows, dtype=np.int64).reshape(-1, 4), tuple(kinds), {"intra": asked_intra, "inter": asked_inter}
    )


def _rules(
    cells: list[np.ndarray], headings: list[np.ndarray], step_fragment: int, cfg: OutlierConfig
) -> dict[str, WrongVertexRule]:
    """The two kinds as rules of the shared planter; an agent's local patterns are computed once, when
    an aliasing outlier first needs them."""
    patterns: dict[int, np.ndarray] = {}

    def pattern(a: int) -> np.ndarray:
        if a not in patterns:
            patterns[a] = local_patterns(cells[a], headings[a], cfg.aliasing_window * step_fragment)
        return patterns[a]

    return {
        "random": WrongVertexRule("random", min_to_m=cfg.random_min_radius, max_to_m=cfg.random_radius),
        "aliasing": WrongVertexRule(
            "aliasing",
            min_to_m=cfg.aliasing_min_distance,
            min_from_m=cfg.aliasing_min_distance,
            look_alike=pattern,
        ),
    }


def _choose(
    rng: np.random.Generator,
    ends: np.ndarray,
    fraction: float,
    weights: dict[str, float],
    rules: dict[str, WrongVertexRule],
    positions: list[np.ndarray],
) -> tuple[dict[int, int], dict[int, str], int]:
    """``ends``: (n, 4) rows a_from v_from a_to v_to. Returns the new ``to`` vertex and the kind per
    planted edge, and how many were asked for."""
    k = int(round(fraction * len(ends)))
    quota = _split(k, weights) if k else {}
    order = rng.permutation(len(ends)).tolist()
    # the rarer kind (aliasing needs a look-alike place) first; a kind's shortfall goes to the next,
    # and the first kind takes what the last fell short of
    names = [n for n in ("aliasing", "random") if n in quota]
    passes = [(rules[n], quota[n]) for n in names] + [(rules[n], 0) for n in names[:1]]
    new_to, kind_of = plant_wrong_vertices(rng, ends, order, passes, positions)
    return new_to, kind_of, k


def _intra_ends(agents: list[AgentGraph]) -> np.ndarray:
    """(n, 4) rows ``k from k to`` of every agent's loop closures, agent by agent."""
    return (
        np.concatenate(
            [
                np.column_stack(
                    [
                        np.full(len(a.loop_closures), k),
                        a.loop_closures.from_index,
                        np.full(len(a.loop_closures), k),
                        a.loop_closures.to_index,
                    ]
                )
                for k, a in enumerate(agents)
            ]
        )
        .astype(np.int64)
        .reshape(-1, 4)
    )


def _rewire_intra(
    agents: list[AgentGraph],
    new_intra: dict[int, int],
    kinds_intra: dict[int, str],
    rows: list[tuple[int, int, int, int]],
    kinds: list[str],
) -> list[AgentGraph]:
    """The agents with their planted loop closures' new ``to`` vertices; appends to ``rows``/``kinds``."""
    out = list(agents)
    offset = 0
    for k, a in enumerate(agents):
        lc = a.loop_closures
        to = lc.to_index.copy()
        for e in range(len(lc)):
            if offset + e in new_intra:
                to[e] = new_intra[offset + e]
                rows.append((k, int(lc.from_index[e]), k, int(to[e])))
                kinds.append(kinds_intra[offset + e])
        offset += len(lc)
        if len(lc):
            out[k] = AgentGraph(
                a.name,
                a.kind,
                a.stamps_ns,
                a.initial,
                a.ground_truth,
                a.odometry,
                Edges(lc.kind, lc.from_index, to, lc.measurements, lc.information_upper),
                a.ground_truth_se3,
            )
    return out


def _rewire_inter(
    inter: InterAgentEdges,
    new_inter: dict[int, int],
    kinds_inter: dict[int, str],
    rows: list[tuple[int, int, int, int]],
    kinds: list[str],
) -> InterAgentEdges:
    """The inter-agent edges with their planted ``to`` vertices; appends to ``rows``/``kinds``."""
    to_index = inter.to_index.copy()
    for e in sorted(new_inter):
        to_index[e] = new_inter[e]
        rows.append((int(inter.from_agent[e]), int(inter.from_index[e]), int(inter.to_agent[e]), int(to_index[e])))
        kinds.append(kinds_inter[e])
    return InterAgentEdges(
        inter.kind,
        inter.from_agent,
        inter.from_index,
        inter.to_agent,
        to_index,
        inter.measurements,
        inter.information_upper,
    )
