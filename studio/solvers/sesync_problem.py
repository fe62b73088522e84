"""SE-Sync's objective and its certificate of global optimality, on sparse matrices (scipy).

SE-Sync (D. M. Rosen, L. Carlone, A. S. Bandeira, J. J. Leonard, "SE-Sync: A certifiably correct
algorithm for synchronization over the special Euclidean group", IJRR 2019) poses pose-graph
optimization with isotropic weights and the chordal distance on rotations::

    f(t, R) = sum_e kappa_e ||R_j - R_i R_ij||_F^2 + tau_e ||t_j - t_i - R_i t_ij||^2

with ``kappa`` and ``tau`` taken from each edge's information as its ``read_g2o_file`` does
(planar: ``tau = 2 / tr(I_tt^-1)``, ``kappa = I_33``; spatial: ``tau = 3 / tr(I_tt^-1)``,
``kappa = 3 / (2 tr(I_rr^-1))``). Writing ``X = [t_1 .. t_n | R_1 .. R_n]`` (``d x (n + dn)``),
``f = tr(X M X^T)`` with the sparse data matrix ``M = W^T W``, one row of ``W`` per translation
residual and ``d`` per rotation residual (:func:`build`). Translations are eliminated in closed form
(``t = -R M_Rt L^+``, ``L = M_tt`` the tau-weighted graph Laplacian), leaving ``f(R) = tr(R Q R^T)``
with ``Q = M_RR - M_Rt L^+ M_tR``, applied without being formed (a sparse LU of ``L`` grounded at
vertex 0; ``Q`` itself is dense).

The certificate (SE-Sync's Theorem 7 and its ``verify_solution``): for rotations ``Y`` (``r x dn``,
``r >= d``) the Lagrange multipliers are ``Lambda_i = sym((Q Y^T)_i Y_i)``, ``S = Q - Lambda``. For
every ``S``, ``tr(Lambda) + n d lambda_min(S)`` is a lower bound on the semidefinite relaxation and
so on the optimum ``f*``, and ``tr(Lambda) = f(Y)``; when ``lambda_min(S) >= -eta`` (SE-Sync's
``min_eig_num_tol``, 1e-3) the estimate is certified, and in every case
``f(estimate) - tr(Lambda) - n d min(lambda_min, 0)`` bounds how far above ``f*`` the estimate is.
``lambda_min`` is found by LOBPCG (scipy) started from ``Y``'s rows, which span ``S``'s null space
at a critical point, preconditioned by a sparse LU of ``M_RR`` (``M_RR >= Q``). The trust-region
steps are preconditioned as SE-Sync's are, by a regularized factorization of ``M``. Every matrix
factored here is symmetric positive definite; :func:`studio.solvers.spd.spd_factor` factors it by
QDLDL where installed, else by SuperLU.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studio.core.geometry import upper_to_matrix
from studio.core.model import PoseKind
from studio.solvers.spd import spd_factor

__all__ = ["SyncProblem", "build", "rotation_matrices", "poses_from", "Certificate", "certify_rotations", "EIG_TOL"]

#: SE-Sync's ``min_eig_num_tol``: ``S`` is taken as positive semidefinite when ``lambda_min >= -EIG_TOL``.
EIG_TOL = 1e-3
#: LOBPCG's residual tolerance and iterations at most for ``lambda_min``: a first pass, enough at a
#: critical point (``Y``'s rows are exact null vectors of ``S``), and where it finds a negative
#: value, a second pass from its block that sharpens it (a Ritz value is never below ``lambda_min``).
LOBPCG_PASSES = ((1e-4, 20), (1e-7, 200))


def _weights(kind: PoseKind, information_upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(kappa, tau)`` per edge, as SE-Sync's ``read_g2o_file`` computes them."""
    if kind is PoseKind.SE2:
        info = upper_to_matrix(information_upper, 3)
        tau = 2.0 / np.trace(np.linalg.inv(info[:, :2, :2]), axis1=1, axis2=2)
        return info[:, 2, 2].copy(), tau
    info = upper_to_matrix(information_upper, 6)
    tau = 3.0 / np.trace(np.linalg.inv(info[:, :3, :3]), axis1=1, axis2=2)
    kappa = 3.0 / (2.0 * np.trace(np.linalg.inv(info[:, 3:, 3:]), axis1=1, axis2=2))
    return kappa, tau


