"""The ``dgs`` method (Distributed Gauss-Seidel): the batch optimum of GTSAM where the rounds can get
there, the rounds and bytes it reports, bad options, and ``studio solve --method dgs``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.core.errors import ConfigError, GraphError
from studio.core.geometry import quat_from_rotvec, quat_mul
from studio.core.model import PoseKind
from studio.solvers import get_method
from studio.solvers.dgs import BYTES_PER_NUMBER, contiguous_robots, dgs_rounds
from studio.solvers.problem import Problem, SolveOptions, graph_chi2
from tests.conftest import DATA
from tests.solvers.test_solvers import _relative

ROBOTS = 3


def team_problem(kind: PoseKind, *, per_robot: int = 40, inter: int = 6, seed: int = 5, noise: float = 0.01):
    """Three robots walking side by side, each with its own odometry and intra-robot closures, tied
    by a few inter-robot closures (the paper's regime); noisy measurements, drifted start values
    (rotations too). Returns the problem (robot identity set) and the ground truth."""
    rng = np.random.default_rng(seed)
    gt = []
    for r in range(ROBOTS):
        yaw = 0.3 * np.sin(np.arange(per_robot) / 6.0) + 0.1 * r
        xy = np.cumsum(np.column_stack([np.cos(yaw), np.sin(yaw)]), axis=0) + [0.0, 3.0 * r]
        if kind is PoseKind.SE2:
            gt.append(np.column_stack([xy, yaw]))
        else:
            z = 0.2 * np.sin(np.arange(per_robot) / 5.0 + r)
            q = quat_from_rotvec(np.column_stack([0.05 * np.cos(yaw), 0.05 * np.sin(yaw), yaw]))
            gt.append(np.column_stack([xy, z, q]))
    truth = np.concatenate(gt)
    robot = np.repeat(np.arange(ROBOTS), per_robot)
    fr, to = [], []
    for r in range(ROBOTS):
        base = r * per_robot
        fr += list(range(base, base + per_robot - 1))
        to += list(range(base + 1, base + per_robot))
        for _ in range(4):
            i = int(rng.integers(0, per_robot - 10))
            fr.append(base + i)
            to.append(base + i + int(rng.integers(5, 10)))
    for _ in range(inter):
        a, b = sorted(rng.choice(ROBOTS, 2, replace=False).tolist())
        k = int(rng.integers(0, per_robot))
        fr.append(a * per_robot + k)
        to.append(b * per_robot + min(per_robot - 1, k + int(rng.integers(-2, 3))))
    fr_a, to_a = np.array(fr), np.array(to)
    z = _relative(kind, truth[fr_a], truth[to_a])
    d = 3 if kind is PoseKind.SE2 else 6
    if kind is PoseKind.SE2:
        z = z + rng.normal(0, noise, z.shape)
    else:
        z[:, 0:3] += rng.normal(0, noise, (len(z), 3))
        z[:, 3:7] = quat_mul(z[:, 3:7], quat_from_rotvec(rng.normal(0, noise, (len(z), 3))))
    rows, cols = np.triu_indices(d)
    info = np.tile(np.where(rows == cols, 1.0 / noise**2, 0.0), (len(fr_a), 1))
    start = truth.copy()
    ramp = np.tile(np.linspace(0, 1, per_robot), ROBOTS)
    if kind is PoseKind.SE2:
        start[:, 2] += 0.4 * ramp
        start[:, 0:2] += 2.0 * ramp[:, None]
    else:
        start[:, 0:3] += 2.0 * ramp[:, None]
        start[:, 3:7] = quat_mul(quat_from_rotvec(np.column_stack([0.1 * ramp, 0 * ramp, 0.4 * ramp])), start[:, 3:7])
    start[0] = truth[0]
    robust = np.arange(len(fr_a)) >= 0
    problem = Problem(kind, start, fr_a, to_a, z, info, robust, agent_of_vertex=robot)
    return problem, truth


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_dgs_reaches_gtsams_batch_optimum_on_a_small_team(kind):
    problem, _ = team_problem(kind)
    batch = get_method("gtsam")(problem, SolveOptions())
    assert problem.agent_of_vertex is not None
    res = dgs_rounds(problem, problem.agent_of_vertex, max_rounds=1500, rotation_tol=1e-6, pose_tol=1e-7)
    assert res.converged
    best = graph_chi2(problem, batch.poses)
    assert graph_chi2(problem, problem.initial) > 100 * best
    assert graph_chi2(problem, res.poses) == pytest.approx(best, rel=1e-6)
    width = 2 if kind is PoseKind.SE2 else 3
    np.testing.assert_allclose(res.poses[:, 0:width], batch.poses[:, 0:width], atol=1e-4)
    np.testing.assert_array_equal(res.poses[problem.anchor], problem.initial[problem.anchor])
    assert res.rotation_rounds >= 2 and res.pose_rounds >= 2 and res.linearizations >= 2
    # the pose stage's chi2 settles on the optimum
    assert res.chi2_history[-1] == pytest.approx(best, rel=1e-6)


def test_the_solve_method_reports_rounds_and_bytes_and_calls_back_per_round():
    problem, _ = team_problem(PoseKind.SE2)
    seen = []
    sol = get_method("dgs")(problem, SolveOptions(max_iterations=60), lambda k, poses: seen.append(k))
    notes = sol.notes
    assert sol.iterations == notes["rounds"] == notes["rotation_rounds"] + notes["pose_rounds"] <= 60
    assert seen == list(range(notes["pose_rounds"] + 1))  # iteration i: the i-th pose-stage round
    assert len(sol.chi2_history) == notes["pose_rounds"] + 1
    assert sol.chi2_history[0] == graph_chi2(problem, problem.initial)
    assert sol.chi2_history[1:] == tuple(c for c in notes["round_chi2"] if c is not None)
    assert notes["bytes_total"] == sum(notes["bytes_per_robot"]) == sum(notes["round_bytes"])
    assert sum(notes["bytes_per_link"].values()) == notes["bytes_total"]
    assert set(notes["bytes_per_link"]) <= {f"{a}->{b}" for a in range(3) for b in range(3) if a != b}


def _two_robot_chain():
    """Two robots of three poses in a line, one inter-robot edge 2 -> 3: one separator each."""
    kind = PoseKind.SE2
    truth = np.array([[k, 0.0, 0.0] for k in range(6)])
    fr, to = np.array([0, 1, 2, 3, 4]), np.array([1, 2, 3, 4, 5])
    z = _relative(kind, truth[fr], truth[to])
    info = np.tile([100.0, 0, 0, 100.0, 0, 100.0], (5, 1))
    start = truth.copy()
    start[1:, 2] += 0.1
    return Problem(kind, start, fr, to, z, info, np.zeros(5, dtype=bool)), truth


def test_bytes_are_the_separators_times_the_numbers_sent():
    problem, truth = _two_robot_chain()
    robot = np.array([0, 0, 0, 1, 1, 1])
    res = dgs_rounds(problem, robot, max_rounds=200, rotation_tol=1e-8, pose_tol=1e-8, pose_gamma=1.0, coarse_size=0)
    assert res.converged
    np.testing.assert_allclose(res.poses, truth, atol=1e-7)
    # per round one separator each way: 4 numbers (a 2x2 rotation) in the rotation stage, 3 in the
    # pose stage, and one pose (3 numbers) when the pose stage starts
    per_direction = BYTES_PER_NUMBER * (4 * res.rotation_rounds + 3 * res.pose_rounds + 3)
    np.testing.assert_array_equal(res.bytes_per_link, [[0, per_direction], [per_direction, 0]])
    np.testing.assert_array_equal(res.bytes_per_robot, [per_direction, per_direction])
    assert res.links() == {"0->1": per_direction, "1->0": per_direction}
    assert sum(r.bytes_sent for r in res.rounds) == 2 * per_direction


def test_the_coarse_correction_is_counted_on_the_coordinators_links():
    """Two-level rounds: besides the separators, each robot sends robot 0 (the coordinator) its
    coarse unknowns' residuals and gets their corrections back, and sends its rows of the coarse
    matrix once per linear system. Each robot here is one aggregate of 3 poses: robot 1 has 2
    coarse unknowns in the rotation stage (a 2x2 rotation's entries, 2 columns each) and 3 in the
    pose stage (a rigid move in the plane)."""
    problem, truth = _two_robot_chain()
    robot = np.array([0, 0, 0, 1, 1, 1])
    kw = dict(max_rounds=200, rotation_tol=1e-8, pose_tol=1e-8, pose_gamma=1.0)
    res = dgs_rounds(problem, robot, coarse_size=3, **kw)  # type: ignore[arg-type]
    assert res.converged
    np.testing.assert_allclose(res.poses, truth, atol=1e-7)
    plain = BYTES_PER_NUMBER * (4 * res.rotation_rounds + 3 * res.pose_rounds + 3)
    down = BYTES_PER_NUMBER * (2 * 2 * res.rotation_rounds + 3 * 1 * res.pose_rounds)
    assert res.bytes_per_link[0, 1] == plain + down
    assert res.bytes_per_link[1, 0] > plain + down  # its residuals and its rows of the coarse matrix
    assert sum(r.bytes_sent for r in res.rounds) == res.bytes_per_link.sum()


def test_two_level_rounds_reach_the_batch_optimum_where_plain_dgs_does_not(tmp_path):
    """On kollagen's tiny_three (3 robots of 241 poses walking one grid, strongly coupled) plain DGS
    is still 40 % above the optimum after 40 rounds; with the coarse correction (runs of 5 poses
    moved rigidly, solved jointly every round) the rounds reach GTSAM's batch chi2."""
    from studio.solve import load_problem
    from studio.synth import load_synth_config, synthesize

    synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), tmp_path, rrd=False)
    loaded = load_problem(tmp_path / "tiny_three")
    problem = loaded.problem
    robot = np.repeat(np.arange(len(loaded.offsets) - 1), np.diff(loaded.offsets))
    batch = get_method("gtsam")(problem, SolveOptions())
    optimum = graph_chi2(problem, batch.poses)
    two_level = dgs_rounds(problem, robot, max_rounds=40)
    plain = dgs_rounds(problem, robot, max_rounds=40, coarse_size=0, pose_gamma=1.9)
    assert graph_chi2(problem, two_level.poses) == pytest.approx(optimum, rel=1e-3)
    assert graph_chi2(problem, plain.poses) > 1.3 * optimum
    assert two_level.linearizations > plain.linearizations


