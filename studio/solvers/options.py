"""The options every optimizer back-end reads (:class:`SolveOptions`) and their word choices, without
numpy: the method registry (:mod:`studio.solvers`) and the command line's ``studio solve`` options are
declared from them at start-up, before any solver or graph is loaded. :mod:`studio.solvers.problem`
re-exports them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["SolveOptions", "Optimizer", "Init", "G2O_DEFAULT_ITERATIONS", "DEFAULT_MAX_ROUNDS", "SESYNC_MAX_ITERATIONS"]

Optimizer = Literal["gn", "lm"]
Init = Literal["chordal", "spanning-tree", "odometry"]

#: g2o's default iterations: the paper's setup, 10 Gauss-Newton iterations.
G2O_DEFAULT_ITERATIONS = 10
#: sesync's trust-region iterations at most per rank of the staircase (SE-Sync's ``max_iterations``).
SESYNC_MAX_ITERATIONS = 1000
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
    pose_gamma: float | None = None
    """``dgs``: over-relaxation of each robot's block update in the pose stage (None: 1.5 with the
    two-level correction, 1.9 for plain DGS, ``coarse_size=0``: the fastest measured, docs/solve.md)."""
    coarse_size: int = 5
    """``dgs``: vertices per aggregate of the two-level correction (each run of that many poses of
    a robot moved rigidly, solved jointly by a coordinator every round); 0: plain DGS."""
    rotation_momentum: float | None = None
    """``dgs``: Nesterov momentum of the rotation stage's rounds (each robot extrapolates its own block;
    0: none; None: 0.9 with Gauss-Seidel rounds, 0 with Jacobi's, measured on kollagen's datasets,
    see docs/replay.md)."""
    pose_momentum: float = 0.0
    """``dgs``: Nesterov momentum of the pose stage's rounds (0: none; it diverges with over-relaxation)."""
    schedule: str = "gauss-seidel"
    """``dgs``: robots update in turn (``gauss-seidel``) or all from the last round (``jacobi``)."""
