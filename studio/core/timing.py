"""When each measurement of a pose graph is made (pure numpy, no I/O).

* An odometry edge or an intra-agent loop closure is measured when its agent reaches the later of
  its two poses: the stamp of ``max(from_index, to_index)``.
* An inter-agent loop closure can only be found once both robots have visited its poses: the later
  of the two poses' stamps. (When the robots *learn* it is the communication model's business,
  :mod:`studio.core.comms`.)

Stamps are the dataset's own (``AgentGraph.stamps_ns``: real stamps for converted data, the node
index in seconds for kollagen's datasets), or, with ``period_ns``, every agent's pose index times
that period (a synthetic clock shared by all agents).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.core.errors import ConfigError, GraphError
from studio.core.model import PoseGraph

__all__ = ["MeasurementTimes", "measurement_times"]


@dataclass(frozen=True, eq=False)
class MeasurementTimes:
    """The time of every pose and every measurement of a graph, int64 nanoseconds."""

    pose_ns: tuple[np.ndarray, ...]
    """Per agent, the stamp of each pose (the clock the replay runs on)."""
    odometry_ns: tuple[np.ndarray, ...]
    """Per agent, when each odometry edge is measured."""
    loop_closure_ns: tuple[np.ndarray, ...]
    """Per agent, when each intra-agent loop closure is measured."""
    inter_ns: np.ndarray
    """When each inter-agent loop closure becomes measurable (both poses visited)."""
    period_ns: int | None
    """The synthetic period used (pose index x period), or None for the dataset's own stamps."""

    @property
    def start_ns(self) -> int:
        return int(min(int(s[0]) for s in self.pose_ns))

    @property
    def end_ns(self) -> int:
        return int(max(int(s[-1]) for s in self.pose_ns))


def measurement_times(graph: PoseGraph, *, period_ns: int | None = None) -> MeasurementTimes:
    """The times of ``graph``'s measurements (see the module doc); ``period_ns`` replaces every
    agent's stamps by ``pose index x period_ns``."""
    if period_ns is not None:
        if isinstance(period_ns, bool) or int(period_ns) != period_ns or period_ns <= 0:
            raise ConfigError(f"period: must be a positive duration, got {period_ns!r} ns")
        period_ns = int(period_ns)
        longest = max((a.num_poses for a in graph.agents), default=1)
        if (longest - 1) * period_ns > np.iinfo(np.int64).max:  # the stamps would wrap round
            raise ConfigError(
                f"period: {period_ns} ns x {longest - 1} poses is beyond the int64 nanosecond range (about 292 years)",
                option="period",
            )
    poses = []
    for a in graph.agents:
        if period_ns is not None:
            stamps = np.arange(a.num_poses, dtype=np.int64) * np.int64(period_ns)
        else:
            stamps = np.asarray(a.stamps_ns, dtype=np.int64)
            if len(stamps) > 1 and np.any(np.diff(stamps) <= 0):
                bad = int(np.flatnonzero(np.diff(stamps) <= 0)[0]) + 1
                raise GraphError(f"{a.name}: stamps run backwards at pose {bad}")
        poses.append(stamps)
    odometry = tuple(p[np.maximum(a.odometry.from_index, a.odometry.to_index)] for p, a in zip(poses, graph.agents))
    closures = tuple(
        p[np.maximum(a.loop_closures.from_index, a.loop_closures.to_index)] for p, a in zip(poses, graph.agents)
    )
    inter = graph.inter
    if len(inter):
        from_ns = np.concatenate(poses)[_offsets(poses)[inter.from_agent] + inter.from_index]
        to_ns = np.concatenate(poses)[_offsets(poses)[inter.to_agent] + inter.to_index]
        inter_ns = np.maximum(from_ns, to_ns)
    else:
        inter_ns = np.zeros(0, dtype=np.int64)
    return MeasurementTimes(tuple(poses), odometry, closures, inter_ns.astype(np.int64), period_ns)


def _offsets(poses: list[np.ndarray]) -> np.ndarray:
    return np.concatenate([[0], np.cumsum([len(p) for p in poses])]).astype(np.int64)