def test_jacobi_rounds_reach_the_same_optimum_as_gauss_seidel():
    problem, truth = _two_robot_chain()
    robot = np.array([0, 0, 0, 1, 1, 1])
    kw = dict(max_rounds=400, rotation_tol=1e-9, pose_tol=1e-9, pose_gamma=1.0)
    gs = dgs_rounds(problem, robot, **kw)  # type: ignore[arg-type]
    jac = dgs_rounds(problem, robot, schedule="jacobi", **kw)  # type: ignore[arg-type]
    assert gs.converged and jac.converged
    np.testing.assert_allclose(jac.poses, truth, atol=1e-7)
    assert jac.num_rounds > gs.num_rounds


def test_one_robot_is_the_centralized_two_stage_solve_on_a_kollagen_dataset(tmp_path):
    from studio.solve import load_problem
    from studio.synth import load_synth_config, synthesize

    synthesize(load_synth_config(DATA / "configs" / "tiny_single.json"), tmp_path, rrd=False)
    loaded = load_problem(tmp_path / "tiny_single")
    problem = loaded.problem
    assert problem.agent_of_vertex is not None and set(problem.agent_of_vertex.tolist()) == {0}
    batch = get_method("gtsam")(problem, SolveOptions())
    sol = get_method("dgs")(problem, SolveOptions())
    assert sol.notes["bytes_total"] == 0
    # the default tolerances stop the Gauss-Newton steps once no update exceeds 1 cm
    assert graph_chi2(problem, sol.poses) == pytest.approx(graph_chi2(problem, batch.poses), rel=1e-6)


