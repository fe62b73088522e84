"""The ``sesync`` method: SE-Sync's certifiably correct pose-graph optimization (Rosen et al., IJRR
2019), on :mod:`studio.solvers.sesync_problem`'s sparse matrices and pymanopt's Riemannian
trust-region method (``pip install pymanopt``).

The Riemannian staircase: rotations from SE-Sync's chordal initialization (the rotation-only
connection Laplacian's least-squares solution with vertex 0 at the identity, each block projected
to SO(d)); at rank ``r`` (starting at ``d``) the translation-free objective ``tr(Y Q Y^T)`` is
minimized over the product of ``n`` Stiefel manifolds St(d, r) by trust regions (pymanopt's
``TrustRegions`` with the exact Hessian ``2 Ydot Q`` made Riemannian by pymanopt's Stiefel
geometry); the critical point is verified (``lambda_min`` of the certificate matrix); where the
certificate fails, the rank grows by one and the iterate leaves the saddle along the eigenvector of
the negative eigenvalue (SE-Sync's ``escape_saddle``: a backtracking line search on ``[Y; 0] +
alpha [0; v^T]``, retracted). The final ``Y`` is rounded to SO(d) (its ``d`` leading singular
directions, the sign with most positive determinants, each block projected), translations solved in
closed form, and the rounded estimate verified again: the notes hold ``f``, ``lambda_min``, the
ranks, whether it is certified and SE-Sync's suboptimality bound. A result is called optimal only
when the certificate holds.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from studio.core.errors import ConfigError
from studio.core.model import PoseKind
from studio.solvers.options import SESYNC_MAX_ITERATIONS
from studio.solvers.problem import Iteration, Problem, Solution, SolveOptions, graph_chi2
from studio.solvers.sesync_problem import (
    EIG_TOL,
    Certificate,
    SyncProblem,
    build,
    certify_rotations,
    poses_from,
    rotation_matrices,
)

__all__ = [
    "solve_sesync",
    "chordal_rotations",
    "round_rotations",
    "staircase",
    "MAX_RANK_EXTRA",
    "Optimum",
    "certified_optimum",
    "sesync_objective",
]

#: The staircase stops at rank ``d + MAX_RANK_EXTRA`` (SE-Sync's ``rmax`` is 10 for ``r0 = 5``).
MAX_RANK_EXTRA = 7
#: Riemannian gradient norm at which a rank's trust-region run stops (SE-Sync's ``grad_norm_tol``
#: is 1e-2; smaller here so that f agrees with SE-Sync's to four digits).
GRAD_TOL = 1e-3
#: The truncated conjugate gradient's stopping rule, SE-Sync's ``STPCG_theta`` and ``STPCG_kappa``
#: (pymanopt's default theta, 1, asks for quadratic convergence and many more inner iterations).
TCG_THETA = 0.5
TCG_KAPPA = 0.1


def _so_project(blocks: np.ndarray) -> np.ndarray:
    """Each ``(d, d)`` block's nearest rotation (SVD, determinant +1)."""
    u, _, vt = np.linalg.svd(blocks)
    det = np.sign(np.linalg.det(u @ vt))
    u[:, :, -1] *= det[:, None]
    out: np.ndarray = u @ vt
    return out


def _blocks(y: np.ndarray, n: int, d: int) -> np.ndarray:
    """``Y`` (``r x dn``) as ``(n, r, d)``."""
    return np.ascontiguousarray(y.reshape(y.shape[0], n, d).transpose(1, 0, 2))


def _matrix(p: np.ndarray) -> np.ndarray:
    n, r, d = p.shape
    return np.ascontiguousarray(p.transpose(1, 0, 2).reshape(r, n * d))


def chordal_rotations(sync: SyncProblem) -> np.ndarray:
    """SE-Sync's chordal initialization: ``(d, dn)`` rotations, vertex 0 at the identity."""
    import scipy.sparse.linalg as spla

    d = sync.d
    conn = sync.connection
    x = np.asarray(spla.splu(conn[d:, d:].tocsc()).solve(-np.asarray(conn[d:, :d].todense())))
    y = np.concatenate([np.eye(d), x], axis=0)  # (dn, d): the rows are R_i^T stacked
    rot = _so_project(y.reshape(sync.n, d, d).transpose(0, 2, 1))
    return _matrix(rot)


