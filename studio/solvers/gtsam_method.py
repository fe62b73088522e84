"""The ``gtsam`` and ``gnc`` methods: GTSAM's factor graphs and optimizers (``pip install gtsam``).

``gtsam``: a global initial guess (planar chordal relaxation of :mod:`studio.solvers.init`, GTSAM's
``InitializePose3`` chordal relaxation in 3D, or the spanning tree), then Gauss-Newton or
Levenberg-Marquardt on ``BetweenFactorPose2/3`` with each edge's full information matrix, the
anchor held by a hard prior. Every iterate is passed to the callback.

``gnc``: the same factors under GTSAM's graduated non-convexity (``GncLMOptimizer``, truncated least
squares) from the same initial guess; odometry edges are known inliers, loop closures whose final
weight is below 0.5 are reported as rejected.

GTSAM orders a Pose3 tangent vector ``(rotation, translation)`` while the g2o files and the studio's
information matrices are ``(translation, rotation)``: 3D information is permuted on the way in. The
files' rotation information refers to g2o's error (the quaternion's vector part, about half the
rotation vector GTSAM uses), so it is converted: ``Omega_gtsam = J^T Omega J`` with
``J = diag(1, 1, 1, 1/2, 1/2, 1/2)``; without that GTSAM would weigh rotations 4 times too much.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np

from studio.core.errors import ConfigError
from studio.core.geometry import upper_to_matrix
from studio.core.model import PoseKind
from studio.solvers.init import chordal_se2, roots_of, spanning_tree
from studio.solvers.problem import Iteration, Problem, Solution, SolveOptions, graph_chi2

__all__ = ["solve_gtsam", "solve_gnc"]

_PERMUTE_SE3 = np.array([3, 4, 5, 0, 1, 2])


def _gtsam() -> Any:
    try:
        import gtsam
    except ImportError:
        raise ConfigError("method gtsam needs GTSAM: pip install 'cslam-studio[solve]'") from None
    return gtsam


def _pose(gtsam: Any, kind: PoseKind, row: np.ndarray) -> Any:
    if kind is PoseKind.SE2:
        return gtsam.Pose2(float(row[0]), float(row[1]), float(row[2]))
    q = row[3:7]
    return gtsam.Pose3(
        gtsam.Rot3.Quaternion(float(q[3]), float(q[0]), float(q[1]), float(q[2])),
        gtsam.Point3(float(row[0]), float(row[1]), float(row[2])),
    )


def _values(gtsam: Any, kind: PoseKind, poses: np.ndarray) -> Any:
    values = gtsam.Values()
    for k in range(len(poses)):
        values.insert(k, _pose(gtsam, kind, poses[k]))
    return values


def _poses(gtsam: Any, kind: PoseKind, values: Any) -> np.ndarray:
    if kind is PoseKind.SE2:
        return np.asarray(gtsam.utilities.extractPose2(values), dtype=np.float64)
    from scipy.spatial.transform import Rotation

    m = np.asarray(gtsam.utilities.extractPose3(values), dtype=np.float64)
    quat = Rotation.from_matrix(m[:, 0:9].reshape(-1, 3, 3)).as_quat()
    quat[quat[:, 3] < 0] *= -1.0
    return np.column_stack([m[:, 9:12], quat])


def _information(kind: PoseKind, information_upper: np.ndarray) -> np.ndarray:
    """Information matrices of the studio's convention in GTSAM's (see the module doc)."""
    d = 3 if kind is PoseKind.SE2 else 6
    omega = upper_to_matrix(information_upper, d)
    if kind is PoseKind.SE3:
        half = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
        omega = (omega * half[None, :, None] * half[None, None, :])[:, _PERMUTE_SE3][:, :, _PERMUTE_SE3]
    return omega


def _graph(gtsam: Any, problem: Problem) -> tuple[Any, int]:
    """The factor graph of the problem's edges (factor k is edge k), then its priors (weighed by
    their information) and a hard prior on each held vertex (the anchor alone without a gauge)."""
    kind = problem.kind
    graph = gtsam.NonlinearFactorGraph()
    d = 3 if kind is PoseKind.SE2 else 6
    omega = _information(kind, problem.information_upper)
    factor = gtsam.BetweenFactorPose2 if kind is PoseKind.SE2 else gtsam.BetweenFactorPose3
    gaussian = gtsam.noiseModel.Gaussian.Information
    fr, to, z = problem.edge_from.tolist(), problem.edge_to.tolist(), problem.measurements
    for k in range(problem.num_edges):
        graph.add(factor(fr[k], to[k], _pose(gtsam, kind, z[k]), gaussian(omega[k])))
    prior = gtsam.PriorFactorPose2 if kind is PoseKind.SE2 else gtsam.PriorFactorPose3
    if problem.priors is not None:
        p = problem.priors
        p_omega = _information(kind, p.information_upper)
        for k, v in enumerate(p.vertex.tolist()):
            graph.add(prior(v, _pose(gtsam, kind, p.poses[k]), gaussian(p_omega[k])))
    for v in problem.held.tolist():
        graph.add(prior(v, _pose(gtsam, kind, problem.initial[v]), gtsam.noiseModel.Constrained.All(d)))
    return graph, problem.num_edges


def _chordal_se3(gtsam: Any, problem: Problem, graph: Any) -> np.ndarray:
    """GTSAM's chordal relaxation (``InitializePose3``: rotations, then one Gauss-Newton step on full
    poses; the graph's hard priors hold the gauge), moved so each held vertex keeps its pose exactly.
    ``InitializePose3`` finds a graph held by Gaussian priors alone indeterminate: where there are
    priors it starts from the edges with each piece's first prior held hard at its value (the
    spanning tree's roots), and the iterations then weigh the priors by their information."""
    if problem.priors is not None and len(problem.priors):
        start = gtsam.NonlinearFactorGraph()
        for k in range(problem.num_edges):
            start.add(graph.at(k))
        roots, poses = roots_of(problem)
        for v, pose in zip(roots.tolist(), poses):
            start.add(gtsam.PriorFactorPose3(v, _pose(gtsam, PoseKind.SE3, pose), gtsam.noiseModel.Constrained.All(6)))
        graph = start
    return _reanchor(problem, _poses(gtsam, PoseKind.SE3, gtsam.InitializePose3.initialize(graph)))


