"""What every optimizer back-end takes and returns: a pose graph flattened to global vertex ids, as
columns, and the optimized poses with their history."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from studio.core.model import PoseKind
from studio.core.residuals import chi2_terms, edge_errors

__all__ = ["Problem", "Solution", "SolveOptions", "Iteration", "Method", "Optimizer", "Init", "graph_chi2"]

Optimizer = Literal["gn", "lm"]
Init = Literal["chordal", "spanning-tree", "odometry"]

#: Called after every iteration with ``(iteration, poses)`` (iteration 0: the initial guess).
Iteration = Callable[[int, np.ndarray], None]


@dataclass(frozen=True, eq=False)
class Problem:
    """A pose graph over global vertex ids ``0..n-1``; vertex :attr:`anchor` is held fixed."""

    kind: PoseKind
    initial: np.ndarray
    """``(n, 3)`` planar or ``(n, 7)`` spatial poses: the starting values (e.g. dead reckoning)."""
    edge_from: np.ndarray
    edge_to: np.ndarray
    measurements: np.ndarray
    information_upper: np.ndarray
    robust: np.ndarray
    """Per edge, True where a robust method may reject it (loop closures); odometry is trusted."""
    anchor: int = 0
    agent_of_vertex: np.ndarray | None = None
    """Per vertex, the index of the robot (agent) that owns it, when known (a multi-g2o dataset);
    distributed methods (``dgs``) split the problem by it."""

    @property
    def num_vertices(self) -> int:
        return len(self.initial)

    @property
    def num_edges(self) -> int:
        return len(self.edge_from)


#: g2o's default iterations: the paper's setup, 10 Gauss-Newton iterations.
G2O_DEFAULT_ITERATIONS = 10
#: DGS's default rounds at most, both stages together.
DEFAULT_MAX_ROUNDS = 100


@dataclass(frozen=True)
class SolveOptions:
    """Options every method reads (each uses the ones that apply to it)."""

    optimizer: Optimizer = "gn"
    """Gauss-Newton or Levenberg-Marquardt."""
    init: Init = "chordal"
    """Initial guess: chordal relaxation, spanning tree of the measurements, or the dataset's values."""
    max_iterations: int = 20
    """Iterations at most (the ``g2o`` method runs exactly this many, 10 by default as the paper)."""
    relative_tolerance: float = 1e-9
    """Stop when the cost decreases by less than this fraction."""
    command: str = ""
    """``command`` method: the program to run, with ``{input}`` and ``{output}`` placeholders."""
    robots: int = 0
    """``dgs`` on a problem without robot identity (a single g2o): that many robots of contiguous
    vertex ids (DPGO's split); 0: 8, or fewer if the graph has fewer vertices."""
    rotation_tol: float = 0.2
    """``dgs``: the rotation stage stops when no rotation-matrix entry changes more in a round."""
    pose_tol: float = 1e-2
    """``dgs``: a pose-stage system stops when no update entry [m, rad] changes more in a round."""
    rotation_gamma: float = 1.0
    """``dgs``: over-relaxation of each robot's block update in the rotation stage (1: plain Gauss-Seidel)."""
    pose_gamma: float = 1.9
    """``dgs``: over-relaxation of each robot's block update in the pose stage (measured best of
    1, 1.3, 1.6, 1.9 on kollagen's datasets, see docs/solve.md)."""
    rotation_momentum: float | None = None
    """``dgs``: Nesterov momentum of the rotation stage's rounds (each robot extrapolates its own block;
    0: none; None: 0.9 with Gauss-Seidel rounds, 0 with Jacobi's, measured on kollagen's datasets,
    see docs/replay.md)."""
    pose_momentum: float = 0.0
    """``dgs``: Nesterov momentum of the pose stage's rounds (0: none; it diverges with over-relaxation)."""
    schedule: str = "gauss-seidel"
    """``dgs``: robots update in turn (``gauss-seidel``) or all from the last round (``jacobi``)."""


@dataclass(frozen=True, eq=False)
class Solution:
    poses: np.ndarray
    """Optimized poses, same layout as :attr:`Problem.initial`."""
    iterations: int
    chi2_history: tuple[float, ...] = ()
    """chi2 (g2o convention) of the initial guess and after each iteration, when the method has it."""
    rejected: np.ndarray | None = None
    """Robust methods: per edge, True where the edge was rejected as an outlier."""
    notes: dict[str, object] = field(default_factory=dict)
    """Facts about the run worth saving (initialisation time, library versions...)."""


class Method(Protocol):
    """An optimizer back-end: solve ``problem``; call ``on_iteration`` with each iterate if given."""

    def __call__(self, problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution: ...


def graph_chi2(problem: Problem, poses: np.ndarray) -> float:
    """Sum of ``e^T Omega e`` over the edges at ``poses`` (g2o's convention, see studio.core.residuals)."""
    e = edge_errors(poses[problem.edge_from], poses[problem.edge_to], problem.measurements)
    return float(chi2_terms(e, problem.information_upper).sum())