def rotation_matrices(kind: PoseKind, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R (n, d, d), t (n, d))`` of planar ``(x, y, theta)`` or spatial ``(xyz, quat_xyzw)`` rows."""
    poses = np.asarray(poses, dtype=np.float64)
    if kind is PoseKind.SE2:
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], 1), poses[:, 0:2].copy()
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(poses[:, 3:7]).as_matrix(), poses[:, 0:3].copy()


def poses_from(kind: PoseKind, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
    """The inverse of :func:`rotation_matrices` (rotations must be in SO(d))."""
    if kind is PoseKind.SE2:
        return np.column_stack([translations, np.arctan2(rotations[:, 1, 0], rotations[:, 0, 0])])
    from scipy.spatial.transform import Rotation

    quat = Rotation.from_matrix(rotations).as_quat()
    quat[quat[:, 3] < 0] *= -1.0
    return np.column_stack([translations, quat])


@dataclass(frozen=True, eq=False)
class SyncProblem:
    """SE-Sync's data for one graph: ``d``, ``n``, the blocks of ``M`` (scipy sparse: ``Any``)."""

    kind: PoseKind
    d: int
    n: int
    m_tt: Any
    m_tr: Any
    m_rr: Any
    lap: Any
    """Sparse LU of ``M_tt`` without vertex 0's row and column (``L`` grounded)."""
    connection: Any
    """The rotation-only connection Laplacian ``L(G^rho)`` (``dn x dn``, chordal initialization)."""
    kappa: np.ndarray
    tau: np.ndarray
    cache: dict[str, Any] = field(default_factory=dict)
    """The preconditioner, factored when first used (a certificate alone does not need it)."""

    @property
    def precon(self) -> Any:
        """SE-Sync's regularized-Cholesky preconditioner: a sparse LU of ``M + lambda I`` with
        ``lambda`` such that its condition number is at most 1e6 (SE-Sync's
        ``reg_Cholesky_precon_max_condition_number``)."""
        if "precon" not in self.cache:
            import scipy.sparse as sp

            big = sp.bmat([[self.m_tt, self.m_tr], [self.m_tr.T, self.m_rr]], format="csc")
            # ||M|| from above by its largest absolute row sum (SE-Sync estimates it by LOBPCG)
            reg = float(abs(big).sum(axis=1).max()) / (1e6 - 1)
            # SuperLU's default COLAMD here: on M the symmetric minimum degree fills far more
            # (sphere2500: 16.4M entries against 3.0M, 4.0 s against 0.18 s to factor)
            self.cache["precon"] = spd_factor(big + reg * sp.identity(big.shape[0]), permc_spec="COLAMD")
        return self.cache["precon"]

    def precondition(self, x: np.ndarray) -> np.ndarray:
        """``Q^-1 x`` approximately (``(dn, k)``): the rotation block of ``(M + lambda I)^-1 [0; x]``,
        as SE-Sync preconditions its simplified problem."""
        rhs = np.zeros((self.n + x.shape[0], x.shape[1]))
        rhs[self.n :] = x
        out: np.ndarray = self.precon.solve(rhs)[self.n :]
        return out

    def translations(self, y: np.ndarray) -> np.ndarray:
        """``L^+ M_tR Y^T`` as ``(n, r)`` with vertex 0's row zero (the optimal ``t`` is minus it)."""
        b = np.asarray(self.m_tr @ y.T)
        out = np.zeros((self.n, y.shape[0]))
        out[1:] = self.lap.solve(np.ascontiguousarray(b[1:]))
        return out

    def q_times(self, x: np.ndarray) -> np.ndarray:
        """``Q x`` for ``x`` of shape ``(dn,)`` or ``(dn, k)``, without forming ``Q``."""
        flat = x.ndim == 1
        x2 = x[:, None] if flat else x
        out: np.ndarray = np.asarray(self.m_rr @ x2) - np.asarray(self.m_tr.T @ self.translations(x2.T))
        return out[:, 0] if flat else out

    def objective(self, y: np.ndarray) -> float:
        """``tr(Y Q Y^T)``: ``f`` at rotations ``Y`` (``r x dn``) with the best translations."""
        return float(np.sum(y.T * self.q_times(y.T)))

    def full_objective(self, rotations: np.ndarray, translations: np.ndarray) -> float:
        """``f(t, R)`` for ``(n, d, d)`` rotations and ``(n, d)`` translations."""
        x = np.concatenate([translations.T, _rows(rotations)], axis=1)
        mx = np.asarray(self.m_tt @ x[:, : self.n].T + self.m_tr @ x[:, self.n :].T).T
        mr = np.asarray(self.m_tr.T @ x[:, : self.n].T + self.m_rr @ x[:, self.n :].T).T
        return float(np.sum(x[:, : self.n] * mx) + np.sum(x[:, self.n :] * mr))