def initial_guess(gtsam: Any, problem: Problem, options: SolveOptions, graph: Any) -> np.ndarray:
    if options.init == "odometry":
        return problem.initial
    if options.init == "spanning-tree":
        return spanning_tree(problem)
    if problem.kind is PoseKind.SE2:
        return chordal_se2(problem)
    return _chordal_se3(gtsam, problem, graph)


def _optimizer(gtsam: Any, graph: Any, values: Any, options: SolveOptions) -> Any:
    if options.optimizer == "lm":
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(options.max_iterations)
        params.setRelativeErrorTol(options.relative_tolerance)
        return gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    params = gtsam.GaussNewtonParams()
    params.setMaxIterations(options.max_iterations)
    params.setRelativeErrorTol(options.relative_tolerance)
    return gtsam.GaussNewtonOptimizer(graph, values, params)


def _moved(kind: PoseKind, poses: np.ndarray, a: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``poses`` moved by the rigid transform that puts pose ``a`` on ``target``."""
    from studio.core.geometry import normalize_angle, quat_conj, quat_mul, quat_rotate

    if kind is PoseKind.SE2:
        dth = target[2] - a[2]
        c, s = np.cos(dth), np.sin(dth)
        xy = (poses[:, 0:2] - a[0:2]) @ np.array([[c, s], [-s, c]]) + target[0:2]
        return np.column_stack([xy, normalize_angle(poses[:, 2] + dth)])
    dq = np.repeat(quat_mul(target[None, 3:7], quat_conj(a[None, 3:7])), len(poses), axis=0)
    q = quat_mul(dq, poses[:, 3:7])
    return np.column_stack(
        [quat_rotate(dq, poses[:, 0:3] - a[0:3]) + target[0:3], q / np.linalg.norm(q, axis=1, keepdims=True)]
    )


def _reanchor(problem: Problem, poses: np.ndarray) -> np.ndarray:
    """``poses`` with each held vertex's piece moved rigidly so the vertex is back on its initial
    pose (the anchor alone: the whole graph); pieces held by priors stay where they are."""
    if problem.anchors is None:
        anchor = problem.anchor
        moved = _moved(problem.kind, poses, poses[anchor], problem.initial[anchor])
        moved[anchor] = problem.initial[anchor]
        return moved
    from studio.solvers.gauge import pieces

    _, labels = pieces(problem)
    out: np.ndarray = poses.copy()
    for v in problem.anchors.tolist():
        rows = np.flatnonzero(labels == labels[v])
        out[rows] = _moved(problem.kind, poses[rows], poses[v], problem.initial[v])
        out[v] = problem.initial[v]
    return out


def solve_gtsam(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    gtsam = _gtsam()
    t0 = time.perf_counter()
    graph, _ = _graph(gtsam, problem)
    t_build = time.perf_counter() - t0
    guess = initial_guess(gtsam, problem, options, graph)
    t_init = time.perf_counter() - t0 - t_build
    if on_iteration is not None:
        on_iteration(0, guess)
    history = [graph_chi2(problem, guess)]
    lowest = _Lowest(history[0], guess, 0)
    opt = _optimizer(gtsam, graph, _values(gtsam, problem.kind, guess), options)
    error = opt.error()
    iterations = 0
    poses = guess
    switched = False
    while iterations < options.max_iterations:
        before = gtsam.Values(opt.values())  # a copy: the optimizer owns its values
        try:
            opt.iterate()
            new_error = opt.error()
        except RuntimeError as err:
            # Gauss-Newton's Cholesky finds the system indeterminate on some connected graphs whose
            # information is ill-conditioned (SE-Sync's ais2klinik, bridged over a missing odometry
            # link by its loop closures): Levenberg-Marquardt's damping keeps it solvable
            if options.optimizer != "gn" or switched or "Indeterminate" not in str(err):
                raise
            new_error = np.inf
        if new_error > error and options.optimizer == "gn" and not switched:
            # a Gauss-Newton step that raises the cost (over-confident information far from the
            # optimum, e.g. kollagen's Exact odometry) or cannot be solved: go on with
            # Levenberg-Marquardt from the last good values instead of stopping there
            switched = True
            opt = _optimizer(gtsam, graph, before, dataclasses.replace(options, optimizer="lm"))
            continue
        iterations += 1
        poses = _poses(gtsam, problem.kind, opt.values())
        history.append(graph_chi2(problem, poses))
        lowest.visit(history[-1], poses, iterations)
        if on_iteration is not None:
            on_iteration(iterations, poses)
        if abs(error - new_error) <= options.relative_tolerance * max(error, 1e-300) or new_error > error:
            break
        error = new_error
    certified_start = _from_certified(gtsam, problem, options, graph, history[-1])
    if certified_start["poses"] is not None:
        poses = certified_start.pop("poses")
        history.append(graph_chi2(problem, poses))
        iterations += 1  # the answer from the certified start counts as the last iteration
        if on_iteration is not None:
            on_iteration(iterations, poses)
    certified_start.pop("poses", None)
    kept = lowest.keep_if_lower(history[-1])
    if kept is not None:
        poses = lowest.poses
        history.append(lowest.chi2)
    return Solution(
        poses,
        iterations,
        tuple(history),
        notes={
            "build_s": t_build,
            "init_s": t_init,
            "init": options.init,
            "optimizer": options.optimizer + (" then lm (a gn step raised the cost or failed)" if switched else ""),
            "certified_start": certified_start,
            **({"lowest_chi2_visited": kept} if kept is not None else {}),
        },
    )


@dataclasses.dataclass
class _Lowest:
    """The iterate of lowest chi2 seen. GTSAM minimizes its own error (the logarithm's), chi2 is
    g2o's; where the information is ill-conditioned their optima differ far enough that GTSAM's ends
    above its start in chi2 (SE-Sync's ``MIT.g2o``: 79.18 -> 108.52, from either start), and the
    answer is then the lowest-chi2 iterate, not a worse one."""

    chi2: float
    poses: np.ndarray
    iteration: int

    def visit(self, chi2: float, poses: np.ndarray, iteration: int) -> None:
        if np.isfinite(chi2) and chi2 < self.chi2:
            self.chi2, self.poses, self.iteration = chi2, poses, iteration

    def keep_if_lower(self, chi2_last: float) -> dict[str, float] | None:
        """What the notes say when the lowest iterate beats the last answer's ``chi2_last``."""
        if not (self.chi2 < chi2_last):
            return None
        return {"iteration": self.iteration, "chi2": self.chi2, "chi2_last": chi2_last}


def _from_certified(gtsam: Any, problem: Problem, options: SolveOptions, graph: Any, chi2: float) -> dict[str, Any]:
    """Gauss-Newton (or ``options``' Levenberg-Marquardt) from SE-Sync's certified solution
    (:mod:`studio.solvers.sesync`): a local
    method's answer may lie in a worse basin of chi2 than the one around the global optimum of
    SE-Sync's (isotropic) objective. ``poses`` holds the better answer when it is lower than
    ``chi2``, else None; the rest says what was compared and which was chosen."""
    from studio.solvers.sesync import solve_sesync

    if problem.anchors is not None:  # SE-Sync's problem is one connected graph held at one vertex
        return {"poses": None, "chosen": "local", "skipped": "the graph is held by priors or is in pieces"}
    t0 = time.perf_counter()
    try:
        start = solve_sesync(problem, dataclasses.replace(options, max_iterations=1000)).poses
    except ConfigError as err:  # pymanopt missing: the local answer stands, and the notes say so
        return {"poses": None, "chosen": "local", "skipped": str(err)}
    lm = options.optimizer == "lm"
    params = gtsam.LevenbergMarquardtParams() if lm else gtsam.GaussNewtonParams()
    params.setMaxIterations(max(options.max_iterations, 50))
    params.setRelativeErrorTol(options.relative_tolerance)
    optimizer = gtsam.LevenbergMarquardtOptimizer if lm else gtsam.GaussNewtonOptimizer
    try:
        result = optimizer(graph, _values(gtsam, problem.kind, start), params).optimize()
    except RuntimeError:  # Gauss-Newton's system indeterminate (see solve_gtsam): Levenberg-Marquardt
        lm_params = gtsam.LevenbergMarquardtParams()
        lm_params.setMaxIterations(max(options.max_iterations, 50))
        lm_params.setRelativeErrorTol(options.relative_tolerance)
        result = gtsam.LevenbergMarquardtOptimizer(graph, _values(gtsam, problem.kind, start), lm_params).optimize()
    poses = _poses(gtsam, problem.kind, result)
    refined = graph_chi2(problem, poses)
    better = bool(np.isfinite(refined) and refined < chi2)
    return {
        "poses": poses if better else None,
        "chosen": "certified start" if better else "local",
        "chi2_local": chi2,
        "chi2_certified_start": refined,
        "seconds": time.perf_counter() - t0,
    }


def solve_gnc(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    gtsam = _gtsam()
    graph, n_edges = _graph(gtsam, problem)
    guess = initial_guess(gtsam, problem, options, graph)
    if on_iteration is not None:
        on_iteration(0, guess)
    params = gtsam.GncLMParams()
    params.setMaxIterations(max(options.max_iterations, 100))
    gauge = list(range(n_edges, int(graph.size())))  # the priors and the held vertices' hard priors
    trusted = [int(k) for k in np.flatnonzero(~problem.robust)] + gauge
    params.setKnownInliers(trusted)
    opt = gtsam.GncLMOptimizer(graph, _values(gtsam, problem.kind, guess), params)
    result = opt.optimize()
    # GNC re-weights factors and does not keep the anchor's hard prior exactly: put it back
    poses = _reanchor(problem, _poses(gtsam, problem.kind, result))
    weights = np.asarray(opt.getWeights(), dtype=np.float64)[:n_edges]
    rejected = problem.robust & (weights < 0.5)
    # GNC stops once the weights settle; finish with plain least squares on the inliers
    inliers = gtsam.NonlinearFactorGraph()
    for k in np.flatnonzero(~rejected).tolist() + gauge:
        inliers.add(graph.at(k))
    refine = _optimizer(gtsam, inliers, _values(gtsam, problem.kind, poses), options)
    poses = _reanchor(problem, _poses(gtsam, problem.kind, refine.optimize()))
    if on_iteration is not None:
        on_iteration(1, poses)
    return Solution(
        poses,
        1,
        (graph_chi2(problem, guess), graph_chi2(problem, poses)),
        rejected,
        notes={"init": options.init, "rejected": int(rejected.sum())},
    )