def test_contiguous_split_and_bad_options():
    np.testing.assert_array_equal(contiguous_robots(7, 3), [0, 0, 0, 1, 1, 2, 2])
    with pytest.raises(ConfigError, match="robots: expected an integer in 1..7"):
        contiguous_robots(7, 8)
    problem, _ = team_problem(PoseKind.SE2, per_robot=12, inter=3)
    robot = problem.agent_of_vertex
    assert robot is not None
    with pytest.raises(ConfigError, match="agent_of_vertex: expected 36 integers"):
        dgs_rounds(problem, robot[:-1])
    with pytest.raises(ConfigError, match="pose_gamma: over-relaxation expects a number in"):
        dgs_rounds(problem, robot, pose_gamma=2.0)
    with pytest.raises(ConfigError, match="schedule: expected gauss-seidel or jacobi"):
        dgs_rounds(problem, robot, schedule="random")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="max_rounds: expected an integer of at least 2"):
        dgs_rounds(problem, robot, max_rounds=1)
    keep = problem.edge_to < 30  # vertices 30..35 lose their edges
    cut = Problem(
        problem.kind,
        problem.initial,
        problem.edge_from[keep],
        problem.edge_to[keep],
        problem.measurements[keep],
        problem.information_upper[keep],
        problem.robust[keep],
        agent_of_vertex=robot,
    )
    with pytest.raises(GraphError, match="falls apart into 7 pieces"):
        dgs_rounds(cut, robot)


