"""The one check of a problem before any back-end runs and of every back-end's answer after it
(issue 23): whichever method ran, a result that is not finite, whose chi2 rose, or that came from a
graph an optimizer cannot determine is refused in one line instead of being written as a success.

* before: every edge's information matrix is symmetric positive definite (a negative or zero
  eigenvalue makes chi2 unbounded below or flat: "chi2 306 -> 306" with nothing optimized), and every
  vertex is joined to the anchor by edges (without an inter-agent loop closure the other agents'
  placement is arbitrary; GTSAM calls the system indeterminate, g2o silently drifts);
* after: poses finite and within :data:`MAX_SOLUTION_M`, chi2 finite, and chi2 at the end not above
  chi2 at the start of the iterations (a robust method that rejected edges is exempt from this
  last rule: its chi2 over all edges may rise as it lets the outliers go).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from studio.core.errors import FormatError
from studio.core.geometry import upper_to_matrix
from studio.core.model import PoseKind
from studio.core.units import CHI2_RISE_TOLERANCE, MAX_SOLUTION_M
from studio.solvers.problem import Problem, Solution

__all__ = [
    "check_problem",
    "check_solution",
    "indefinite_information",
    "unreached_vertices",
    "MAX_SOLUTION_M",
    "CHI2_RISE_TOLERANCE",
]


def indefinite_information(information_upper: np.ndarray, dim: int) -> np.ndarray:
    """Indices of the rows whose ``dim x dim`` information matrix is not positive definite (or not
    finite)."""
    upper = np.asarray(information_upper, dtype=np.float64).reshape(len(information_upper), -1)
    if not len(upper):
        return np.zeros(0, dtype=np.int64)
    finite: np.ndarray = np.asarray(np.isfinite(upper).all(axis=1))
    mats = upper_to_matrix(np.where(finite[:, None], upper, 0.0), dim)
    smallest = np.linalg.eigvalsh(mats)[:, 0]
    return np.flatnonzero(~finite | ~(smallest > 0)).astype(np.int64)


def unreached_vertices(problem: Problem) -> np.ndarray:
    """Vertices with no path of edges to a held vertex (the anchor, or every one of
    :attr:`~Problem.anchors`) or a prior, in id order."""
    from studio.solvers.gauge import pieces

    _, labels = pieces(problem)
    holders = problem.held if problem.priors is None else np.concatenate([problem.held, problem.priors.vertex])
    return np.flatnonzero(~np.isin(labels, labels[holders])).astype(np.int64)


def check_problem(problem: Problem, where: str, vertex_name: Callable[[int], str] = lambda v: f"vertex {v}") -> None:
    """Refuse a problem no back-end can answer truthfully (see the module doc); ``where`` names the
    dataset, ``vertex_name`` turns a global id into the dataset's words (``agent2 vertex 0``)."""
    dim = 3 if problem.kind is PoseKind.SE2 else 6
    bad = indefinite_information(problem.information_upper, dim)
    if len(bad):
        e = int(bad[0])
        raise FormatError(
            f"{where}: the information matrix of the edge {vertex_name(int(problem.edge_from[e]))} -> "
            f"{vertex_name(int(problem.edge_to[e]))} is not positive definite ({len(bad)} such edges); "
            "an optimizer cannot weigh it"
        )
    lost = unreached_vertices(problem)
    if len(lost):
        raise FormatError(
            f"{where}: the graph is not connected: {len(lost)} vertices, from {vertex_name(int(lost[0]))}, have no "
            f"path of edges to {vertex_name(problem.anchor)} (no inter-agent loop closure?); their estimate "
            "would be arbitrary"
        )


def check_solution(
    problem: Problem, solution: Solution, chi2_start: float, chi2_final: float, *, method: str, where: str
) -> None:
    """Refuse an answer that is not finite, lies beyond :data:`MAX_SOLUTION_M`, or whose chi2 rose
    over the iterations (unless a robust method rejected edges)."""
    poses = np.asarray(solution.poses, dtype=np.float64)
    if poses.shape != problem.initial.shape:
        raise FormatError(f"{where}: method {method} returned {poses.shape} poses, expected {problem.initial.shape}")
    coords = poses[:, 0 : 2 if problem.kind is PoseKind.SE2 else 3]
    if not np.isfinite(poses).all() or not (np.abs(coords) <= MAX_SOLUTION_M).all():
        raise FormatError(
            f"{where}: method {method} returned poses that are not finite or lie beyond {MAX_SOLUTION_M:g} m "
            "(the optimization diverged)"
        )
    if not (np.isfinite(chi2_start) and np.isfinite(chi2_final)):
        raise FormatError(f"{where}: method {method}: chi2 {chi2_start:.6g} -> {chi2_final:.6g} is not finite")
    if solution.rejected is not None and np.any(solution.rejected):
        return  # a robust method's chi2 over all edges may rise as it lets outliers go: not a failure
    if not solution.minimizes_chi2:
        return  # another objective (SE-Sync's) may end at a higher chi2 than its start
    if chi2_final > chi2_start * (1 + CHI2_RISE_TOLERANCE) + CHI2_RISE_TOLERANCE:
        raise FormatError(
            f"{where}: method {method} made chi2 worse ({chi2_start:.6g} -> {chi2_final:.6g}); "
            "the estimate is not written"
        )
