"""Global initial guesses on columns: planar chordal relaxation and the spanning tree of measurements.

Planar chordal relaxation: each rotation is unknown as the first column ``(cos t, sin t)`` of its
matrix; every edge asks ``R_j = R_i R_ij``, two linear equations weighted by the square root of the
edge's rotation information; the least-squares solution (anchor fixed) is projected back to SO(2)
by normalising each column. Positions then solve ``t_j - t_i = R_i t_ij``, weighted by the square root
of the translation information, by linear least squares. Both are sparse normal equations solved with
SuperLU (scipy). The spatial chordal guess is GTSAM's (``InitializePose3``), see ``gtsam_method``.

Spanning tree: breadth-first from the anchor over all edges, composing measurements along the tree
(g2o's ``computeInitialGuess`` does the same with odometry-like costs).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from studio.core.geometry import normalize_angle, quat_conj, quat_mul, quat_rotate, upper_to_matrix
from studio.core.model import PoseKind
from studio.solvers.problem import Problem

__all__ = ["chordal_se2", "spanning_tree", "roots_of"]


def _solve_normal(a: Any, b: np.ndarray) -> np.ndarray:
    """The least-squares solution of ``a x = b`` for a scipy sparse ``a`` (scipy is untyped: ``Any``)."""
    import scipy.sparse.linalg as spla

    x: np.ndarray = spla.splu((a.T @ a).tocsc()).solve(a.T @ b)
    return x


def _prior_rows(
    problem: Problem, keep: np.ndarray, width: int, weights: np.ndarray, values: np.ndarray
) -> tuple[Any, Any]:
    """The rows ``w x_v = w value`` of the priors over the unknowns ``keep`` (``width`` unknowns per
    vertex, one row per prior and unknown), or None without priors."""
    import scipy.sparse as sp

    priors = problem.priors
    if priors is None or not len(priors):
        return None, None
    k = len(priors)
    rows = np.arange(k * width)
    cols = (width * priors.vertex[:, None] + np.arange(width)[None, :]).ravel()
    w = np.repeat(weights, width)
    full = sp.csr_matrix((w, (rows, cols)), shape=(k * width, width * problem.num_vertices))
    return full[:, keep], w * values.ravel()


def _stack(a: Any, b: np.ndarray, extra: tuple[Any, Any]) -> tuple[Any, np.ndarray]:
    import scipy.sparse as sp

    if extra[0] is None:
        return a, b
    return sp.vstack([a, extra[0]]).tocsr(), np.concatenate([b, extra[1]])


def _chordal_rotations(problem: Problem, omega: np.ndarray) -> np.ndarray:
    """Each vertex's planar angle from the chordal relaxation, the held vertices keeping theirs and
    the priors' angles weighed by their rotation information."""
    import scipy.sparse as sp

    n, m = problem.num_vertices, problem.num_edges
    fr, to, z = problem.edge_from, problem.edge_to, problem.measurements
    held = problem.held
    rows = np.arange(m)
    w = np.sqrt(np.maximum(omega[:, 2, 2], 0.0))
    cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
    # R_i R_ij first column: [c_i cz - s_i sz, s_i cz + c_i sz]
    r = np.concatenate([2 * rows] * 3 + [2 * rows + 1] * 3)
    c = np.concatenate([2 * to, 2 * fr, 2 * fr + 1, 2 * to + 1, 2 * fr + 1, 2 * fr])
    v = np.concatenate([w, -w * cz, w * sz, w, -w * cz, -w * sz])
    a = sp.csr_matrix((v, (r, c)), shape=(2 * m, 2 * n))
    held_cols = np.column_stack([2 * held, 2 * held + 1]).ravel()
    keep = np.setdiff1d(np.arange(2 * n), held_cols)
    fixed = np.column_stack([np.cos(problem.initial[held, 2]), np.sin(problem.initial[held, 2])]).ravel()
    b = -(a[:, held_cols] @ fixed)
    if problem.priors is not None and len(problem.priors):
        p = problem.priors
        wp = np.sqrt(np.maximum(upper_to_matrix(p.information_upper, 3)[:, 2, 2], 0.0))
        cs = np.column_stack([np.cos(p.poses[:, 2]), np.sin(p.poses[:, 2])])
        a_keep, b = _stack(a[:, keep], b, _prior_rows(problem, keep, 2, wp, cs))
    else:
        a_keep = a[:, keep]
    sol = np.empty(2 * n)
    sol[keep] = _solve_normal(a_keep, b)
    sol[held_cols] = fixed
    cs = sol.reshape(n, 2)
    return np.arctan2(cs[:, 1], cs[:, 0])