def test_ape_translation_is_scores_figure(tmp_path):
    from studio.core.trajectory import Trajectory
    from studio.evaluate import ape_translation, score
    from studio.io.multig2o import read_multi_g2o
    from studio.synth import load_synth_config, synthesize

    synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), tmp_path, rrd=False)
    graph = read_multi_g2o(tmp_path / "tiny_three")
    g3 = graph.to_se3()
    gt = [a.ground_truth for a in g3.agents]
    est = [a.initial for a in g3.agents]
    for align in ("none", "first-pose", "se3"):
        full = score(graph, [Trajectory.from_poses(a.name, a.stamps_ns, a.initial) for a in g3.agents], align=align)
        light = ape_translation(graph, gt, est, align=align)  # type: ignore[arg-type]
        assert light.mean == pytest.approx(full.overall.ape_translation_m.mean, rel=1e-12)
        assert light.rmse == pytest.approx(full.overall.ape_translation_m.rmse, rel=1e-12)
        assert light.count == full.overall.poses


def test_studio_solve_method_dgs_reports_rounds_ape_and_bytes(tmp_path):
    from studio.synth import load_synth_config, synthesize

    synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), tmp_path, rrd=False)
    out = tmp_path / "solved"
    result = CliRunner().invoke(
        app, ["solve", str(tmp_path / "tiny_three"), "-o", str(out), "--method", "dgs", "--iterations", "40"]
    )
    assert result.exit_code == 0, result.output
    doc = json.loads((out / "solve.json").read_text())
    notes = doc["notes"]
    rounds = notes["rounds"]
    assert f"dgs: 3 robots, {rounds} rounds" in result.output and rounds <= 40
    assert "round  APE first-pose mean [m]  APE se3 mean [m]" in result.output
    assert doc["method"] == "dgs" and doc["iterations"] == rounds and notes["coarse_size"] == 5
    curve = doc["ape_per_round"]
    assert curve["round"] == [0, *range(notes["rotation_rounds"] + 1, rounds + 1)]
    assert len(curve["se3_mean_m"]) == len(curve["first_pose_mean_m"]) == len(curve["round"])
    assert notes["bytes_total"] > 0 and len(notes["bytes_per_robot"]) == 3
    # the last round's APE is the estimate's, as studio evaluate scores it
    from studio.evaluate import evaluate

    ev = evaluate(tmp_path / "tiny_three", estimate=out / "estimate", align="se3")
    assert curve["se3_mean_m"][-1] == pytest.approx(ev.overall.ape_translation_m.mean, rel=1e-6)
    # the rounds do better than dead reckoning
    assert curve["se3_mean_m"][-1] < 0.5 * curve["se3_mean_m"][0]