def _rows(rotations: np.ndarray) -> np.ndarray:
    """``(n, d, d)`` rotations as SE-Sync's ``d x dn`` matrix ``[R_1 .. R_n]``."""
    n, d, _ = rotations.shape
    return np.ascontiguousarray(rotations.transpose(1, 0, 2).reshape(d, n * d))


def build(
    kind: PoseKind,
    num_vertices: int,
    edge_from: np.ndarray,
    edge_to: np.ndarray,
    measurements: np.ndarray,
    information_upper: np.ndarray,
) -> SyncProblem:
    """SE-Sync's data matrix of a graph (every vertex must be joined to vertex 0 by edges)."""
    import scipy.sparse as sp

    d, n, m = (2 if kind is PoseKind.SE2 else 3), num_vertices, len(edge_from)
    kappa, tau = _weights(kind, information_upper)
    r_ij, t_ij = rotation_matrices(kind, measurements)
    fr, to = np.asarray(edge_from, dtype=np.int64), np.asarray(edge_to, dtype=np.int64)
    st, sk = np.sqrt(tau), np.sqrt(kappa)
    e = np.arange(m)
    # translation rows: t_j - t_i - R_i t_ij
    rows: list[np.ndarray] = [e, e, np.repeat(e, d)]
    cols: list[np.ndarray] = [to, fr, (n + d * fr[:, None] + np.arange(d)).ravel()]
    vals = [st, -st, (-st[:, None] * t_ij).ravel()]
    # rotation rows (row m + d e + l): column l of R_j - R_i R_ij
    ell, k = np.meshgrid(np.arange(d), np.arange(d), indexing="ij")  # ell: residual column, k: R_i column
    rows += [m + d * e[:, None] + np.arange(d), (m + d * e[:, None, None] + ell[None]).reshape(m, -1)]
    cols += [n + d * to[:, None] + np.arange(d), (n + d * fr[:, None, None] + k[None]).reshape(m, -1)]
    vals += [
        np.repeat(sk[:, None], d, axis=1),
        (-sk[:, None, None] * r_ij.transpose(0, 2, 1)[:, ell, k]).reshape(m, -1),
    ]
    w = sp.csr_matrix(
        (
            np.concatenate([v.ravel() for v in vals]),
            (np.concatenate([r.ravel() for r in rows]), np.concatenate([c.ravel() for c in cols])),
        ),
        shape=(m + d * m, n + d * n),
    )
    big = (w.T @ w).tocsc()
    m_tt, m_tr, m_rr = big[:n, :n].tocsc(), big[:n, n:].tocsr(), big[n:, n:].tocsr()
    # a symmetric ordering: half the fill of SuperLU's default COLAMD on a Laplacian
    lap = spd_factor(m_tt[1:, 1:])
    w_rot = w[m:, n:]
    return SyncProblem(kind, d, n, m_tt, m_tr, m_rr, lap, (w_rot.T @ w_rot).tocsc(), kappa, tau)


@dataclass(frozen=True)
class Certificate:
    """SE-Sync's verification of an estimate (see the module doc)."""

    objective: float
    """``f`` at the estimate (its own translations)."""
    lower_bound: float
    """``tr(Lambda) + n d min(lambda_min, 0)``: no estimate has ``f`` below it."""
    lambda_min: float
    """The smallest eigenvalue of the certificate matrix ``S = Q - Lambda``."""
    certified: bool
    """``lambda_min >= -EIG_TOL`` and the estimate's translations optimal for its rotations."""

    @property
    def gap_bound(self) -> float:
        """How far above the optimum the estimate is at most."""
        return max(self.objective - self.lower_bound, 0.0)

    def verdict(self) -> str:
        if self.certified:
            return f"certified globally optimal (f = {self.objective:.6g}, lambda_min = {self.lambda_min:.3g})"
        return f"not certified, at most {self.gap_bound:.6g} above the optimum (f = {self.objective:.6g}, lambda_min = {self.lambda_min:.3g})"


