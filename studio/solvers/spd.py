"""Factors of symmetric positive definite sparse matrices, for the solvers that factor many: QDLDL
(OSQP's sparse LDL^T with AMD ordering, the ``qdldl`` package of the ``solve`` extra) where
installed, else SuperLU. QDLDL takes about half of SuperLU's time to factor such a matrix and a
tenth or less to solve with it (SuperLU is a general LU; scikit-sparse's CHOLMOD does not build
against this system's SuiteSparse).

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


def spd_factor(a: Any, *, permc_spec: str = "MMD_AT_PLUS_A", upper: bool = False) -> Any:
    """A factorization of the symmetric positive definite sparse ``a`` with ``.solve(b)`` and
    ``.update(a)``: QDLDL's LDL^T where the ``qdldl`` package is installed, else SuperLU's LU with
    ``permc_spec``. With ``upper``, ``a`` holds only its upper triangle (the lower is ignored)."""
    try:
        import qdldl
    except ImportError:
        return _Lu(a, upper, permc_spec)
    if a.shape[0] == 0:  # QDLDL refuses an empty matrix
        return _Lu(a, upper, permc_spec)
    return _Ldl(qdldl.Solver(a.tocsc(), upper=upper), upper)
