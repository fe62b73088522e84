"""The gauge of a problem: what fixes the rigid motion each connected piece of the graph is free to
make, which no relative measurement sees.

* A dataset with pose priors (COSMO-Bench anchors each robot at its first pose with a
  ``PriorFactorPose3``) is held by them, weighed by their covariance: a piece that holds a prior
  gets no artificial anchor.
* A piece without a prior is held at one vertex, fixed at its initial value: the problem's
  :attr:`~studio.solvers.problem.Problem.anchor` for its piece (``FIX``, else the first vertex),
  the first vertex of every other piece, as a Kimera-RPGO or GTSAM user fixes each graph. An
  isolated vertex is a piece of its own and keeps its initial value.

A connected graph without priors is held by its anchor alone, as before: its problem, its start and
its answer are unchanged.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from studio.solvers.problem import Problem

__all__ = ["pieces", "with_gauge", "gauge_report"]


def pieces(problem: Problem) -> tuple[int, np.ndarray]:
    """The number of connected pieces of the graph (edges only) and each vertex's piece, numbered
    by their lowest vertex."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = problem.num_vertices
    adj = coo_matrix((np.ones(problem.num_edges), (problem.edge_from, problem.edge_to)), shape=(n, n))
    count, labels = connected_components(adj, directed=False)
    return int(count), np.asarray(labels, dtype=np.int64)


def with_gauge(problem: Problem) -> Problem:
    """``problem`` with :attr:`~Problem.anchors`: one vertex per piece that holds no prior (see the
    module doc); a connected problem without priors is returned as it is."""
    count, labels = pieces(problem)
    if count == 1 and (problem.priors is None or not len(problem.priors)):
        return problem  # held by its anchor alone, exactly as a connected graph always was
    priored = np.zeros(count, dtype=bool)
    if problem.priors is not None:
        priored[labels[problem.priors.vertex]] = True
    _, first = np.unique(labels, return_index=True)  # the lowest vertex of each piece
    first = first.astype(np.int64)
    first[labels[problem.anchor]] = problem.anchor
    anchors = np.sort(first[~priored])
    return dataclasses.replace(problem, anchors=anchors)


def gauge_report(problem: Problem, vertex_name: object = None) -> dict[str, object]:
    """What ``solve.json`` says of the gauge of a problem that has priors or several pieces: the
    pieces, the priors, and the anchored vertices (global ids, and the dataset's names when
    ``vertex_name`` is given)."""
    count, labels = pieces(problem)
    held = problem.held
    out: dict[str, object] = {
        "pieces": count,
        "priors": 0 if problem.priors is None else len(problem.priors),
        "anchored_vertices": held.tolist(),
        "isolated_vertices": int((np.bincount(labels, minlength=count) == 1).sum()),
    }
    if callable(vertex_name):
        out["anchored"] = [vertex_name(int(v)) for v in held]
    return out
