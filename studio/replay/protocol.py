"""The back-end protocol of ``studio replay``: what a back-end is told and what it answers.

A back-end is made once per replay from a :class:`Setup` (the team and the dataset's columns, by
global id), then told each checkpoint's news in time order (:meth:`ReplayBackend.advance` with a
:class:`Checkpoint`: each robot's poses visited and measurements made since the last checkpoint,
with their stamps, the inter-agent closures delivered since, and who was in contact), and after the
last checkpoint told the end (:meth:`ReplayBackend.finish`). Each call answers a :class:`Step`:
each robot's estimate of its own poses, the poses of other robots it holds, and the messages and
bytes sent on each link so far.

The studio's own back-ends (centralized, independent, swarm, dgs) implement exactly this protocol;
so do plug-ins from other packages (entry point group ``studio.replay_backends``) and programs in
other languages (``command:PROGRAM``, the same messages as JSON lines: docs/replay.md).

The :class:`Setup` holds the dataset's columns so that an in-process back-end indexes rows by
global id without copies; a back-end reads the row of a vertex or an edge only once a checkpoint
has given its id (the studio's back-ends do; a program behind ``command:`` is sent nothing else).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from studio.solvers.isam_settings import IsamSettings
from studio.solvers.problem import Problem

__all__ = ["Setup", "Checkpoint", "Step", "KeptPoses", "ReplayBackend", "BackendFactory"]


@dataclass(frozen=True, eq=False)
class Setup:
    """What a back-end is made from: the team, the dataset's columns by global id, the options."""

    problem: Problem
    """Vertices (``initial``: each pose's initial guess, the dataset's dead reckoning) and edges
    (``edge_from``/``edge_to``, ``measurements``, ``information_upper``), by global id."""
    agent_of_vertex: np.ndarray
    """Per vertex, its robot (0-based)."""
    num_robots: int
    settings: IsamSettings
    """ISAM2's options (``studio replay --relinearize-*``, ``--polish``) for back-ends that use it."""

    @property
    def pose_bytes(self) -> int:
        """Bytes of one pose on a link: its id and its values, 8 bytes each."""
        return 8 * (1 + self.problem.kind.pose_width)

    @property
    def edge_bytes(self) -> int:
        """Bytes of one measurement on a link: its two ids, its values and its information."""
        return 8 * (2 + self.problem.kind.pose_width + self.problem.kind.information_width)

    def inter_edges(self) -> np.ndarray:
        """Per edge: an inter-agent closure (its two ends on different robots)."""
        p = self.problem
        return np.asarray(self.agent_of_vertex[p.edge_from] != self.agent_of_vertex[p.edge_to])


@dataclass(frozen=True, eq=False)
class Checkpoint:
    """The news of one checkpoint: what happened since the last one (columns of global ids)."""

    tick: int
    """The checkpoint's tick (``studio replay --step`` apart)."""
    time_ns: int
    vertices: np.ndarray
    """Poses visited since the last checkpoint (global ids, ascending; robot: ``agent_of_vertex``)."""
    vertex_ns: np.ndarray
    """When each was visited."""
    edges: np.ndarray
    """The robots' own measurements made since (odometry and intra-agent closures; global ids,
    ascending): each known to the robot of its ends."""
    edge_ns: np.ndarray
    """When each was measured."""
    closures: np.ndarray
    """The inter-agent closures delivered since (global edge ids, ascending): each known to both
    its robots from now on."""
    closure_ns: np.ndarray
    """When each was measured (its delivery is this checkpoint)."""
    groups: list[tuple[int, ...]]
    """The robots present (their first pose visited) as groups of those that could talk since the
    last checkpoint (connected components of the contacts; sorted, a robot alone is a group)."""
    contacts: np.ndarray
    """``(k, 2)``: the pairs of robots in contact at some tick since the last checkpoint."""


@dataclass(frozen=True, eq=False)
class KeptPoses:
    """The estimates robots keep of other robots' poses: per row the robot keeping it, the vertex
    (global id) and the pose it holds."""

    robot: np.ndarray
    vertex: np.ndarray
    poses: np.ndarray


@dataclass(frozen=True, eq=False)
class Step:
    """What a back-end believes at one checkpoint (its answer to :meth:`ReplayBackend.advance`)."""

    own: np.ndarray
    """``(num_vertices, w)``: each vertex's estimate by its own robot (rows of poses not yet visited
    are unused)."""
    solver_seconds: float
    """Wall time in the solver since the last checkpoint."""
    messages: np.ndarray
    """Per link (the pairs of :func:`studio.core.comms.robot_pairs`: (0,1), (0,2), ..., (1,2), ...),
    the messages sent on it since the start."""
    bytes: np.ndarray
    """Per link, the bytes sent on it since the start."""
    kept: KeptPoses | None = None
    """The robots' own estimates of other robots' poses; None for a back-end whose robots keep none
    (centralized holds one estimate, independent shares nothing)."""


class ReplayBackend(Protocol):
    """A running back-end: told each checkpoint's news, then the end."""

    def advance(self, news: Checkpoint) -> Step:
        """Take the news of one checkpoint; answer what the robots believe now."""
        ...

    def finish(self) -> Step:
        """The end (after the last checkpoint, no news): answer the final beliefs."""
        ...


BackendFactory = Callable[[Setup], ReplayBackend]
"""What a registry entry or a plug-in's entry point names: ``factory(setup) -> ReplayBackend``."""
