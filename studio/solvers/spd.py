"""Factors of symmetric positive definite sparse matrices, for the solvers that factor many: QDLDL
(OSQP's sparse LDL^T with AMD ordering, the ``qdldl`` package of the ``solve`` extra) where
installed, else SuperLU. QDLDL takes about half of SuperLU's time to factor such a matrix and a
tenth or less to solve with it (SuperLU is a general LU; scikit-sparse's CHOLMOD does not build
against this system's SuiteSparse).

QDLDL is simplicial: it adds the factor's columns up one entry at a time, which is fast while the
factor stays about as sparse as the matrix (a robot's chain of poses) and slow where it fills in
(DGS's coarse system, whose aggregates couple across robots: 1.2 million entries in the factor of
a matrix with 0.28 million). There ``supernodal`` takes CHOLMOD's supernodal Cholesky (the
``cvxopt`` package of the ``solve`` extra), which factors the dense blocks of such a factor with
BLAS: 16 ms against QDLDL's 55 ms on Multi10000x5's last coarse system, though it solves no faster.

A factor's ``update(a)`` factors a matrix of the same sparsity pattern again, keeping the ordering
and the symbolic analysis (QDLDL's AMD ordering is most of its time on the chains of a pose graph):
what a solver relinearizing the same graph does many times.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["spd_factor"]


class _Ldl:
    """QDLDL's factorization with SuperLU's ``solve`` (a vector or the columns of a matrix)."""

    def __init__(self, solver: Any, upper: bool) -> None:
        self.solver = solver
        self.upper = upper

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        if b.ndim == 1:
            return np.asarray(self.solver.solve(b))
        out = np.empty_like(b)
        for k in range(b.shape[1]):
            out[:, k] = self.solver.solve(np.ascontiguousarray(b[:, k]))
        return out

    def update(self, a: Any) -> None:
        """Factor ``a`` (the pattern of the first, given the same way) in place of the first."""
        self.solver.update(a.tocsc(), upper=self.upper)


class _Cholmod:
    """CHOLMOD's supernodal Cholesky of a matrix given by one triangle, with the same ``solve``
    and ``update`` (the ordering and symbolic analysis kept; a matrix of the same pattern only
    replaces the numbers of the first, which is cvxopt's cheap way: building its sparse matrix from
    coordinates sorts them, half the time of a numeric factorization)."""

    def __init__(self, a: Any, upper: bool, permc_spec: str) -> None:
        from cvxopt import cholmod, matrix, spmatrix

        self.upper, self.permc_spec = upper, permc_spec
        self.ldl: Any = None
        """The LDL^T factor that took over where a matrix was not numerically positive definite."""
        a = _sorted_csc(a)
        cols = np.repeat(np.arange(a.shape[1], dtype=np.int64), np.diff(a.indptr))
        self.matrix = spmatrix(matrix(a.data), matrix(a.indices.astype(np.int64)), matrix(cols), a.shape)
        self.factor = cholmod.symbolic(self.matrix, uplo="U" if upper else "L")
        self.update(a)

    def solve(self, b: np.ndarray) -> np.ndarray:
        from cvxopt import cholmod, matrix

        if self.ldl is not None:
            return np.asarray(self.ldl.solve(b))
        b = np.asarray(b, dtype=np.float64)
        x = matrix(b.reshape(len(b), -1))
        cholmod.solve(self.factor, x)
        return np.array(x).reshape(b.shape)

    def update(self, a: Any) -> None:
        from cvxopt import cholmod, matrix

        if self.ldl is not None:
            self.ldl.update(a)
            return
        self.matrix.V = matrix(_sorted_csc(a).data)  # column by column, rows sorted: cvxopt's order
        try:
            cholmod.numeric(self.matrix, self.factor)
        except ArithmeticError:  # a pivot rounded to zero or below: LDL^T takes any nonzero one
            self.ldl = spd_factor(a, permc_spec=self.permc_spec, upper=self.upper)


def _sorted_csc(a: Any) -> Any:
    a = a.tocsc()
    return a if a.has_sorted_indices else a.sorted_indices()


class _Lu:
    """SuperLU's factorization, with the same ``update`` (a new factorization)."""

    def __init__(self, a: Any, upper: bool, permc_spec: str) -> None:
        self.upper, self.permc_spec = upper, permc_spec
        self.update(a)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return np.asarray(self.lu.solve(np.asarray(b, dtype=np.float64)))

    def update(self, a: Any) -> None:
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        if self.upper:  # the whole matrix from its upper triangle
            a = sp.triu(a) + sp.triu(a, k=1).T
        options = {"SymmetricMode": True} if self.permc_spec == "MMD_AT_PLUS_A" else {}
        self.lu = spla.splu(a.tocsc(), permc_spec=self.permc_spec, options=options)


def spd_factor(a: Any, *, permc_spec: str = "MMD_AT_PLUS_A", upper: bool = False, supernodal: bool = False) -> Any:
    """A factorization of the symmetric positive definite sparse ``a`` with ``.solve(b)`` and
    ``.update(a)``: QDLDL's LDL^T where the ``qdldl`` package is installed, else SuperLU's LU with
    ``permc_spec``; with ``supernodal`` (a factor that fills in), CHOLMOD's supernodal Cholesky
    where ``cvxopt`` is installed. With ``upper``, ``a`` holds only its upper triangle (the lower
    is ignored). A singular matrix raises RuntimeError."""
    if supernodal and a.shape[0]:
        try:
            import cvxopt  # noqa: F401
        except ImportError:
            pass
        else:
            return _Cholmod(a, upper, permc_spec)
    try:
        import qdldl
    except ImportError:
        return _Lu(a, upper, permc_spec)
    if a.shape[0] == 0:  # QDLDL refuses an empty matrix
        return _Lu(a, upper, permc_spec)
    return _Ldl(qdldl.Solver(a.tocsc(), upper=upper), upper)
