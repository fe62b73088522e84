"""The ``g2o`` method: g2o itself through its Python binding (``pip install g2opy``), set up as the
kollagen paper ran it: the spanning-tree initial guess (``computeInitialGuess``), then Gauss-Newton
with a sparse Cholesky (``BlockSolverX`` over ``LinearSolverEigenX``) for a fixed number of
iterations (10 by default). The anchor (vertex 0) is fixed: g2o's own gauge would otherwise be the
last vertex, left at its odometry value, which shifts the whole map.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import ConfigError, FormatError
from studio.core.model import PoseKind
from studio.io.g2o import G2oDocument, write_g2o
from studio.solvers.problem import G2O_DEFAULT_ITERATIONS, Iteration, Problem, Solution, SolveOptions, graph_chi2

__all__ = ["solve_g2o", "G2O_DEFAULT_ITERATIONS"]


def _g2o() -> Any:
    try:
        import g2opy
    except ImportError:
        raise ConfigError("method g2o needs g2o's Python binding: pip install 'cslam-studio[solve]'") from None
    return g2opy


def _read(opt: Any, kind: PoseKind, n: int) -> np.ndarray:
    if kind is PoseKind.SE2:
        return np.array([opt.vertex(k).estimate().to_vector() for k in range(n)], dtype=np.float64)
    out = np.array([opt.vertex(k).get_estimate_data() for k in range(n)], dtype=np.float64)
    out[out[:, 6] < 0, 3:7] *= -1.0
    return out


def solve_g2o(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    g2o = _g2o()
    kind, n = problem.kind, problem.num_vertices
    t0 = time.perf_counter()
    opt = g2o.SparseOptimizer()
    opt.set_algorithm(g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverX(g2o.LinearSolverEigenX())))
    # g2o's own reader builds the graph far faster than one Python call per vertex and edge
    with tempfile.TemporaryDirectory(prefix="studio-g2o-") as tmp:
        path = Path(tmp) / "problem.g2o"
        write_g2o(
            path,
            G2oDocument(
                kind,
                np.arange(n),
                problem.initial,
                problem.edge_from,
                problem.edge_to,
                problem.measurements,
                problem.information_upper,
            ),
        )
        if not opt.load(str(path)):
            raise FormatError("g2o could not load the problem it was given")
    if len(opt.vertices()) != n or len(opt.edges()) != problem.num_edges:
        raise FormatError(
            f"g2o loaded {len(opt.vertices())} vertices and {len(opt.edges())} edges of {n} and {problem.num_edges}"
        )
    opt.vertex(problem.anchor).set_fixed(True)
    opt.initialize_optimization()
    if options.init == "spanning-tree" or options.init == "chordal":
        # g2o has no chordal initialisation of its own: its spanning tree is the paper's setup
        opt.compute_initial_guess()
    t_build = time.perf_counter() - t0
    guess = _read(opt, kind, n)
    history = [graph_chi2(problem, guess)]
    if on_iteration is not None:
        on_iteration(0, guess)
    iterations = options.max_iterations
    if on_iteration is None:
        opt.optimize(iterations)
        poses = _read(opt, kind, n)
        history.append(graph_chi2(problem, poses))
    for it in range(1, iterations + 1 if on_iteration is not None else 1):
        opt.optimize(1)
        poses = _read(opt, kind, n)
        history.append(graph_chi2(problem, poses))
        on_iteration(it, poses)  # type: ignore[misc]
    return Solution(poses, iterations, tuple(history), notes={"build_s": t_build, "init": "spanning-tree"})
