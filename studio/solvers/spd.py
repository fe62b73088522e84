"""Factors of symmetric positive definite sparse matrices, for the solvers that factor many: QDLDL
(OSQP's sparse LDL^T with AMD ordering, the ``qdldl`` package of the ``solve`` extra) where
installed, else SuperLU. QDLDL takes about half of SuperLU's time to factor such a matrix and a
tenth or less to solve with it (SuperLU is a general LU; scikit-sparse's CHOLMOD does not build
against this system's SuiteSparse).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["spd_factor"]


class _Ldl:
    """QDLDL's factorization with SuperLU's ``solve`` (a vector or the columns of a matrix)."""

    def __init__(self, solver: Any) -> None:
        self.solver = solver

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        if b.ndim == 1:
            return np.asarray(self.solver.solve(b))
        out = np.empty_like(b)
        for k in range(b.shape[1]):
            out[:, k] = self.solver.solve(np.ascontiguousarray(b[:, k]))
        return out


def spd_factor(a: Any, *, permc_spec: str = "MMD_AT_PLUS_A") -> Any:
    """A factorization of the symmetric positive definite sparse ``a`` with ``.solve(b)``: QDLDL's
    LDL^T where the ``qdldl`` package is installed, else SuperLU's LU with ``permc_spec``."""
    try:
        import qdldl
    except ImportError:
        return _superlu(a, permc_spec)
    if a.shape[0] == 0:  # QDLDL refuses an empty matrix
        return _superlu(a, permc_spec)
    return _Ldl(qdldl.Solver(a.tocsc()))


def _superlu(a: Any, permc_spec: str) -> Any:
    import scipy.sparse.linalg as spla

    options = {"SymmetricMode": True} if permc_spec == "MMD_AT_PLUS_A" else {}
    return spla.splu(a.tocsc(), permc_spec=permc_spec, options=options)
