"""The back-ends of ``studio replay``: what each robot believes as measurements and closures arrive.

Every back-end sees the same :class:`World` and is advanced checkpoint by checkpoint (every
``every`` ticks and at the end); at each it returns ``own`` (one row per vertex of the problem: the
estimate the vertex's own robot holds of it; rows of poses not yet visited are unused) and counts
what it sent on each link. The registry :data:`studio.replay.registry.BACKENDS` is the one place a
back-end is declared.

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

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from studio.core.comms import robot_pairs
from studio.solvers.incremental import FixedEnds, IncrementalSolver, IsamSettings
from studio.solvers.problem import Problem

__all__ = ["World", "Backend", "BackendFactory", "KeptPoses", "Step", "make_dgs"]


@dataclass(frozen=True, eq=False)
class World:
    """What the simulation knows about the dataset and the schedule, as columns over global ids."""

    problem: Problem
    agent_of_vertex: np.ndarray
    vertex_ns: np.ndarray
    """When each vertex is visited."""
    edge_ns: np.ndarray
    """When each edge is measured."""
    edge_closure: np.ndarray
    """Per edge, its inter-agent closure index, -1 for a robot's own edge."""
    closure_from: np.ndarray
    closure_to: np.ndarray
    delivered_tick: np.ndarray
    """Per inter-agent closure, the tick its robots learn it, -1 for never."""
    ticks_ns: np.ndarray
    num_robots: int
    settings: IsamSettings = field(default_factory=IsamSettings)

    @property
    def pose_bytes(self) -> int:
        return 8 * (1 + self.problem.kind.pose_width)

    @property
    def edge_bytes(self) -> int:
        return 8 * (2 + self.problem.kind.pose_width + self.problem.kind.information_width)

    def edges_known(self) -> np.ndarray:
        """Per edge: known to some robot by the end (its own edges, the closures delivered): the
        edges the centralized back-end optimizes over."""
        inter = self.edge_closure >= 0
        out = ~inter
        out[inter] = self.delivered_tick[self.edge_closure[inter]] >= 0
        return out

    def edge_delivered_tick(self) -> np.ndarray:
        """Per edge: the tick from which it may be known (own edges: their measurement tick)."""
        own = np.searchsorted(self.ticks_ns, self.edge_ns, side="left")
        inter = self.edge_closure >= 0
        out = own.astype(np.int64)
        d = self.delivered_tick[self.edge_closure[inter]]
        out[inter] = np.where(d >= 0, d, np.iinfo(np.int64).max)
        return out


@dataclass(frozen=True, eq=False)
class KeptPoses:
    """The estimates robots keep of other robots' poses: per row the robot keeping it, the vertex
    (global id) and the pose it holds."""

    robot: np.ndarray
    vertex: np.ndarray
    poses: np.ndarray


@dataclass(frozen=True, eq=False)
class Step:
    """What a back-end believes at one checkpoint."""

    own: np.ndarray
    """``(num_vertices, w)``: each vertex's estimate by its own robot."""
    solver_seconds: float
    """Wall time in the solver since the last checkpoint."""
    kept: KeptPoses | None = None
    """The robots' own estimates of other robots' poses (swarm, dgs: :class:`Memory`); None for a
    back-end whose robots keep none (centralized holds one estimate, independent shares nothing)."""


class Backend(Protocol):
    """A running back-end: :meth:`advance` to a tick (groups: robots that may have talked since the
    last checkpoint), :meth:`finish` after the last; per-link counters in ``messages``/``bytes``."""

    messages: np.ndarray
    bytes: np.ndarray

    def advance(self, tick: int, groups: list[tuple[int, ...]]) -> Step: ...

    def finish(self) -> Step: ...


BackendFactory = Callable[[World], Backend]


class _Base:
    def __init__(self, world: World) -> None:
        self.world = world
        pairs = robot_pairs(world.num_robots)
        self._pair_index = {(int(a), int(b)): k for k, (a, b) in enumerate(pairs.tolist())}
        self.messages = np.zeros(len(pairs), dtype=np.int64)
        self.bytes = np.zeros(len(pairs), dtype=np.int64)
        self.own = world.problem.initial.copy()
        self._edge_tick = world.edge_delivered_tick()
        self._seconds = 0.0

    def _count(self, a: int, b: int, messages: int, size: int) -> None:
        if a == b:
            return
        k = self._pair_index[(min(a, b), max(a, b))]
        self.messages[k] += messages
        self.bytes[k] += size

    def _known(self, tick: int, robots: tuple[int, ...] | None) -> tuple[np.ndarray, np.ndarray]:
        """Masks of the vertices and edges known at ``tick`` to a group of robots (None: anyone)."""
        w = self.world
        t = w.ticks_ns[tick]
        vertices = w.vertex_ns <= t
        edges = self._edge_tick <= tick
        if robots is not None:
            member = np.zeros(w.num_robots, dtype=bool)
            member[list(robots)] = True
            vertices &= member[w.agent_of_vertex]
            ends = member[w.agent_of_vertex[w.problem.edge_from]] & member[w.agent_of_vertex[w.problem.edge_to]]
            edges &= ends
        return vertices, edges

    def _step(self, solvers: list[IncrementalSolver]) -> Step:
        total = sum(s.seconds for s in solvers)
        out = Step(self.own.copy(), total - self._seconds)
        self._seconds = total
        return out