def test_robots_option_splits_a_single_g2o(tmp_path):
    from studio.synth import load_synth_config, synthesize

    synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), tmp_path, rrd=False)
    single = tmp_path / "tiny_three_singleg2o" / "tiny_three.g2o"
    out = tmp_path / "solved"
    result = CliRunner().invoke(
        app, ["solve", str(single), "-o", str(out), "--method", "dgs", "--robots", "3", "--iterations", "10"]
    )
    assert result.exit_code == 0, result.output
    doc = json.loads((out / "solve.json").read_text())
    assert doc["notes"]["robots"] == 3 and "ape_per_round" not in doc
    bad = CliRunner().invoke(
        app, ["solve", str(single), "-o", str(tmp_path / "x"), "--method", "dgs", "--robots", "-1"]
    )
    assert bad.exit_code == 2
    assert "--robots: expected 0 (the default) or a count" in bad.output
    assert not (tmp_path / "x").exists()


def test_rotation_momentum_shortens_the_rotation_stage_and_reaches_the_same_optimum():
    problem, _ = team_problem(PoseKind.SE2, per_robot=60, inter=10, seed=7)
    robot = problem.agent_of_vertex
    assert robot is not None
    kw = dict(max_rounds=2000, rotation_tol=1e-6, pose_tol=1e-7)
    plain = dgs_rounds(problem, robot, rotation_momentum=0.0, **kw)  # type: ignore[arg-type]
    fast = dgs_rounds(problem, robot, **kw)  # type: ignore[arg-type]  # momentum 0.9 by default
    assert plain.converged and fast.converged
    assert fast.rotation_rounds < plain.rotation_rounds
    assert graph_chi2(problem, fast.poses) == pytest.approx(graph_chi2(problem, plain.poses), rel=1e-6)
    with pytest.raises(ConfigError, match=r"rotation_momentum: expected a number in \[0, 1\)"):
        dgs_rounds(problem, robot, rotation_momentum=1.0)
    with pytest.raises(ConfigError, match=r"pose_momentum: expected a number in \[0, 1\)"):
        dgs_rounds(problem, robot, pose_momentum=-0.1)


def test_without_the_rotation_stage_rounds_start_at_the_given_poses():
    problem, _ = team_problem(PoseKind.SE2)
    robot = problem.agent_of_vertex
    assert robot is not None
    batch = get_method("gtsam")(problem, SolveOptions())
    res = dgs_rounds(problem, robot, initial=batch.poses, rotation_stage=False, max_rounds=5)
    assert res.rotation_rounds == 0 and res.pose_rounds >= 1
    assert res.chi2_initial == pytest.approx(graph_chi2(problem, batch.poses), rel=1e-12)
    assert graph_chi2(problem, res.poses) == pytest.approx(graph_chi2(problem, batch.poses), rel=1e-4)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_fixed_vertices_held_at_the_optimum_leave_the_others_at_it(kind):
    """A replay's neighbour poses: robot 2 held where the batch optimum puts it, robots 0 and 1
    start drifted and end at the joint optimum; the held vertices do not move and send nothing."""
    problem, _ = team_problem(kind)
    robot = problem.agent_of_vertex
    assert robot is not None
    batch = get_method("gtsam")(problem, SolveOptions())
    start = problem.initial.copy()
    held = robot == 2
    start[held] = batch.poses[held]
    start[problem.anchor] = batch.poses[problem.anchor]
    res = dgs_rounds(
        problem, robot, initial=start, fixed=held, warm_start=True, max_rounds=1500, rotation_tol=1e-6, pose_tol=1e-7
    )
    np.testing.assert_allclose(res.poses[held], start[held], atol=1e-12)  # rounding of the retraction
    width = 2 if kind is PoseKind.SE2 else 3
    np.testing.assert_allclose(res.poses[:, 0:width], batch.poses[:, 0:width], atol=1e-4)
    assert res.bytes_per_link[2].sum() > 0  # robot 2 is still a neighbour: it sends its separators
    with pytest.raises(ConfigError, match="fixed: expected a mask of 120 vertices"):
        dgs_rounds(problem, robot, fixed=held[:5])


