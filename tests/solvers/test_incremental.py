"""The incremental solver of ``studio replay``: edges with one end held at a given pose (a
neighbour's pose another robot shared) enter as unary factors that are exactly the edge's factor."""

from __future__ import annotations

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
