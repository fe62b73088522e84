"""What every optimizer back-end takes and returns: a pose graph flattened to global vertex ids, as
columns, and the optimized poses with their history."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from studio.core.model import PoseKind
from studio.core.residuals import chi2_terms, edge_errors
from studio.solvers.options import DEFAULT_MAX_ROUNDS, G2O_DEFAULT_ITERATIONS, Init, Optimizer, SolveOptions

__all__ = [
    "Problem",
    "VertexPriors",
    "Solution",
    "SolveOptions",
    "Iteration",
    "Method",
    "Optimizer",
    "Init",
    "graph_chi2",
    "G2O_DEFAULT_ITERATIONS",
    "DEFAULT_MAX_ROUNDS",
]

#: Called after every iteration with ``(iteration, poses)`` (iteration 0: the initial guess).
Iteration = Callable[[int, np.ndarray], None]


@dataclass(frozen=True, eq=False)
class VertexPriors:
    """Pose priors on vertices (JRL's ``PriorFactorPose2/3``): per row the vertex, the prior's pose
    and its information in the edges' convention (a measurement of the pose from the origin)."""

    vertex: np.ndarray
    poses: np.ndarray
    information_upper: np.ndarray

    def __len__(self) -> int:
        return len(self.vertex)


@dataclass(frozen=True, eq=False)
class Problem:
    """A pose graph over global vertex ids ``0..n-1``; vertex :attr:`anchor` is held fixed, or,
    where :attr:`anchors` is given, those vertices and the :attr:`priors` hold the gauge
    (:mod:`studio.solvers.gauge`)."""

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
    priors: VertexPriors | None = None
    """Pose priors (a dataset's ``priors.txt``), used as the gauge by the methods that take them."""
    anchors: np.ndarray | None = None
    """The vertices held fixed at their initial values, one per connected piece that holds no prior
    (:func:`studio.solvers.gauge.with_gauge`); None: :attr:`anchor` alone."""

    @property
    def held(self) -> np.ndarray:
        """The vertices held fixed: :attr:`anchors`, else :attr:`anchor` alone."""
        return np.array([self.anchor], dtype=np.int64) if self.anchors is None else self.anchors

    @property
    def num_vertices(self) -> int:
        return len(self.initial)

    @property
    def num_edges(self) -> int:
        return len(self.edge_from)


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
    minimizes_chi2: bool = True
    """False for a method whose objective is not chi2 (``sesync``: SE-Sync's isotropic objective),
    which the check that chi2 did not rise leaves alone."""


class Method(Protocol):
    """An optimizer back-end: solve ``problem`` with the shared ``options`` it reads and its own
    (``options.own_options(ItsOptions)``, the class its registry entry names); call ``on_iteration``
    with each iterate if given."""

    def __call__(self, problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution: ...


def graph_chi2(problem: Problem, poses: np.ndarray, edges: np.ndarray | None = None) -> float:
    """Sum of ``e^T Omega e`` over the edges at ``poses`` (g2o's convention, see studio.core.residuals);
    ``edges``: only the edges of this mask (or index array)."""
    fr, to, z, info = problem.edge_from, problem.edge_to, problem.measurements, problem.information_upper
    if edges is not None:
        fr, to, z, info = fr[edges], to[edges], z[edges], info[edges]
    return float(chi2_terms(edge_errors(poses[fr], poses[to], z), info).sum())
