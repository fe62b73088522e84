"""The incremental solver of ``studio replay``: edges with one end held at a given pose (a
neighbour's pose another robot shared) enter as unary factors that are exactly the edge's factor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.core.model import PoseKind
from studio.solvers import get_method
from studio.solvers.incremental import FixedEnds, IncrementalSolver, IsamSettings
from studio.solvers.problem import SolveOptions
from tests.solvers.test_dgs import team_problem

pytest.importorskip("gtsam")


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_edges_to_held_poses_at_the_optimum_leave_the_others_at_it(kind):
    problem, _ = team_problem(kind)
    robot = problem.agent_of_vertex
    assert robot is not None
    batch = get_method("gtsam")(problem, SolveOptions())
    held = robot == 1  # closures 0 -> 1 and 1 -> 2: held at either end
    mine = np.flatnonzero(~held)
    inside = ~held[problem.edge_from] & ~held[problem.edge_to]
    across = np.flatnonzero(held[problem.edge_from] != held[problem.edge_to])
    held_is_from = held[problem.edge_from[across]]
    held_vertex = np.where(held_is_from, problem.edge_from[across], problem.edge_to[across])
    assert held_is_from.any() and not held_is_from.all()  # both directions of the adjoint rule
    solver = IncrementalSolver(problem, robot, IsamSettings())
    fixed = FixedEnds(across, batch.poses[held_vertex], held_is_from)
    solver.add(mine, np.flatnonzero(inside), anchor_pose=batch.poses[mine[0]], fixed=fixed)
    solver.refine(5)
    solver.polish(50)
    width = 2 if kind is PoseKind.SE2 else 3
    np.testing.assert_allclose(solver.estimate[mine, 0:width], batch.poses[mine, 0:width], atol=1e-4)


def test_updates_order_the_reeliminated_part_freely(tmp_path):
    """GTSAM's default update pins a batch's new variables at the root of the Bayes tree; with every
    robot's newest poses in each batch and closures reaching back, that root and the separators
    under it grow. The solver's updates order by plain COLAMD: a smaller tree, the same estimate
    (on the paper presets the peak memory falls by a third to three quarters)."""
    import json

    import gtsam

    from studio.solve import load_problem
    from studio.synth import load_synth_config, synthesize

    config = json.loads((Path(__file__).parents[1] / "data" / "configs" / "small3x100.json").read_text())
    config["number_of_steps"] = 300
    (tmp_path / "walk.json").write_text(json.dumps(config))
    synthesize(load_synth_config(tmp_path / "walk.json"), tmp_path / "out", rrd=False)
    loaded = load_problem(tmp_path / "out" / "walk")
    problem = loaded.problem
    offsets = np.asarray(loaded.offsets)
    robot = np.searchsorted(offsets, np.arange(problem.num_vertices), side="right") - 1
    step_of_vertex = np.arange(problem.num_vertices) - offsets[robot]
    solver = IncrementalSolver(problem, robot, IsamSettings())
    pinned = IncrementalSolver(problem, robot, IsamSettings())
    pinned._unconstrained = gtsam.ISAM2UpdateParams  # type: ignore[method-assign]  # GTSAM's default
    for each in (solver, pinned):
        for step in range(25, 301, 25):  # checkpoints every 25 steps
            known = step_of_vertex < step
            edges = known[problem.edge_from] & known[problem.edge_to] & ~each.edges
            each.add(np.flatnonzero(known & ~each.vertices), np.flatnonzero(edges))
    assert solver.isam.treeNnz() < 0.95 * pinned.isam.treeNnz()
    np.testing.assert_allclose(solver.solve(), pinned.solve(), atol=1e-6)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_solvers_share_the_edges_terms_one_noise_model_per_information(kind):
    """The edges' GTSAM terms are made once per problem: a noise model per distinct information
    (here two: the closures' information doubled), each measurement as a pose; solvers sharing them
    reach the same estimate, bit for bit, as one making its own."""
    import dataclasses

    import gtsam

    from studio.solvers.incremental import EdgeTerms, gtsam_information

    problem, _ = team_problem(kind)
    robot = problem.agent_of_vertex
    assert robot is not None
    information = problem.information_upper.copy()
    closures = problem.edge_to - problem.edge_from != 1
    information[closures] *= 2.0
    problem = dataclasses.replace(problem, information_upper=information)
    terms = EdgeTerms(problem)
    models = {id(m) for m in terms.noise}
    assert len(models) == 2
    omega = gtsam_information(problem)
    for e in (0, int(np.flatnonzero(closures)[0])):
        np.testing.assert_allclose(terms.noise[e].information(), omega[e], rtol=1e-12)
    z = terms.measurements[3]
    if kind is PoseKind.SE2:
        np.testing.assert_array_equal([z.x(), z.y(), z.theta()], problem.measurements[3])
    else:
        assert isinstance(z, gtsam.Pose3)
        np.testing.assert_array_equal(z.translation(), problem.measurements[3, 0:3])
    estimates = []
    for shared in (None, terms):
        solver = IncrementalSolver(problem, robot, IsamSettings(), terms=shared)
        solver.add(np.arange(problem.num_vertices), np.arange(problem.num_edges))
        estimates.append(solver.solve())
    np.testing.assert_array_equal(estimates[0], estimates[1])