@pytest.mark.parametrize("seed", range(6))
def test_the_layout_of_any_edges_is_a_sorted_pattern_holding_their_dense_sum(seed):
    """Random edges (repeated pairs, both directions, self-loops, vertices no edge touches): the
    layout's pattern has each row's columns sorted and distinct, and its data is the dense sum of
    the edges' products."""
    import scipy.sparse as sp

    from studio.solvers import dgs

    rng = np.random.default_rng(seed)
    n, m, b = int(rng.integers(2, 12)), int(rng.integers(1, 30)), int(rng.integers(1, 4))
    fr, to = rng.integers(0, n, m), rng.integers(0, n, m)
    layout = dgs._layout(fr, to, n, b)
    jacobians = rng.standard_normal((m, b, 2 * b))
    omega = np.broadcast_to(np.eye(b), (m, b, b))
    dense = np.zeros((n * b, n * b))
    for k, (i, j) in enumerate(zip(fr, to)):
        cols = np.concatenate([np.arange(i * b, i * b + b), np.arange(j * b, j * b + b)])
        np.add.at(dense, np.ix_(cols, cols), jacobians[k].T @ jacobians[k])
    whole = sp.csr_matrix(
        (layout.data(dgs._products(jacobians, omega)), layout.indices, layout.indptr), shape=dense.shape
    )
    for row in range(n * b):
        columns = layout.indices[layout.indptr[row] : layout.indptr[row + 1]]
        assert np.all(np.diff(columns) > 0)
    np.testing.assert_allclose(whole.toarray(), dense, rtol=1e-12, atol=1e-12)
    touched = np.isin(np.arange(n), np.concatenate([fr, to]))
    assert np.array_equal(np.diff(layout.indptr) > 0, np.repeat(touched, b))


@pytest.mark.parametrize("b", [2, 3, 6])
def test_the_layout_adds_every_edges_products_where_a_dense_sum_puts_them(b):
    """The matrix a stage's layout fills in (edges in any order, two between the same pair, both
    directions) is ``sum_e J_e^T Omega_e J_e``; each robot's pieces are its block's upper triangle
    and its coupling to everyone else, and factoring a second system in place of the first solves
    the second."""
    import scipy.sparse as sp

    from studio.solvers import dgs

    rng = np.random.default_rng(7)
    n, r = 7, b + 1
    fr = np.array([0, 1, 2, 3, 4, 5, 1, 2, 6])
    to = np.array([1, 2, 3, 4, 5, 6, 0, 3, 2])  # 1-0 reverses 0-1; 2-3 twice; 6-2 closes a loop
    layout = dgs._layout(fr, to, n, b)
    robot_dofs = [np.arange(b, 3 * b), np.arange(3 * b, n * b)]  # vertex 0 is the anchor
    pieces = dgs._pieces(layout, robot_dofs)
    for _ in range(2):
        jacobians = rng.standard_normal((len(fr), r, 2 * b))
        omega = np.array([a @ a.T + np.eye(r) for a in rng.standard_normal((len(fr), r, r))])
        dense = np.zeros((n * b, n * b))
        for k, (i, j) in enumerate(zip(fr, to)):
            cols = np.concatenate([np.arange(i * b, i * b + b), np.arange(j * b, j * b + b)])
            dense[np.ix_(cols, cols)] += jacobians[k].T @ omega[k] @ jacobians[k]
        data = layout.data(dgs._products(jacobians, omega))
        whole = sp.csr_matrix((data, layout.indices, layout.indptr), shape=(n * b, n * b))
        np.testing.assert_allclose(whole.toarray(), dense, rtol=1e-12, atol=1e-12)
        blocks = dgs._factorise(data, pieces)
        for dofs, other, take, coupling, lu in zip(
            robot_dofs, blocks.others, pieces.blocks, blocks.couplings, blocks.lus
        ):
            own = dense[np.ix_(dofs, dofs)]
            np.testing.assert_allclose(take.of(data).toarray(), np.triu(own), rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(coupling.toarray(), dense[np.ix_(dofs, other)], rtol=1e-12, atol=1e-12)
            rhs = rng.standard_normal(len(dofs))
            np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(own, rhs), rtol=1e-8)
    assert len(pieces.factors) == 2  # the second system's blocks were factored in place of the first's