class Memory:
    """What each robot keeps of what it learned from others: per robot and vertex of another robot,
    the latest estimate of it the robot received and the tick it received it (-1: never). A robot
    receives the estimates of the other ends of the inter-agent closures delivered to it whose
    other robot was in its group (swarm: in the solution its group's solver shares; dgs: in the
    separator values its team's rounds exchange); it knows every closure delivered to it. A group
    solving later enters each delivered closure between a member and a non-member as a unary factor
    on the member's pose, the closure composed with the non-member's pose the member keeps."""

    def __init__(self, world: World) -> None:
        self.world = world
        p = world.problem
        self.edges = np.flatnonzero(world.edge_closure >= 0)
        self.robot_from = world.agent_of_vertex[p.edge_from[self.edges]]
        self.robot_to = world.agent_of_vertex[p.edge_to[self.edges]]
        self.delivered_tick = world.delivered_tick[world.edge_closure[self.edges]]
        self.poses = np.zeros((world.num_robots, p.num_vertices, p.kind.pose_width))
        self.tick = np.full((world.num_robots, p.num_vertices), -1, dtype=np.int64)

    def _delivered(self, tick: int, group: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        member = np.zeros(self.world.num_robots, dtype=bool)
        member[list(group)] = True
        known = (self.delivered_tick >= 0) & (self.delivered_tick <= tick)
        return known, member[self.robot_from], member[self.robot_to]

    def learn(self, tick: int, group: tuple[int, ...], estimate: np.ndarray) -> dict[int, int]:
        """After ``group`` solved at ``tick`` (``estimate``: its poses, global rows): each member keeps
        the other ends of its delivered closures inside the group; per member, how many poses."""
        known, from_in, to_in = self._delivered(tick, group)
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

    def fixed(self, tick: int, group: tuple[int, ...], information_scale: float) -> FixedEnds:
        """The delivered closures between a member of ``group`` and a non-member whose pose the
        member keeps, the non-member's end held there."""
        known, from_in, to_in = self._delivered(tick, group)
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
    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.solver = IncrementalSolver(world.problem, world.agent_of_vertex, world.settings)

    def advance(self, tick: int, groups: list[tuple[int, ...]]) -> Step:
        vertices, edges = self._known(tick, None)
        _add_known(self.solver, vertices, edges)
        ids = np.flatnonzero(self.solver.vertices)
        self.own[ids] = self.solver.solve()
        return self._step([self.solver])

    def finish(self) -> Step:
        self.own = _finish(self.solver, self.own, self.world.settings)
        return self._step([self.solver])


class Independent(_Base):
    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.solvers = [
            IncrementalSolver(world.problem, world.agent_of_vertex, world.settings) for _ in range(world.num_robots)
        ]

    def advance(self, tick: int, groups: list[tuple[int, ...]]) -> Step:
        for r, solver in enumerate(self.solvers):
            vertices, edges = self._known(tick, (r,))
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

    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.groups: dict[tuple[int, ...], IncrementalSolver] = {}
        self.fixed_edges: dict[tuple[int, ...], np.ndarray] = {}
        """Per group, the mask of the kept closures its solver holds as unary factors."""
        self.believed = np.zeros(world.problem.num_vertices, dtype=bool)
        self.memory = Memory(world)
        self.rebuilds = 0

    def _new_group(self, group: tuple[int, ...], vertices: np.ndarray, edges: np.ndarray, fixed: FixedEnds):
        w = self.world
        solver = IncrementalSolver(w.problem, w.agent_of_vertex, w.settings)
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

    def _solve(self, tick: int, group: tuple[int, ...], vertices: np.ndarray, edges: np.ndarray):
        """The group's solver after its update at ``tick`` and the edges sent up to it."""
        w = self.world
        fixed = self.memory.fixed(tick, group, self.NEIGHBOUR_INFORMATION_SCALE)
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

    def advance(self, tick: int, groups: list[tuple[int, ...]]) -> Step:
        w = self.world
        kept: dict[tuple[int, ...], IncrementalSolver] = {}
        seconds = 0.0
        for group in groups:
            vertices, edges = self._known(tick, group)
            if not vertices.any():
                continue
            old = self.groups.get(group)
            before = 0.0 if old is None else old.seconds
            solver, sent_edges = self._solve(tick, group, vertices, edges)
            ids = np.flatnonzero(solver.vertices)
            self.own[ids] = solver.solve()
            self.believed[ids] = True
            seconds += solver.seconds - before
            kept[group] = solver
            learned = self.memory.learn(tick, group, self.own)
            lead_robot = group[0]
            for m in group[1:]:
                # up: its new measurements; down: its estimate and the poses it keeps of the others
                n_edges = int((sent_edges & (w.agent_of_vertex[w.problem.edge_from] == m)).sum())
                n_poses = int((w.agent_of_vertex[ids] == m).sum()) + learned[m]
                self._count(lead_robot, m, 2, n_edges * w.edge_bytes + n_poses * w.pose_bytes)
        self.groups = kept
        self.fixed_edges = {g: self.fixed_edges[g] for g in kept}
        return Step(self.own.copy(), seconds, self.memory.kept())

    def finish(self) -> Step:
        seconds = 0.0
        for solver in self.groups.values():
            before = solver.seconds
            self.own = _finish(solver, self.own, self.world.settings)
            seconds += solver.seconds - before
        return Step(self.own.copy(), seconds, self.memory.kept())


def make_dgs(world: World) -> Backend:
    """Distributed Gauss-Seidel, a few rounds per checkpoint (:mod:`studio.replay.dgs_backend`)."""
    from studio.replay.dgs_backend import Dgs

    return Dgs(world)
