"""Optimizer back-ends on small graphs with a known optimum, and the g2o-convention residuals."""

from __future__ import annotations

import builtins
import sys

import numpy as np
import pytest

from studio.core.errors import ConfigError
from studio.core.geometry import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from studio.core.model import PoseKind
from studio.core.residuals import chi2_terms, edge_errors
from studio.solvers import METHODS, get_method
from studio.solvers.init import chordal_se2, spanning_tree
from studio.solvers.options import CommandOptions, DgsOptions
from studio.solvers.problem import Problem, SolveOptions, graph_chi2


def _relative(kind, a, b):
    if kind is PoseKind.SE2:
        c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
        dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
        dth = np.arctan2(np.sin(b[:, 2] - a[:, 2]), np.cos(b[:, 2] - a[:, 2]))
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy, dth])
    qi = quat_conj(a[:, 3:7])
    return np.column_stack([quat_rotate(qi, b[:, 0:3] - a[:, 0:3]), quat_mul(qi, b[:, 3:7])])


def make_problem(
    kind: PoseKind, n: int = 60, *, seed: int = 1, closures: int = 25, outliers: int = 0, noise: float = 0.0
):
    """A noiseless (or noisy) walk with loop closures; the initial values are a drifted copy."""
    rng = np.random.default_rng(seed)
    if kind is PoseKind.SE2:
        yaw = np.cumsum(rng.normal(0, 0.3, n))
        xy = np.cumsum(np.column_stack([np.cos(yaw), np.sin(yaw)]), axis=0)
        gt = np.column_stack([xy, np.arctan2(np.sin(yaw), np.cos(yaw))])
    else:
        q = np.zeros((n, 4))
        q[0] = [0, 0, 0, 1]
        for k in range(1, n):
            q[k] = quat_mul(q[k - 1 : k], quat_from_rotvec(rng.normal(0, 0.2, (1, 3))))[0]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        t = np.cumsum(quat_rotate(q, np.tile([1.0, 0, 0], (n, 1))), axis=0)
        gt = np.column_stack([t, q])
    fr = list(range(n - 1))
    to = list(range(1, n))
    pairs = set()
    while len(pairs) < closures:
        i, j = sorted(rng.choice(n, 2, replace=False).tolist())
        if j - i > 2:
            pairs.add((i, j))
    fr += [p[0] for p in sorted(pairs)]
    to += [p[1] for p in sorted(pairs)]
    fr, to = np.array(fr), np.array(to)
    z = _relative(kind, gt[fr], gt[to])
    robust = np.arange(len(fr)) >= n - 1
    planted = np.zeros(len(fr), dtype=bool)
    if outliers:
        picks = rng.choice(np.flatnonzero(robust), outliers, replace=False)
        planted[picks] = True
        if kind is PoseKind.SE2:
            z[picks, 0:2] += rng.uniform(5, 10, (outliers, 2))
            z[picks, 2] += 1.5
        else:
            z[picks, 0:3] += rng.uniform(5, 10, (outliers, 3))
    d = 3 if kind is PoseKind.SE2 else 6
    rows, cols = np.triu_indices(d)
    info = np.tile(np.where(rows == cols, 100.0, 0.0), (len(fr), 1))
    drift = gt.copy()
    if kind is PoseKind.SE2:
        drift[:, 2] += np.linspace(0, 0.3, n)
        drift[:, 0:2] += np.linspace(0, 2, n)[:, None]
    else:
        drift[:, 0:3] += np.linspace(0, 2, n)[:, None]
    drift[0] = gt[0]
    return Problem(kind, drift, fr, to, z, info, robust), gt, planted


def _pose_distance(kind, a, b):
    if kind is PoseKind.SE2:
        return max(np.abs(a[:, 0:2] - b[:, 0:2]).max(), np.abs(np.angle(np.exp(1j * (a[:, 2] - b[:, 2])))).max())
    dq = np.abs(np.abs(np.einsum("ij,ij->i", a[:, 3:7], b[:, 3:7])) - 1.0).max()
    return max(np.abs(a[:, 0:3] - b[:, 0:3]).max(), dq)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
