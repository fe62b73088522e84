"""The studio's own back-ends of ``studio replay``: what each robot believes as measurements and
closures arrive.

Each implements the public protocol of :mod:`studio.replay.protocol` and nothing more: made from a
:class:`~studio.replay.protocol.Setup`, told each checkpoint's news (every ``every`` ticks and at the
end) and then the end, it keeps what the news said (the poses visited, the edges known to their
robots) and answers a :class:`~studio.replay.protocol.Step`: ``own`` (one row per vertex of the
problem: the estimate the vertex's own robot holds of it; rows of poses not yet visited are
unused), the poses of other robots kept, and what it sent on each link. The registry
:data:`studio.replay.registry.BACKENDS` is the one place a back-end is declared.

* ``centralized``: one ISAM2 (:class:`~studio.solvers.incremental.IncrementalSolver`) over
  everything anyone knows: every robot's odometry and intra-agent closures at their times and each
  inter-agent closure once the schedule delivers it; every robot holds that estimate.
* ``independent``: each robot's own ISAM2 over its own odometry and intra-agent closures.
* ``swarm``: Swarm-SLAM's scheme. At each checkpoint the robots that were in contact since the last
  one form groups (connected components of the contact graph); each group's lowest-id robot
  gathers the members' graphs (their odometry and intra-agent closures so far, and the delivered
  inter-agent closures between members), solves it and sends each member its estimate. A group
  that was the same at the last checkpoint goes on incrementally; a new group starts an ISAM2
  from the members' current beliefs (the lowest-id member's frame kept). A robot alone is a group
  of one: its own graph and what it kept from others (:class:`Memory`: the delivered closures to
  non-members as unary factors at the neighbours' poses it last received; Swarm-SLAM's lone robot
  does not optimize). Messages: per member and solve, its new measurements up to the solver and its
  estimate and the neighbour poses it keeps back, counted on the pair (solver, member).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from studio.core.comms import robot_pairs
from studio.replay.protocol import BackendFactory, Checkpoint, KeptPoses, ReplayBackend, Setup, Step
from studio.solvers.incremental import EdgeTerms, FixedEnds, IncrementalSolver, IsamSettings

__all__ = ["Centralized", "Independent", "Swarm", "Memory", "make_dgs"]


class _Base:
    """What every built-in back-end keeps of the news: the vertices visited and the edges known to
    their robots so far, the per-link counters, the robots' own estimates."""

    def __init__(self, world: Setup) -> None:
        self.world = world
        pairs = robot_pairs(world.num_robots)
        self._pair_index = {(int(a), int(b)): k for k, (a, b) in enumerate(pairs.tolist())}
        self.messages = np.zeros(len(pairs), dtype=np.int64)
        self.bytes = np.zeros(len(pairs), dtype=np.int64)
        self.own = world.problem.initial.copy()
        self.visited = np.zeros(world.problem.num_vertices, dtype=bool)
        self.edges_known = np.zeros(world.problem.num_edges, dtype=bool)
        self._seconds = 0.0
        self.edge_robots = (
            world.agent_of_vertex[world.problem.edge_from],
            world.agent_of_vertex[world.problem.edge_to],
        )
        """Each edge's two ends' robots."""

    def _receive(self, news: Checkpoint) -> None:
        self.visited[news.vertices] = True
        self.edges_known[news.edges] = True
        self.edges_known[news.closures] = True

    def _count(self, a: int, b: int, messages: int, size: int) -> None:
        if a == b:
            return
        k = self._pair_index[(min(a, b), max(a, b))]
        self.messages[k] += messages
        self.bytes[k] += size

    def _known(self, robots: tuple[int, ...] | None) -> tuple[np.ndarray, np.ndarray]:
        """Masks of the vertices and edges known so far to a group of robots (None: anyone)."""
        w = self.world
        vertices = self.visited.copy()
        edges = self.edges_known.copy()
        if robots is not None:
            member = np.zeros(w.num_robots, dtype=bool)
            member[list(robots)] = True
            vertices &= member[w.agent_of_vertex]
            edges &= member[self.edge_robots[0]] & member[self.edge_robots[1]]
        return vertices, edges

    def _step(self, solvers: list[IncrementalSolver]) -> Step:
        total = sum(s.seconds for s in solvers)
        out = self._answer(total - self._seconds)
        self._seconds = total
        return out

    def _answer(self, seconds: float, kept: KeptPoses | None = None) -> Step:
        return Step(self.own.copy(), seconds, self.messages.copy(), self.bytes.copy(), kept)