def lambda_blocks(sync: SyncProblem, y: np.ndarray) -> np.ndarray:
    """SE-Sync's ``Lambda_i = sym((Q Y^T)_i Y_i)`` as ``(n, d, d)``."""
    d, n = sync.d, sync.n
    qy = sync.q_times(y.T).reshape(n, d, -1)  # (Q Y^T)_i: d x r
    yb = y.reshape(y.shape[0], n, d).transpose(1, 0, 2)  # Y_i: r x d
    p = qy @ yb
    out: np.ndarray = 0.5 * (p + p.transpose(0, 2, 1))
    return out


def min_eigenpair(
    sync: SyncProblem, y: np.ndarray, blocks: np.ndarray, *, sharpen: bool = True, seed: int = 0
) -> tuple[float, np.ndarray]:
    """The smallest eigenvalue of ``S = Q - Lambda`` and its eigenvector (LOBPCG, scipy, preconditioned
    by a sparse LU of ``M_RR >= Q``, cheaper here than the full factorization the steps use);
    ``sharpen=False``: a negative value from the first pass is enough (the staircase's escape)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    d, n = sync.d, sync.n
    rows = (np.arange(n)[:, None, None] * d + np.arange(d)[None, :, None]).repeat(d, axis=2)
    lam = sp.csr_matrix((blocks.ravel(), (rows.ravel(), rows.transpose(0, 2, 1).ravel())), shape=(d * n, d * n))

    def s_times(x: np.ndarray) -> np.ndarray:
        out: np.ndarray = sync.q_times(x) - np.asarray(lam @ x)
        return out

    op = spla.LinearOperator((d * n, d * n), matvec=s_times, matmat=s_times, dtype=np.float64)
    shift = 1e-6 * float(sync.m_rr.diagonal().mean())
    lu = spd_factor(sync.m_rr + shift * sp.identity(d * n))
    pre = spla.LinearOperator((d * n, d * n), matvec=lu.solve, matmat=lu.solve, dtype=np.float64)
    rng = np.random.default_rng(seed)
    vecs = np.concatenate([y.T, rng.standard_normal((d * n, 4))], axis=1)
    for tol, maxiter in LOBPCG_PASSES:
        with warnings.catch_warnings():  # LOBPCG's notice when it stops at maxiter
            warnings.simplefilter("ignore", UserWarning)
            vals, vecs = spla.lobpcg(op, vecs, M=pre, largest=False, tol=tol, maxiter=maxiter)
        if vals.min() >= -EIG_TOL or not sharpen:
            break
    k = int(np.argmin(vals))
    v = vecs[:, k] / np.linalg.norm(vecs[:, k])
    return float(v @ s_times(v)), v


def certify_rotations(
    sync: SyncProblem, y: np.ndarray, objective: float | None = None, *, eta: float = EIG_TOL, sharpen: bool = True
) -> tuple[Certificate, np.ndarray]:
    """Verify rotations ``Y`` (``r x dn``); ``objective``: ``f`` at the estimate with its own
    translations (default: the best ones, ``f(Y)``). Returns the certificate and the eigenvector."""
    blocks = lambda_blocks(sync, y)
    tr_lambda = float(np.trace(blocks, axis1=1, axis2=2).sum())
    lam_min, v = min_eigenpair(sync, y, blocks, sharpen=sharpen)
    f_y = sync.objective(y)
    f = f_y if objective is None else objective
    lower = tr_lambda + sync.n * sync.d * min(lam_min, 0.0)
    # the estimate's own translations may be worse than the best ones for its rotations
    translations_ok = f - f_y <= 1e-9 * max(abs(f_y), 1.0) + eta
    return Certificate(f, min(lower, f), lam_min, lam_min >= -eta and translations_ok), v
