"""``studio check --certify ESTIMATE`` as a library function: is an estimate of a dataset the global
optimum of SE-Sync's objective, and if not, how far above it can it be?

The dataset is read as ``studio solve`` reads it (a multi-g2o folder or a single g2o file, global
ids); the estimate is any layout ``studio evaluate`` takes for that dataset (the folder ``studio
solve`` wrote, a multi-g2o folder, a folder of TUM files with one pose per vertex) or, for a single
g2o dataset, a g2o file of its vertices (ids ``0..n-1``; edges ignored). The verification is
SE-Sync's (:mod:`studio.solvers.sesync_problem`): ``f`` at the estimate, the Lagrange multipliers
from its rotations, the smallest eigenvalue of the certificate matrix, and the verdict "certified
globally optimal" or "not certified, at most X above the optimum". An estimate that misses poses,
holds non-finite values or belongs to another graph is refused in one line naming the file.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import EvaluationError, FormatError
from studio.core.geometry import se3_poses_to_planar
from studio.core.model import PoseKind
from studio.core.types import PathLike

__all__ = ["CertifyReport", "certify", "read_estimate_poses"]


@dataclass(frozen=True)
class CertifyReport:
    dataset: str
    estimate: str
    num_vertices: int
    dimension: int
    objective: float
    """SE-Sync's ``f`` at the estimate."""
    lower_bound: float
    lambda_min: float
    certified: bool
    seconds: float

    @property
    def gap_bound(self) -> float:
        return max(self.objective - self.lower_bound, 0.0)

    def verdict(self) -> str:
        if self.certified:
            return "certified globally optimal"
        return f"not certified, at most {self.gap_bound:.6g} above the optimum"

    def to_dict(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset,
            "estimate": self.estimate,
            "num_vertices": self.num_vertices,
            "dimension": self.dimension,
            "sesync_f": self.objective,
            "lower_bound": self.lower_bound,
            "lambda_min": self.lambda_min,
            "certified": self.certified,
            "suboptimality_bound": self.gap_bound,
            "verdict": self.verdict(),
            "seconds": self.seconds,
        }

    def to_json(self) -> str:
        from studio.io.strict_json import dumps_strict

        return dumps_strict(self.to_dict(), self.estimate, indent=2)

    def format(self) -> str:
        return (
            f"{self.estimate}: {self.verdict()}\n"
            f"  SE-Sync objective f = {self.objective:.10g}  lower bound on f* = {self.lower_bound:.10g}\n"
            f"  lambda_min(S) = {self.lambda_min:.4g}  ({self.num_vertices} poses, {self.dimension}D, "
            f"{self.seconds:.2f} s)"
        )


def read_estimate_poses(estimate: PathLike, loaded: Any) -> np.ndarray:
    """The estimate's poses in the problem's layout (global ids, planar when the problem is)."""
    from studio.io.estimate import read_estimate, solve_output_estimate
    from studio.io.g2o import read_g2o

    path = Path(estimate)
    problem = loaded.problem
    n = problem.num_vertices
    if loaded.graph is not None:
        est = read_estimate(path, loaded.graph)
        sizes = [len(a.stamps_ns) for a in loaded.graph.agents]
        for a, size in zip(est.agents, sizes, strict=True):
            if len(a.positions_xyz) != size:
                raise EvaluationError(f"{est.source}: agent {a.name} has {len(a.positions_xyz)} poses, expected {size}")
        poses = np.concatenate([np.column_stack([a.positions_xyz, a.quat_xyzw]) for a in est.agents])
        where = est.source
    else:
        path = solve_output_estimate(path) or path
        if not path.is_file():
            raise FormatError(f"{path}: not a g2o file of the estimate's vertices")
        doc = read_g2o(path, edges=False)
        where = str(path)
        order = np.argsort(doc.vertex_ids, kind="stable")
        if len(order) != n or not np.array_equal(doc.vertex_ids[order], np.arange(n)):
            raise EvaluationError(f"{path}: {len(order)} vertices, expected ids 0..{n - 1} as the dataset's")
        if doc.kind is not loaded.source_kind:
            raise EvaluationError(f"{path}: {doc.kind.name} vertices, the dataset's are {loaded.source_kind.name}")
        poses = doc.vertex_poses[order]
        if doc.kind is PoseKind.SE2:
            return _finite(poses, where)
    poses = _finite(poses, where)
    if problem.kind is PoseKind.SE2:
        return se3_poses_to_planar(poses)
    return poses


def _finite(poses: np.ndarray, where: str) -> np.ndarray:
    bad = np.flatnonzero(~np.isfinite(poses).all(axis=1))
    if len(bad):
        raise FormatError(f"{where}: pose {int(bad[0])} (global id order) is not finite ({len(bad)} such poses)")
    return np.asarray(poses, dtype=np.float64)


def certify(dataset: PathLike, estimate: PathLike, *, dimension: str = "auto") -> CertifyReport:
    """Verify ``estimate`` of ``dataset`` with SE-Sync's certificate (see the module doc)."""
    from studio.solve import load_problem
    from studio.solvers.sesync import sync_problem
    from studio.solvers.sesync_problem import certify_rotations, rotation_matrices
    from studio.solvers.validate import check_problem

    t0 = time.perf_counter()
    loaded = load_problem(dataset, dimension=dimension)  # type: ignore[arg-type]
    problem = loaded.problem
    check_problem(problem, str(dataset))
    poses = read_estimate_poses(estimate, loaded)
    sync = sync_problem(problem)
    rot, trans = rotation_matrices(problem.kind, poses)
    rows = np.ascontiguousarray(rot.transpose(1, 0, 2).reshape(sync.d, -1))
    cert, _ = certify_rotations(sync, rows, sync.full_objective(rot, trans))
    return CertifyReport(
        str(dataset),
        str(estimate),
        sync.n,
        sync.d,
        cert.objective,
        cert.lower_bound,
        cert.lambda_min,
        cert.certified,
        time.perf_counter() - t0,
    )