def chordal_se2(problem: Problem) -> np.ndarray:
    """Planar poses ``(n, 3)`` from the chordal relaxation, the held vertices (the anchor, or one per
    piece without a prior) keeping their initial poses and the priors weighed by their information."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    n, m = problem.num_vertices, problem.num_edges
    fr, to, z = problem.edge_from, problem.edge_to, problem.measurements
    omega = upper_to_matrix(problem.information_upper, 3)
    held = problem.held
    theta = _chordal_rotations(problem, omega)
    rows = np.arange(m)
    wt = np.sqrt(np.maximum(0.5 * (omega[:, 0, 0] + omega[:, 1, 1]), 0.0))
    ci, si = np.cos(theta[fr]), np.sin(theta[fr])
    bx = wt * (ci * z[:, 0] - si * z[:, 1])
    by = wt * (si * z[:, 0] + ci * z[:, 1])
    bmat = sp.csr_matrix(
        (np.concatenate([wt, -wt]), (np.concatenate([rows, rows]), np.concatenate([to, fr]))), shape=(m, n)
    )
    others = np.setdiff1d(np.arange(n), held)
    x0 = problem.initial[held]
    held_part = bmat[:, held].toarray()
    rhs = np.column_stack([bx, by])
    if len(held) == 1:  # the anchor alone: its column times its position, as the problem always had
        rhs -= held_part[:, 0:1] * x0[0, 0:2]
    else:
        rhs -= held_part @ x0[:, 0:2]
    reduced = bmat[:, others]
    if problem.priors is not None and len(problem.priors):
        p = problem.priors
        info = upper_to_matrix(p.information_upper, 3)
        wp = np.sqrt(np.maximum(0.5 * (info[:, 0, 0] + info[:, 1, 1]), 0.0))
        extra = _prior_rows(problem, others, 1, wp, np.zeros(len(p)))
        reduced = sp.vstack([reduced, extra[0]]).tocsr()
        rhs = np.concatenate([rhs, wp[:, None] * p.poses[:, 0:2]])
    lu = spla.splu((reduced.T @ reduced).tocsc())
    xy = np.empty((n, 2))
    xy[held] = x0[:, 0:2]
    xy[others, 0] = lu.solve(reduced.T @ rhs[:, 0])
    xy[others, 1] = lu.solve(reduced.T @ rhs[:, 1])
    return np.column_stack([xy, theta])


def _compose(kind: PoseKind, parent: np.ndarray, z: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """``parent * z`` where ``forward``, else ``parent * z^-1``, row by row."""
    if kind is PoseKind.SE2:
        th = np.where(forward, z[:, 2], -z[:, 2])
        cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
        zx = np.where(forward, z[:, 0], -(cz * z[:, 0] + sz * z[:, 1]))
        zy = np.where(forward, z[:, 1], -(-sz * z[:, 0] + cz * z[:, 1]))
        c, s = np.cos(parent[:, 2]), np.sin(parent[:, 2])
        return np.column_stack(
            [parent[:, 0] + c * zx - s * zy, parent[:, 1] + s * zx + c * zy, normalize_angle(parent[:, 2] + th)]
        )
    qz = np.where(forward[:, None], z[:, 3:7], quat_conj(z[:, 3:7]))
    tz = np.where(forward[:, None], z[:, 0:3], -quat_rotate(quat_conj(z[:, 3:7]), z[:, 0:3]))
    q = quat_mul(parent[:, 3:7], qz)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.column_stack([parent[:, 0:3] + quat_rotate(parent[:, 3:7], tz), q])


def roots_of(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """The vertices a spanning tree grows from and their poses: the held vertices at their initial
    values, and in each piece held by priors its first prior's vertex at the prior's value."""
    held = problem.held
    if problem.priors is None or not len(problem.priors):
        return held, problem.initial[held]
    from studio.solvers.gauge import pieces

    _, labels = pieces(problem)
    _, first = np.unique(labels[problem.priors.vertex], return_index=True)
    roots = np.concatenate([held, problem.priors.vertex[first]])
    return roots, np.concatenate([problem.initial[held], problem.priors.poses[first]])


def spanning_tree(problem: Problem) -> np.ndarray:
    """Poses composed along a breadth-first spanning tree of all edges from each root (the anchor;
    see :func:`roots_of`); vertices no tree reaches keep their initial values."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import breadth_first_order

    n, m = problem.num_vertices, problem.num_edges
    fr, to = problem.edge_from, problem.edge_to
    # edge k stored as +(k + 1) from -> to and -(k + 1) to -> from; the first edge of a pair wins
    rows, cols = np.concatenate([fr, to]), np.concatenate([to, fr])
    vals = np.concatenate([np.arange(1, m + 1), -np.arange(1, m + 1)])
    _, first = np.unique(rows * n + cols, return_index=True)
    adj = sp.csr_matrix((vals[first], (rows[first], cols[first])), shape=(n, n))
    poses: np.ndarray = problem.initial.copy()
    roots, root_poses = roots_of(problem)
    poses[roots] = root_poses
    pred = np.full(n, -9999, dtype=np.int64)
    depth = np.zeros(n, dtype=np.int64)
    reached_parts = []
    for root in roots.tolist():
        order, pred_r = breadth_first_order(abs(adj), root, directed=True, return_predecessors=True)
        pred[order[1:]] = pred_r[order[1:]]
        for v in order[1:]:
            depth[v] = depth[pred[v]] + 1
        reached_parts.append(order[1:])
    reached = np.concatenate(reached_parts)
    for level in range(1, int(depth.max(initial=0)) + 1):
        vs = reached[depth[reached] == level]
        ps = pred[vs]
        signed = np.asarray(adj[ps, vs]).ravel()
        k = np.abs(signed) - 1
        poses[vs] = _compose(problem.kind, poses[ps], problem.measurements[k], signed > 0)
    return poses
