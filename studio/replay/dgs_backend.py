"""The ``dgs`` back-end of ``studio replay``: Distributed Gauss-Seidel (:mod:`studio.solvers.dgs`)
run a few rounds at every checkpoint, warm-started from what the robots believed at the last one.

At a checkpoint the robots that were in contact since the last one (a group of the replay) and are
tied by the inter-agent closures they have been delivered form a *team*; a team runs
:data:`CHECKPOINT` (10) DGS rounds on what its members know (their odometry and intra-agent
closures so far, the delivered closures between members), each robot its own block. The team starts
from its members' beliefs, new poses continued from each robot's latest belief by the dataset's dead
reckoning, the pose stage keeping those translations (``warm_start``); the gauge is the lowest-id
member's first pose, held where that robot believes it. A robot alone is a team of one (its one
block solved exactly: Gauss-Newton on its own graph). Each member's delivered closures to robots
outside its team enter at the neighbours' poses it kept from earlier teams (:class:`Memory`), held
vertices in its block. After the last checkpoint every team runs
:data:`FINAL` (100) more rounds. A solve whose result has a higher chi2 than its start is not
taken (each robot can sum its own edges' chi2; the team needs the total, one number each). Messages
and bytes are DGS's own (each round every robot sends each neighbour its separator values), counted
on the pair.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from studio.replay.backends import Memory, _Base
from studio.replay.protocol import Checkpoint, Setup, Step
from studio.solvers.dgs import DEFAULT_POSE_TOL, dgs_rounds
from studio.solvers.incremental import compose, inverse
from studio.solvers.problem import Problem, graph_chi2

__all__ = ["Dgs", "Budget", "CHECKPOINT", "FINAL"]


@dataclass(frozen=True)
class Budget:
    """What a team runs at once: DGS rounds at most (both stages), the pose stage's tolerance [m,
    rad] and over-relaxation."""

    rounds: int
    pose_tol: float
    pose_gamma: float


#: At each checkpoint: 10 rounds, DGS's pose tolerance, no over-relaxation (1.6 diverges on
#: Multi3500x8 once the eight robots are one team: Gauss-Newton steps far from the optimum).
CHECKPOINT = Budget(10, DEFAULT_POSE_TOL, 1.0)
#: After the last checkpoint: 100 rounds to a tolerance of 1e-4, over-relaxed by 1.6 (on small3x100
#: under ``always`` it ends at the batch optimum, chi2 +0.02 %; 1.0 short of it, +0.3 %).
FINAL = Budget(100, 1e-4, 1.6)


def _teams(
    group: tuple[int, ...], edge_robots: tuple[np.ndarray, np.ndarray], edges: np.ndarray, num_robots: int
) -> list[tuple[int, ...]]:
    """``group`` split into the robots tied together by the known edges ``edges`` (a mask), each
    edge's ends' robots ``edge_robots``."""
    parent = {r: r for r in group}

    def find(r: int) -> int:
        while parent[r] != r:
            parent[r] = parent[parent[r]]
            r = parent[r]
        return r

    a, b = edge_robots[0][edges], edge_robots[1][edges]
    apart = a != b
    pairs = np.unique(a[apart] * num_robots + b[apart])
    for x, y in zip((pairs // num_robots).tolist(), (pairs % num_robots).tolist()):
        rx, ry = find(x), find(y)
        parent[max(rx, ry)] = min(rx, ry)
    teams: dict[int, list[int]] = {}
    for r in group:
        teams.setdefault(find(r), []).append(r)
    return sorted(tuple(t) for t in teams.values())


class Dgs(_Base):
    #: the information of a kept closure to a held neighbour pose: the closure's own times this
    NEIGHBOUR_INFORMATION_SCALE = 1.0

    def __init__(self, world: Setup) -> None:
        super().__init__(world)
        self.believed = np.zeros(world.problem.num_vertices, dtype=bool)
        self.last_groups: list[tuple[int, ...]] = []
        self.last_tick = 0
        self.teams: set[tuple[int, ...]] = set()
        """The teams of the last checkpoint: a team seen again skips the rotation stage."""
        self.memory = Memory(world)
        self.rounds = 0
        self.rejected = 0
        """Solves whose result was not taken (chi2 not below the start's)."""

    def _start(self, vertices: np.ndarray) -> np.ndarray:
        """Starting values of ``vertices`` (global ids, sorted): beliefs, new poses dead-reckoned."""
        w, kind = self.world, self.world.problem.kind
        out = self.own[vertices].copy()
        for r in np.unique(w.agent_of_vertex[vertices]).tolist():
            rows = np.flatnonzero((w.agent_of_vertex[vertices] == r) & ~self.believed[vertices])
            mine = np.flatnonzero(self.believed & (w.agent_of_vertex == r))
            if not len(rows) or not len(mine):
                continue
            last = int(mine[-1])
            base = compose(self.own[last : last + 1], inverse(w.problem.initial[last : last + 1], kind), kind)
            out[rows] = compose(np.repeat(base, len(rows), axis=0), w.problem.initial[vertices[rows]], kind)
        return out

    def _sub_problem(self, team: tuple[int, ...]) -> tuple[np.ndarray, Problem, np.ndarray, np.ndarray]:
        """What ``team`` solves: its known vertices (global ids), the problem over them plus one held
        vertex per kept closure to a non-member (its pose as the member keeps it, in the member's
        block), each vertex's robot in the team and the held mask."""
        w, p = self.world, self.world.problem
        vertices, edges = self._known(team)
        ids = np.flatnonzero(vertices)
        edge_ids = np.flatnonzero(edges)
        fixed = self.memory.fixed(team, self.NEIGHBOUR_INFORMATION_SCALE)
        n, k = len(ids), len(fixed.edges)
        local = np.full(p.num_vertices, -1, dtype=np.int64)
        local[ids] = np.arange(n)
        held = np.arange(n, n + k)
        fe = fixed.edges
        fr = np.concatenate([local[p.edge_from[edge_ids]], np.where(fixed.held_is_from, held, local[p.edge_from[fe]])])
        to = np.concatenate([local[p.edge_to[edge_ids]], np.where(fixed.held_is_from, local[p.edge_to[fe]], held)])
        member_vertex = np.where(fixed.held_is_from, p.edge_to[fe], p.edge_from[fe])
        agents = np.concatenate([w.agent_of_vertex[ids], w.agent_of_vertex[member_vertex]])
        robot_local = np.searchsorted(np.asarray(team), agents)
        all_edges = np.concatenate([edge_ids, fe])
        start = np.concatenate([self._start(ids), fixed.held_poses])
        information = p.information_upper[all_edges].copy()
        information[len(edge_ids) :] *= fixed.information_scale
        sub = Problem(
            p.kind,
            start,
            fr,
            to,
            p.measurements[all_edges],
            information,
            p.robust[all_edges],
            anchor=int(np.flatnonzero(robot_local == 0)[0]),
            agent_of_vertex=robot_local,
        )
        return ids, sub, robot_local, np.arange(n + k) >= n

    def _solve(self, team: tuple[int, ...], tick: int, budget: Budget) -> float:
        """DGS rounds of one team on what it knows and the neighbour poses its members keep; the
        seconds it took. A result whose chi2 is not below the start's (Gauss-Newton steps can
        diverge far from the optimum) is not taken."""
        ids, sub, robot_local, held = self._sub_problem(team)
        if not sub.num_edges:
            self.own[ids] = sub.initial[: len(ids)]
            self.believed[ids] = True
            return 0.0
        start = sub.initial
        rotation_stage = team not in self.teams
        t0 = time.perf_counter()
        result = dgs_rounds(
            sub,
            robot_local,
            initial=start,
            max_rounds=max(budget.rounds, 2),
            pose_gamma=budget.pose_gamma,
            pose_tol=budget.pose_tol,
            warm_start=True,
            rotation_stage=rotation_stage,
            fixed=held if held.any() else None,
            score_rounds=False,
        )
        # without the rotation stage the pose stage's first linearization point is the start
        before = graph_chi2(sub, start) if rotation_stage else result.chi2_initial
        better = bool(graph_chi2(sub, result.poses) < before)  # nan: not better
        seconds = time.perf_counter() - t0
        self.own[ids] = (result.poses if better else start)[: len(ids)]
        self.rejected += not better
        self.believed[ids] = True
        self.rounds += result.num_rounds
        for a, b in zip(*np.nonzero(result.bytes_per_link)):
            self._count(team[int(a)], team[int(b)], result.num_rounds, int(result.bytes_per_link[a, b]))
        # the separator values the rounds exchanged: already counted in DGS's bytes
        self.memory.learn(tick, team, self.own)
        return seconds

    def _advance(self, tick: int, groups: list[tuple[int, ...]], budget: Budget) -> Step:
        seconds = 0.0
        teams = set()
        for group in groups:
            _, edges = self._known(group)
            for team in _teams(group, self.edge_robots, edges, self.world.num_robots):
                seconds += self._solve(team, tick, budget)
                teams.add(team)
        self.teams = teams
        return self._answer(seconds, self.memory.kept())

    def advance(self, news: Checkpoint) -> Step:
        self._receive(news)
        self.memory.deliver(news.closures)
        self.last_tick, self.last_groups = news.tick, news.groups
        return self._advance(news.tick, news.groups, CHECKPOINT)

    def finish(self) -> Step:
        return self._advance(self.last_tick, self.last_groups, FINAL)