@pytest.mark.parametrize("b", [3, 6])
def test_the_coarse_matrix_added_up_over_the_edges_is_p_transposed_h_p(b):
    """The coarse system the edges add up over the runs of two poses is ``P^T h P`` on the free
    unknowns (vertex 0 held: its edges reach only their free end's block), its factor solves it,
    and each robot's rows are counted on its structure: here every run meets every other, so each
    coarse row has three blocks."""
    from studio.solvers import dgs

    rng = np.random.default_rng(11)
    n, r = 7, b
    fr = np.array([0, 1, 2, 3, 4, 5, 1, 2, 6])
    to = np.array([1, 2, 3, 4, 5, 6, 0, 3, 2])
    layout = dgs._layout(fr, to, n, b)
    robot_dofs = [np.arange(b, 3 * b), np.arange(3 * b, n * b)]  # runs {1, 2}, {3, 4}, {5, 6}
    pieces = dgs._pieces(layout, robot_dofs)
    pieces.coarse = dgs._coarse_space(fr, to, n, pieces.dofs, b, b, 2, 0)
    assert pieces.coarse is not None
    assert len(pieces.coarse.pinned) == 0  # the anchor, vertex 0, is held: no gauge to take out
    jacobians = rng.standard_normal((len(fr), r, 2 * b))
    omega = np.array([a @ a.T + np.eye(r) for a in rng.standard_normal((len(fr), r, r))])
    data = layout.data(dgs._products(jacobians, omega))
    blocks = rng.standard_normal((len(pieces.coarse.vertex), b, b))
    coarse = dgs._coarse(pieces, data, jacobians, omega, blocks)
    dense = np.zeros((n * b, n * b))
    for k, (i, j) in enumerate(zip(fr, to)):
        cols = np.concatenate([np.arange(i * b, i * b + b), np.arange(j * b, j * b + b)])
        dense[np.ix_(cols, cols)] += jacobians[k].T @ omega[k] @ jacobians[k]
    free = np.concatenate(robot_dofs)
    p = np.zeros((len(free), 3 * b))
    for k, run in enumerate([0, 0, 1, 1, 2, 2]):  # the free vertices 1..6 in order, two per run
        p[k * b : k * b + b, run * b : run * b + b] = blocks[k]
    np.testing.assert_allclose(coarse.basis.toarray(), p, rtol=0, atol=0)
    hc = p.T @ dense[np.ix_(free, free)] @ p
    rhs = rng.standard_normal(3 * b)
    np.testing.assert_allclose(coarse.lu.solve(rhs), np.linalg.solve(hc, rhs), rtol=1e-8)
    np.testing.assert_array_equal(coarse.per_robot, [[b, b * 3 * b], [2 * b, 2 * b * 3 * b]])
    # with the anchor free (vertex 3, of the second run) that run is held still: zero columns of P,
    # a unit diagonal block, the rest P^T h P as before
    pieces.coarse = dgs._coarse_space(fr, to, n, pieces.dofs, b, b, 2, 3)
    assert pieces.coarse is not None
    np.testing.assert_array_equal(pieces.coarse.pinned, [2, 3])
    pinned = dgs._coarse(pieces, data, jacobians, omega, blocks)
    p[:, b : 2 * b] = 0.0
    np.testing.assert_allclose(pinned.basis.toarray(), p, rtol=0, atol=0)
    hc = p.T @ dense[np.ix_(free, free)] @ p
    hc[b : 2 * b, b : 2 * b] = np.eye(b)
    np.testing.assert_allclose(pinned.lu.solve(rhs), np.linalg.solve(hc, rhs), rtol=1e-8)