@pytest.mark.parametrize("method", ["gtsam", "g2o", "gnc"])
def test_a_noiseless_graph_solves_to_its_ground_truth(kind, method):
    problem, gt, _ = make_problem(kind)
    assert graph_chi2(problem, problem.initial) > 1.0
    sol = get_method(method)(problem, SolveOptions(max_iterations=20))
    assert _pose_distance(kind, sol.poses, gt) < 1e-9
    assert graph_chi2(problem, sol.poses) < 1e-12


def test_planar_chordal_guess_is_exact_on_noiseless_data():
    problem, gt, _ = make_problem(PoseKind.SE2)
    assert _pose_distance(PoseKind.SE2, chordal_se2(problem), gt) < 1e-9
    assert _pose_distance(PoseKind.SE2, spanning_tree(problem), gt) < 1e-9


def test_spanning_tree_guess_in_3d_is_exact_on_noiseless_data():
    problem, gt, _ = make_problem(PoseKind.SE3)
    assert _pose_distance(PoseKind.SE3, spanning_tree(problem), gt) < 1e-9


def test_square_loop_with_one_perturbed_closure_reaches_the_same_optimum_in_gtsam_and_g2o():
    gt = np.array([[0, 0, 0], [1, 0, np.pi / 2], [1, 1, np.pi], [0, 1, -np.pi / 2]], dtype=float)
    fr, to = np.array([0, 1, 2, 3]), np.array([1, 2, 3, 0])
    z = _relative(PoseKind.SE2, gt[fr], gt[to])
    z[3] += [0.2, -0.1, 0.05]  # the closing edge disagrees with the odometry
    info = np.tile([100.0, 0, 0, 100.0, 0, 100.0], (4, 1))
    problem = Problem(PoseKind.SE2, gt.copy(), fr, to, z, info, np.array([False, False, False, True]))
    a = get_method("gtsam")(problem, SolveOptions())
    b = get_method("g2o")(problem, SolveOptions(max_iterations=20))
    # GTSAM's Pose2 error is the SE(2) logarithm, g2o's the plain (x, y, theta) difference: with a
    # residual left, their optima differ at second order (here a few micrometres)
    np.testing.assert_allclose(a.poses, b.poses, atol=1e-5)
    assert np.abs(a.poses - gt).max() > 0.01
    np.testing.assert_array_equal(a.poses[0], gt[0])  # the anchor does not move
    assert graph_chi2(problem, a.poses) < graph_chi2(problem, gt)
    # the disagreement is shared by all four edges, not left on the closure
    e = edge_errors(a.poses[fr], a.poses[to], z)
    assert np.all(np.abs(e[:, 2]) > 0.005)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_gnc_rejects_planted_outliers(kind):
    problem, gt, planted = make_problem(kind, n=80, closures=40, outliers=5, seed=3)
    sol = get_method("gnc")(problem, SolveOptions())
    assert sol.rejected is not None
    assert np.array_equal(sol.rejected, planted)
    assert _pose_distance(kind, sol.poses, gt) < 1e-6
    # plain least squares is pulled away by the same outliers
    assert _pose_distance(kind, get_method("gtsam")(problem, SolveOptions()).poses, gt) > 0.05


@pytest.mark.parametrize("method, module", [("gtsam", "gtsam"), ("gnc", "gtsam"), ("g2o", "g2opy")])
def test_a_missing_library_names_the_extra_to_install(method, module, monkeypatch):
    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == module or name.startswith(module + "."):
            raise ImportError(f"No module named {module!r}")
        return real(name, *args, **kwargs)

    monkeypatch.delitem(sys.modules, module, raising=False)
    monkeypatch.setattr(builtins, "__import__", fake)
    problem, _, _ = make_problem(PoseKind.SE2, n=10, closures=2)
    with pytest.raises(ConfigError, match=r"pip install 'cslam-studio\[solve\]'"):
        get_method(method)(problem, SolveOptions())