class Memory:
    """What each robot keeps of what it learned from others: per robot and vertex of another robot,
    the latest estimate of it the robot received and the tick it received it (-1: never). A robot
    receives the estimates of the other ends of the inter-agent closures delivered to it whose
    other robot was in its group (swarm: in the solution its group's solver shares; dgs: in the
    separator values its team's rounds exchange); it knows every closure delivered to it. A group
    solving later enters each delivered closure between a member and a non-member as a unary factor
    on the member's pose, the closure composed with the non-member's pose the member keeps."""

    def __init__(self, world: Setup) -> None:
        self.world = world
        p = world.problem
        self.edges = np.flatnonzero(world.inter_edges())
        self.robot_from = world.agent_of_vertex[p.edge_from[self.edges]]
        self.robot_to = world.agent_of_vertex[p.edge_to[self.edges]]
        self.delivered = np.zeros(len(self.edges), dtype=bool)
        self.poses = np.zeros((world.num_robots, p.num_vertices, p.kind.pose_width))
        self.tick = np.full((world.num_robots, p.num_vertices), -1, dtype=np.int64)

    def deliver(self, closures: np.ndarray) -> None:
        """The inter-agent closures (global edge ids) delivered to their robots at a checkpoint."""
        self.delivered[np.searchsorted(self.edges, closures)] = True

    def _delivered(self, group: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        member = np.zeros(self.world.num_robots, dtype=bool)
        member[list(group)] = True
        return self.delivered.copy(), member[self.robot_from], member[self.robot_to]

    def learn(self, tick: int, group: tuple[int, ...], estimate: np.ndarray) -> dict[int, int]:
        """After ``group`` solved at ``tick`` (``estimate``: its poses, global rows): each member keeps
        the other ends of its delivered closures inside the group; per member, how many poses."""
        known, from_in, to_in = self._delivered(group)
        inside = known & from_in & to_in
        p = self.world.problem
        e = self.edges[inside]
        robots = np.concatenate([self.robot_from[inside], self.robot_to[inside]])
        others = np.concatenate([p.edge_to[e], p.edge_from[e]])
        keys = np.unique(robots * p.num_vertices + others)
        robots, others = keys // p.num_vertices, keys % p.num_vertices
        self.poses[robots, others] = estimate[others]
        self.tick[robots, others] = tick
        counts = np.bincount(robots, minlength=self.world.num_robots)
        return {r: int(counts[r]) for r in group}

    def kept(self) -> KeptPoses:
        """Every pose of another robot some robot keeps, with the estimate it keeps."""
        robot, vertex = np.nonzero(self.tick >= 0)
        return KeptPoses(robot, vertex, self.poses[robot, vertex].copy())

    def fixed(self, group: tuple[int, ...], information_scale: float) -> FixedEnds:
        """The delivered closures between a member of ``group`` and a non-member whose pose the
        member keeps, the non-member's end held there."""
        known, from_in, to_in = self._delivered(group)
        p = self.world.problem
        held_is_from = ~from_in
        member = np.where(held_is_from, self.robot_to, self.robot_from)
        held = np.where(held_is_from, p.edge_from[self.edges], p.edge_to[self.edges])
        take = known & (from_in != to_in)
        take[take] = self.tick[member[take], held[take]] >= 0
        return FixedEnds(self.edges[take], self.poses[member[take], held[take]], held_is_from[take], information_scale)


def _add_known(solver: IncrementalSolver, vertices: np.ndarray, edges: np.ndarray, **kwargs) -> tuple[int, int]:
    new_v = np.flatnonzero(vertices & ~solver.vertices)
    new_e = np.flatnonzero(edges & ~solver.edges)
    if len(new_v) or len(new_e):
        solver.add(new_v, new_e, **kwargs)
    return len(new_v), len(new_e)


def _finish(solver: IncrementalSolver, own: np.ndarray, settings: IsamSettings) -> np.ndarray:
    """The last estimate: more ISAM2 updates, then (``settings.polish``) Gauss-Newton to convergence."""
    solver.refine(settings.final_updates)
    ids = np.flatnonzero(solver.vertices)
    if len(ids):
        own[ids] = solver.solve()
        if settings.polish:
            solver.polish()
            own[ids] = solver.estimate[ids]
    return own


class Centralized(_Base):
    def __init__(self, world: Setup) -> None:
        super().__init__(world)
        self.solver = IncrementalSolver(world.problem, world.agent_of_vertex, world.settings)

    def advance(self, news: Checkpoint) -> Step:
        self._receive(news)
        vertices, edges = self._known(None)
        _add_known(self.solver, vertices, edges)
        ids = np.flatnonzero(self.solver.vertices)
        self.own[ids] = self.solver.solve()
        return self._step([self.solver])

    def finish(self) -> Step:
        self.own = _finish(self.solver, self.own, self.world.settings)
        return self._step([self.solver])


class Independent(_Base):
    def __init__(self, world: Setup) -> None:
        super().__init__(world)
        terms = EdgeTerms(world.problem)
        self.solvers = [
            IncrementalSolver(world.problem, world.agent_of_vertex, world.settings, terms=terms)
            for _ in range(world.num_robots)
        ]

    def advance(self, news: Checkpoint) -> Step:
        self._receive(news)
        for r, solver in enumerate(self.solvers):
            vertices, edges = self._known((r,))
            _add_known(solver, vertices, edges)
            ids = np.flatnonzero(solver.vertices)
            if len(ids):
                self.own[ids] = solver.solve()
        return self._step(self.solvers)

    def finish(self) -> Step:
        for solver in self.solvers:
            self.own = _finish(solver, self.own, self.world.settings)
        return self._step(self.solvers)


class Swarm(_Base):
    #: further ISAM2 updates when a group starts from its members' beliefs (their frames disagree)
    REBUILD_UPDATES = 3
    #: the information of a kept closure's unary factor: the closure's own (docs/replay.md)
    NEIGHBOUR_INFORMATION_SCALE = 1.0

    def __init__(self, world: Setup) -> None:
        super().__init__(world)
        self.groups: dict[tuple[int, ...], IncrementalSolver] = {}
        self.fixed_edges: dict[tuple[int, ...], np.ndarray] = {}
        """Per group, the mask of the kept closures its solver holds as unary factors."""
        self.believed = np.zeros(world.problem.num_vertices, dtype=bool)
        self.memory = Memory(world)
        self.rebuilds = 0
        self.terms = EdgeTerms(world.problem)
        """The edges' GTSAM terms, shared by every group's solver."""

    def _new_group(self, group: tuple[int, ...], vertices: np.ndarray, edges: np.ndarray, fixed: FixedEnds):
        w = self.world
        solver = IncrementalSolver(w.problem, w.agent_of_vertex, w.settings, terms=self.terms)
        solver.estimate = self.own.copy()
        new_v = np.flatnonzero(vertices)
        start = solver.dead_reckon(new_v, self.believed)
        held = self.believed[new_v]
        start[held] = self.own[new_v[held]]
        lead = new_v[w.agent_of_vertex[new_v] == group[0]]
        anchor = self.own[lead[0]] if len(lead) and self.believed[lead[0]] else None
        solver.add(new_v, np.flatnonzero(edges), start=start, anchor_pose=anchor, fixed=fixed)
        if len(group) > 1 or len(fixed.edges):
            solver.refine(self.REBUILD_UPDATES)
            self.rebuilds += 1
        return solver

    def _solve(self, group: tuple[int, ...], vertices: np.ndarray, edges: np.ndarray):
        """The group's solver after its update and the edges sent up to it."""
        w = self.world
        fixed = self.memory.fixed(group, self.NEIGHBOUR_INFORMATION_SCALE)
        held = np.zeros(w.problem.num_edges, dtype=bool)
        held[fixed.edges] = True
        solver = self.groups.get(group)
        if solver is None:
            self.fixed_edges[group] = held
            return self._new_group(group, vertices, edges, fixed), edges.copy()
        sent_edges = edges & ~solver.edges
        new = held[fixed.edges] & ~self.fixed_edges[group][fixed.edges]
        self.fixed_edges[group] |= held
        more = FixedEnds(fixed.edges[new], fixed.held_poses[new], fixed.held_is_from[new], fixed.information_scale)
        _add_known(solver, vertices, edges)
        if len(more.edges):
            solver.add(np.zeros(0, np.int64), np.zeros(0, np.int64), fixed=more)
        return solver, sent_edges

    def advance(self, news: Checkpoint) -> Step:
        self._receive(news)
        self.memory.deliver(news.closures)
        w, tick = self.world, news.tick
        # a group that is not one of this checkpoint's is gone for good: its solver goes before any
        # new group's is built, not beside it
        self.groups = {g: s for g, s in self.groups.items() if g in news.groups}
        kept: dict[tuple[int, ...], IncrementalSolver] = {}
        seconds = 0.0
        for group in news.groups:
            vertices, edges = self._known(group)
            if not vertices.any():
                continue
            old = self.groups.get(group)
            before = 0.0 if old is None else old.seconds
            solver, sent_edges = self._solve(group, vertices, edges)
            ids = np.flatnonzero(solver.vertices)
            self.own[ids] = solver.solve()
            self.believed[ids] = True
            seconds += solver.seconds - before
            kept[group] = solver
            learned = self.memory.learn(tick, group, self.own)
            lead_robot = group[0]
            edges_of = np.bincount(self.edge_robots[0][sent_edges], minlength=w.num_robots)
            poses_of = np.bincount(w.agent_of_vertex[ids], minlength=w.num_robots)
            for m in group[1:]:
                # up: its new measurements; down: its estimate and the poses it keeps of the others
                n_poses = int(poses_of[m]) + learned[m]
                self._count(lead_robot, m, 2, int(edges_of[m]) * w.edge_bytes + n_poses * w.pose_bytes)
        self.groups = kept
        self.fixed_edges = {g: self.fixed_edges[g] for g in kept}
        return self._answer(seconds, self.memory.kept())

    def finish(self) -> Step:
        seconds = 0.0
        for solver in self.groups.values():
            before = solver.seconds
            self.own = _finish(solver, self.own, self.world.settings)
            seconds += solver.seconds - before
        return self._answer(seconds, self.memory.kept())


def make_dgs(world: Setup) -> ReplayBackend:
    """Distributed Gauss-Seidel, a few rounds per checkpoint (:mod:`studio.replay.dgs_backend`)."""
    from studio.replay.dgs_backend import Dgs

    return Dgs(world)


if TYPE_CHECKING:  # the built-in back-ends are factories of the public protocol: mypy checks each
    _FACTORIES: tuple[BackendFactory, ...] = (Centralized, Independent, Swarm, make_dgs)
