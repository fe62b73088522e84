"""A plug-in package for cslam-studio: one replay back-end and one solve method, both dead reckoning.

``pip install examples/studio-plugin-example``, then ``studio plugins`` lists them and
``studio replay DATASET -b example-odometry,centralized -o OUT`` or
``studio solve DATASET --method example-odometry -o OUT`` runs them. The method's own option is
set by name from Python: ``studio.solve.solve(DATASET, OUT, method="example-odometry", label="x")``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from studio.core.comms import robot_pairs
from studio.replay.protocol import Checkpoint, Setup, Step
from studio.solvers import SolveMethod
from studio.solvers.problem import Problem, Solution, SolveOptions


class OdometryBackend:
    """Each robot believes its own dead reckoning (the dataset's initial guess) and talks to no one."""

    def __init__(self, setup: Setup) -> None:
        self.own = setup.problem.initial.copy()
        self.silent = np.zeros(len(robot_pairs(setup.num_robots)), dtype=np.int64)

    def advance(self, news: Checkpoint) -> Step:
        return Step(self.own.copy(), 0.0, self.silent, self.silent)

    def finish(self) -> Step:
        return Step(self.own.copy(), 0.0, self.silent, self.silent)


@dataclass(frozen=True)
class OdometryOptions:
    """The method's own options: the fields of the class its registry entry names."""

    label: str = field(default="", metadata={"help": "a note copied into solve.json's notes."})


def solve_odometry(problem: Problem, options: SolveOptions, on_iteration: object = None) -> Solution:
    """The initial guess as the estimate: the baseline every optimizer should beat."""
    label = options.own_options(OdometryOptions).label
    return Solution(problem.initial.copy(), 0, notes={"plug-in": "studio-plugin-example", "label": label})


METHOD = SolveMethod(
    "example-odometry", solve_odometry, "dead reckoning, from a plug-in", (), method_options=OdometryOptions
)