def round_rotations(y: np.ndarray, n: int, d: int) -> np.ndarray:
    """SE-Sync's rounding of a rank-``r`` ``Y`` to ``(n, d, d)`` rotations."""
    _, s, vt = np.linalg.svd(y, full_matrices=False)
    r = s[:d, None] * vt[:d]
    blocks = r.reshape(d, n, d).transpose(1, 0, 2)
    if np.count_nonzero(np.linalg.det(blocks) > 0) < n / 2:
        blocks[:, -1, :] *= -1.0
    return _so_project(blocks)


def _qr_retraction(p: np.ndarray) -> np.ndarray:
    """The Q factor (positive diagonal of R) of each ``(r, d)`` block: Gram-Schmidt on the ``d``
    columns at once for every block (numpy's batched QR is slow on many tiny blocks)."""
    q: np.ndarray = p.copy()
    for j in range(q.shape[2]):
        for k in range(j):
            q[:, :, j] -= np.einsum("nr,nr->n", q[:, :, k], q[:, :, j])[:, None] * q[:, :, k]
        q[:, :, j] /= np.linalg.norm(q[:, :, j], axis=1)[:, None]
    return q


def _stiefel_product(r: int, d: int, n: int) -> Any:
    """pymanopt's product of ``n`` Stiefel manifolds St(d, r), with the inner product and the QR
    retraction computed on whole arrays (pymanopt's tensordot and batched QR dominated the run)."""
    from pymanopt.manifolds import Stiefel

    class _Product(Stiefel):  # type: ignore[misc]
        def inner_product(self, point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
            # not np.dot: BLAS's threads on a short vector cost more than the product on a busy machine
            return float((a * b).sum())

        def retraction(self, point: np.ndarray, tangent_vector: np.ndarray) -> np.ndarray:
            return _qr_retraction(point + tangent_vector)

    return _Product(r, d, k=n)


def _riemannian_problem(sync: SyncProblem, r: int) -> tuple[Any, Any]:
    import pymanopt

    n, d = sync.n, sync.d
    manifold = _stiefel_product(r, d, n)
    cache: dict[str, Any] = {"key": None}

    def qy(p: np.ndarray) -> np.ndarray:
        if cache["key"] is not p:
            cache["key"], cache["value"] = p, sync.q_times(_matrix(p).T).T
        out: np.ndarray = cache["value"]
        return out

    @pymanopt.function.numpy(manifold)  # type: ignore[untyped-decorator]
    def cost(p: np.ndarray) -> float:
        return float(np.sum(_matrix(p) * qy(p)))

    @pymanopt.function.numpy(manifold)  # type: ignore[untyped-decorator]
    def gradient(p: np.ndarray) -> np.ndarray:
        return 2.0 * _blocks(qy(p), n, d)

    def hessian(p: np.ndarray, dp: np.ndarray) -> np.ndarray:
        # the Riemannian Hessian of the Stiefel product, written once per point: Proj(2 dY Q - dY G_i)
        # with G_i = sym(Y_i^T grad_i) cached (SE-Sync's "2 Proj(dY S)"), fewer batched products
        # than pymanopt's generic Weingarten map
        if cache.get("sym_key") is not p:
            g = 2.0 * _blocks(qy(p), n, d)
            yg = p.transpose(0, 2, 1) @ g
            cache["sym_key"], cache["sym"] = p, 0.5 * (yg + yg.transpose(0, 2, 1))
        out = 2.0 * _blocks(sync.q_times(_matrix(dp).T).T, n, d) - dp @ cache["sym"]
        return manifold.projection(p, out)  # type: ignore[no-any-return]

    def precondition(p: np.ndarray, v: np.ndarray) -> np.ndarray:
        return manifold.projection(p, _blocks(sync.precondition(_matrix(v).T).T, n, d))  # type: ignore[no-any-return]

    return manifold, pymanopt.Problem(
        manifold,
        cost,
        euclidean_gradient=gradient,
        riemannian_hessian=pymanopt.function.numpy(manifold)(hessian),
        preconditioner=precondition,
    )


def _minimize(sync: SyncProblem, y: np.ndarray, max_iterations: int) -> tuple[np.ndarray, int]:
    """Trust regions at ``Y``'s rank from ``Y``; the critical point and the iterations run."""
    from pymanopt.optimizers import TrustRegions

    _, problem = _riemannian_problem(sync, y.shape[0])
    opt = TrustRegions(
        max_iterations=max_iterations, min_gradient_norm=GRAD_TOL, theta=TCG_THETA, kappa=TCG_KAPPA, verbosity=0
    )
    # at an exact optimum (f = 0, a noiseless graph) pymanopt's trust-region ratio is 0/0: its
    # RuntimeWarning is no message for the user, the critical point it returns is right
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        result = opt.run(problem, initial_point=_blocks(y, sync.n, sync.d))
    return _matrix(result.point), int(result.iterations)


def _escape(sync: SyncProblem, y: np.ndarray, v: np.ndarray, theta: float) -> np.ndarray | None:
    """SE-Sync's ``escape_saddle``: rank ``r + 1``, a step along ``v`` that lowers ``f``, or None."""
    manifold, _ = _riemannian_problem(sync, y.shape[0] + 1)
    y_aug = np.concatenate([y, np.zeros((1, y.shape[1]))])
    ydot = np.zeros_like(y_aug)
    ydot[-1] = v
    f0 = sync.objective(y)
    alpha = max(16e-6, 10 * GRAD_TOL / abs(theta))
    while alpha >= 1e-6:
        trial = _matrix(manifold.retraction(_blocks(y_aug, sync.n, sync.d), alpha * _blocks(ydot, sync.n, sync.d)))
        if sync.objective(trial) < f0:
            return trial
        alpha /= 2
    return None


def staircase(
    sync: SyncProblem, y: np.ndarray, *, max_iterations: int
) -> tuple[np.ndarray, list[dict[str, Any]], Certificate]:
    """The Riemannian staircase from ``Y``: the last rank's critical point, one record per rank
    (rank, f, lambda_min, trust-region iterations, seconds) and the last rank's certificate."""
    steps: list[dict[str, Any]] = []
    while True:
        t0 = time.perf_counter()
        y, iterations = _minimize(sync, y, max_iterations)
        cert, v = certify_rotations(sync, y, sharpen=False)
        steps.append(
            {
                "rank": int(y.shape[0]),
                "f": sync.objective(y),
                "lambda_min": cert.lambda_min,
                "iterations": iterations,
                "seconds": time.perf_counter() - t0,
            }
        )
        if cert.lambda_min >= -EIG_TOL or y.shape[0] >= sync.d + MAX_RANK_EXTRA:
            return y, steps, cert
        escaped = _escape(sync, y, v, cert.lambda_min)
        if escaped is None:
            return y, steps, cert
        y = escaped


def _reanchor(kind: PoseKind, rot: np.ndarray, trans: np.ndarray, target: np.ndarray, anchor: int) -> np.ndarray:
    """Poses from rotations and translations moved rigidly so the anchor has the ``target`` pose."""
    rt, tt = rotation_matrices(kind, target[None])
    g = rt[0] @ rot[anchor].T
    rot2 = g[None] @ rot
    trans2 = (trans - trans[anchor]) @ g.T + tt[0]
    out = poses_from(kind, rot2, trans2)
    out[anchor] = target
    return out


def _same_up_to_rotation(rows: np.ndarray, y: np.ndarray, n: int) -> bool:
    """Whether the rounded rotations are ``O Y`` for one orthogonal ``O`` (``Y``'s ``n`` blocks are in
    O(d) at rank d, so ``Y Y^T = n I`` and ``O = rows Y^T / n``): the certificate matrix depends on
    ``Y^T Y`` only, so ``Y``'s certificate is then the rounded estimate's."""
    o = rows @ y.T / n
    return bool(np.allclose(rows, o @ y, atol=1e-10))


def solve_sesync(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    """SE-Sync's certified solve of ``problem`` (see the module doc)."""
    try:
        import pymanopt  # noqa: F401
    except ImportError:
        raise ConfigError("method sesync needs pymanopt: pip install 'cslam-studio[solve]'") from None
    t0 = time.perf_counter()
    sync = sync_problem(problem)
    y0 = chordal_rotations(sync)
    t_init = time.perf_counter() - t0
    rot0 = y0.reshape(sync.d, sync.n, sync.d).transpose(1, 0, 2)
    guess = _reanchor(problem.kind, rot0, -sync.translations(y0), problem.initial[problem.anchor], problem.anchor)
    if on_iteration is not None:
        on_iteration(0, guess)
    y, steps, final = staircase(sync, y0, max_iterations=options.max_iterations)
    rot = round_rotations(y, sync.n, sync.d)
    rows = rot.transpose(1, 0, 2).reshape(sync.d, -1)
    if final.certified and steps[-1]["rank"] == sync.d and _same_up_to_rotation(rows, y, sync.n):
        cert = final  # rounding at rank d moved Y rigidly: S and f, hence the certificate, are Y's
    else:
        cert, _ = certify_rotations(sync, rows)  # the rounded estimate is what is certified
    poses = _reanchor(problem.kind, rot, -sync.translations(rows), problem.initial[problem.anchor], problem.anchor)
    if on_iteration is not None:
        on_iteration(1, poses)
    return Solution(
        poses,
        sum(s["iterations"] for s in steps),
        (graph_chi2(problem, guess), graph_chi2(problem, poses)),
        notes={"init_s": t_init, "init": "chordal (SE-Sync)", "staircase": steps, **certificate_notes(cert)},
        minimizes_chi2=False,
    )


def certificate_notes(cert: Certificate) -> dict[str, object]:
    """What ``solve.json`` records of a certificate."""
    return {
        "sesync_f": cert.objective,
        "lambda_min": cert.lambda_min,
        "certified": cert.certified,
        "suboptimality_bound": cert.gap_bound,
        "verdict": cert.verdict(),
    }


@dataclass(frozen=True)
class Optimum:
    """A graph's optimum of SE-Sync's objective, as the certified solve found it: ``f_star`` is the
    global optimum when ``certified``, else only an upper bound on it."""

    f_star: float
    certified: bool

    def gap(self, f: float) -> float | None:
        """``(f - f*) / f*``, the relative distance of an estimate's ``f`` above the certified optimum;
        None where there is no certified optimum to measure from (or ``f*`` is 0: exact data)."""
        if not self.certified or not (self.f_star > 0.0) or not np.isfinite(f):
            return None
        return (f - self.f_star) / self.f_star


def sesync_objective(problem: Problem, poses: np.ndarray) -> float:
    """SE-Sync's ``f`` (:mod:`studio.solvers.sesync_problem`) of ``poses``, rows in ``problem``'s pose
    kind: the objective in which a back-end's answer is compared with the certified optimum."""
    sync = sync_problem(problem)
    rot, trans = rotation_matrices(problem.kind, poses)
    return sync.full_objective(rot, trans)


def certified_optimum(problem: Problem) -> Optimum:
    """The certified solve's ``f`` of ``problem`` and whether it is certified (the reference a
    benchmark's results are measured from)."""
    notes = solve_sesync(problem, SolveOptions(max_iterations=SESYNC_MAX_ITERATIONS)).notes
    f_star = notes["sesync_f"]
    assert isinstance(f_star, float)
    return Optimum(f_star, bool(notes["certified"]))


def sync_problem(problem: Problem) -> SyncProblem:
    """SE-Sync's data matrices (:func:`studio.solvers.sesync_problem.build`) of ``problem``'s edges."""
    return build(
        problem.kind,
        problem.num_vertices,
        problem.edge_from,
        problem.edge_to,
        problem.measurements,
        problem.information_upper,
    )