def test_unknown_method_lists_the_known_ones():
    with pytest.raises(ConfigError, match="unknown method 'ceres' .known: gtsam, g2o, gnc, command"):
        get_method("ceres")
    assert set(METHODS) == {"gtsam", "g2o", "gnc", "command", "dgs", "sesync"}


def test_command_method_runs_an_external_program_and_maps_ids_back(tmp_path):
    problem, gt, _ = make_problem(PoseKind.SE2, n=20, closures=5)
    script = tmp_path / "truth.py"
    # an "external solver" that writes the ground truth, in its own id order (reversed)
    lines = "".join(
        f"VERTEX_SE2 {k} {float(gt[k, 0])!r} {float(gt[k, 1])!r} {float(gt[k, 2])!r}\n" for k in reversed(range(20))
    )
    script.write_text(f"import sys\nopen(sys.argv[2], 'w').write({lines!r})\n")
    cmd = f"{sys.executable} {script} {{input}} {{output}}"
    sol = get_method("command")(problem, SolveOptions(own=CommandOptions(cmd)))
    np.testing.assert_array_equal(sol.poses, gt)
    with pytest.raises(ConfigError, match="must contain {input} and {output}"):
        get_method("command")(problem, SolveOptions(own=CommandOptions("true")))
    with pytest.raises(ConfigError, match="exited with status 3"):
        exit3 = f"{sys.executable} -c 'import sys; sys.exit(3)' {{input}} {{output}}"
        get_method("command")(problem, SolveOptions(own=CommandOptions(exit3)))
    with pytest.raises(ConfigError, match="needs the program to run"):  # its class's default: none
        get_method("command")(problem, SolveOptions())
    with pytest.raises(ConfigError, match="options: expected CommandOptions, got DgsOptions"):
        get_method("command")(problem, SolveOptions(own=DgsOptions()))


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_residuals_match_g2o_itself(kind, tmp_path):
    """chi2 of our numpy residuals (g2o convention) equals g2o's own activeChi2 on the same graph."""
    g2o = pytest.importorskip("g2opy")
    from studio.io.g2o import G2oDocument, write_g2o

    problem, gt, _ = make_problem(kind, n=40, closures=15, outliers=3, seed=5)
    rng = np.random.default_rng(2)
    d = 3 if kind is PoseKind.SE2 else 6
    rows, cols = np.triu_indices(d)
    info = np.where(
        rows == cols,
        rng.uniform(1, 50, (problem.num_edges, len(rows))),
        rng.uniform(-0.5, 0.5, (problem.num_edges, len(rows))),
    )
    path = tmp_path / "p.g2o"
    write_g2o(
        path,
        G2oDocument(
            kind,
            np.arange(problem.num_vertices),
            problem.initial,
            problem.edge_from,
            problem.edge_to,
            problem.measurements,
            info,
        ),
    )
    opt = g2o.SparseOptimizer()
    opt.set_algorithm(g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverX(g2o.LinearSolverEigenX())))
    assert opt.load(str(path))
    opt.initialize_optimization()
    opt.compute_active_errors()
    e = edge_errors(problem.initial[problem.edge_from], problem.initial[problem.edge_to], problem.measurements)
    ours = float(chi2_terms(e, info).sum())
    assert ours == pytest.approx(opt.active_chi2(), rel=1e-9)


def test_the_gtsam_method_keeps_its_lowest_chi2_iterate_over_a_higher_last_one():
    # GTSAM minimizes the logarithm's error, chi2 is g2o's: on SE-Sync's MIT.g2o GTSAM's optimum
    # scores 108.52 from a start of 79.18, and the answer must not be the worse one
    from studio.solvers.gtsam_method import _Lowest

    start = np.zeros((2, 3))
    lowest = _Lowest(79.18, start, 0)
    lowest.visit(95.0, np.ones((2, 3)), 1)
    lowest.visit(float("nan"), np.ones((2, 3)), 2)
    assert lowest.keep_if_lower(108.52) == {"iteration": 0, "chi2": 79.18, "chi2_last": 108.52}
    assert lowest.poses is start
    lowest.visit(41.0, np.full((2, 3), 2.0), 3)
    assert lowest.keep_if_lower(41.0) is None
