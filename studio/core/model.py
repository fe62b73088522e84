"""The shared in-memory model of a multi-agent pose graph (pure data, no I/O).

Everything is stored as numpy columns, one array per quantity, never one Python object per pose or
edge. A graph is planar (:attr:`PoseKind.SE2`: poses ``[x, y, theta]``, information upper triangle of
3x3 = 6 values) or spatial (:attr:`PoseKind.SE3`: poses ``[x, y, z, qx, qy, qz, qw]``, information
upper triangle of 6x6 = 21 values over ``(x, y, z, rx, ry, rz)``). Edge measurements are the pose of
the ``to`` vertex expressed in the frame of the ``from`` vertex (the g2o convention).

The containers enforce their invariants at construction and raise :class:`~studio.core.errors.GraphError`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from studio.core.errors import GraphError
from studio.core.geometry import planar_poses_to_se3, se2_information_to_se3

__all__ = [
    "PoseKind",
    "Edges",
    "InterAgentEdges",
    "AgentGraph",
    "PoseGraph",
    "RangeBearing",
    "Priors",
    "graphs_equal",
]

_QUAT_TOLERANCE = 1e-6


class PoseKind(str, enum.Enum):
    SE2 = "SE2"
    SE3 = "SE3"

    @property
    def pose_width(self) -> int:
        return 3 if self is PoseKind.SE2 else 7

    @property
    def information_width(self) -> int:
        return 6 if self is PoseKind.SE2 else 21


def _as_index(a: npt.ArrayLike, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=np.int64)
    if arr.ndim != 1:
        raise GraphError(f"{name} must be one-dimensional, got shape {arr.shape}")
    return arr


def _as_rows(a: npt.ArrayLike, width: int, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim == 1 and arr.size == 0:
        arr = arr.reshape(0, width)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise GraphError(f"{name} must have shape (n, {width}), got {arr.shape}")
    if not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.all(np.isfinite(arr), axis=1))[0])
        raise GraphError(f"{name} row {bad} is not finite")
    return arr


def _first_outside(col: np.ndarray, upper: int | np.ndarray) -> int | None:
    """The first place where ``col`` is negative or not below ``upper`` (a bound, or one per entry),
    or None; two reductions where every entry is inside (the usual case)."""
    if not col.size:
        return None
    if isinstance(upper, int) and col.min() >= 0 and col.max() < upper:
        return None
    wrong = np.flatnonzero((col < 0) | (col >= upper))
    return int(wrong[0]) if wrong.size else None


def _check_poses(poses: np.ndarray, kind: PoseKind, name: str) -> None:
    if kind is PoseKind.SE3 and len(poses):
        norms = np.linalg.norm(poses[:, 3:7], axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > _QUAT_TOLERANCE)
        if bad.size:
            raise GraphError(f"{name} row {int(bad[0])} has a non-unit quaternion (norm {norms[bad[0]]:.9g})")


@dataclass(frozen=True, eq=False)
class Edges:
    """Edges inside one agent: vertex indices are 0-based positions in that agent's poses."""

    kind: PoseKind
    from_index: np.ndarray
    to_index: np.ndarray
    measurements: np.ndarray
    information_upper: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "from_index", _as_index(self.from_index, "from_index"))
        object.__setattr__(self, "to_index", _as_index(self.to_index, "to_index"))
        object.__setattr__(self, "measurements", _as_rows(self.measurements, self.kind.pose_width, "measurements"))
        object.__setattr__(
            self,
            "information_upper",
            _as_rows(self.information_upper, self.kind.information_width, "information_upper"),
        )
        n = len(self.from_index)
        if not (len(self.to_index) == len(self.measurements) == len(self.information_upper) == n):
            raise GraphError("edge columns must have matching lengths")
        _check_poses(self.measurements, self.kind, "measurements")

    def __len__(self) -> int:
        return len(self.from_index)

    @classmethod
    def empty(cls, kind: PoseKind) -> Edges:
        z = np.zeros(0, dtype=np.int64)
        return cls(kind, z, z, np.zeros((0, kind.pose_width)), np.zeros((0, kind.information_width)))

    def to_se3(self) -> Edges:
        if self.kind is PoseKind.SE3:
            return self
        return Edges(
            PoseKind.SE3,
            self.from_index,
            self.to_index,
            planar_poses_to_se3(self.measurements),
            se2_information_to_se3(self.information_upper),
        )


@dataclass(frozen=True, eq=False)
class InterAgentEdges:
    """Edges between agents; agents are 0-based positions in :attr:`PoseGraph.agents`."""

    kind: PoseKind
    from_agent: np.ndarray
    from_index: np.ndarray
    to_agent: np.ndarray
    to_index: np.ndarray
    measurements: np.ndarray
    information_upper: np.ndarray

    def __post_init__(self) -> None:
        for name in ("from_agent", "from_index", "to_agent", "to_index"):
            object.__setattr__(self, name, _as_index(getattr(self, name), name))
        object.__setattr__(self, "measurements", _as_rows(self.measurements, self.kind.pose_width, "measurements"))
        object.__setattr__(
            self,
            "information_upper",
            _as_rows(self.information_upper, self.kind.information_width, "information_upper"),
        )
        n = len(self.from_index)
        lengths = {len(self.from_agent), len(self.to_agent), len(self.to_index)}
        lengths |= {len(self.measurements), len(self.information_upper)}
        if lengths != {n}:
            raise GraphError("inter-agent edge columns must have matching lengths")
        _check_poses(self.measurements, self.kind, "inter-agent measurements")

    def __len__(self) -> int:
        return len(self.from_index)

    @classmethod
    def empty(cls, kind: PoseKind) -> InterAgentEdges:
        z = np.zeros(0, dtype=np.int64)
        return cls(kind, z, z, z, z, np.zeros((0, kind.pose_width)), np.zeros((0, kind.information_width)))

    def to_se3(self) -> InterAgentEdges:
        if self.kind is PoseKind.SE3:
            return self
        return InterAgentEdges(
            PoseKind.SE3,
            self.from_agent,
            self.from_index,
            self.to_agent,
            self.to_index,
            planar_poses_to_se3(self.measurements),
            se2_information_to_se3(self.information_upper),
        )


@dataclass(frozen=True, eq=False)
class AgentGraph:
    """One agent: its poses (ground truth and initial estimate), odometry and intra-agent loop closures."""

    name: str
    kind: PoseKind
    stamps_ns: np.ndarray
    """Timestamp of each pose, int64 nanoseconds (synthetic data: node index in seconds)."""
    initial: np.ndarray
    """Initial estimate (dead reckoning), one row per pose."""
    ground_truth: np.ndarray | None
    """Ground truth, one row per pose, or None where a dataset has none."""
    odometry: Edges
    loop_closures: Edges
    ground_truth_se3: np.ndarray | None = field(default=None, repr=False)
    """Planar agents only, optional: the ground truth as read from a 3D file (``(n, 7)``), kept so
    that :meth:`to_se3` returns the file's quaternions instead of re-deriving them from the yaw."""

    def __post_init__(self) -> None:
        if not self.name:
            raise GraphError("an agent needs a name")
        object.__setattr__(self, "stamps_ns", _as_index(self.stamps_ns, f"{self.name}: stamps_ns"))
        w = self.kind.pose_width
        object.__setattr__(self, "initial", _as_rows(self.initial, w, f"{self.name}: initial"))
        n = len(self.initial)
        if n == 0:
            raise GraphError(f"{self.name}: an agent needs at least one pose")
        if len(self.stamps_ns) != n:
            raise GraphError(f"{self.name}: {len(self.stamps_ns)} stamps for {n} poses")
        if n > 1 and (np.diff(self.stamps_ns) <= 0).any():
            bad = int(np.flatnonzero(np.diff(self.stamps_ns) <= 0)[0]) + 1
            raise GraphError(f"{self.name}: stamps must increase (pose {bad})")
        _check_poses(self.initial, self.kind, f"{self.name}: initial")
        if self.ground_truth is not None:
            gt = _as_rows(self.ground_truth, w, f"{self.name}: ground_truth")
            if len(gt) != n:
                raise GraphError(f"{self.name}: {len(gt)} ground-truth poses for {n} poses")
            _check_poses(gt, self.kind, f"{self.name}: ground_truth")
            object.__setattr__(self, "ground_truth", gt)
        if self.ground_truth_se3 is not None:
            if self.kind is not PoseKind.SE2 or self.ground_truth is None:
                raise GraphError(f"{self.name}: ground_truth_se3 belongs to a planar agent with ground truth")
            gt3 = _as_rows(self.ground_truth_se3, 7, f"{self.name}: ground_truth_se3")
            if len(gt3) != n:
                raise GraphError(f"{self.name}: {len(gt3)} 3D ground-truth poses for {n} poses")
            object.__setattr__(self, "ground_truth_se3", gt3)
        for label, edges in (("odometry", self.odometry), ("loop closure", self.loop_closures)):
            if edges.kind is not self.kind:
                raise GraphError(f"{self.name}: {label} edges are {edges.kind.value}, poses {self.kind.value}")
            for col in (edges.from_index, edges.to_index):
                wrong = _first_outside(col, n)
                if wrong is not None:
                    raise GraphError(
                        f"{self.name}: {label} edge {wrong} refers to vertex {int(col[wrong])}, "
                        f"but the agent has {n} poses"
                    )

    @property
    def num_poses(self) -> int:
        return len(self.initial)

    def se3_poses(self, ground_truth: bool = False) -> np.ndarray | None:
        """The initial estimate (or the ground truth, None where there is none) as ``(n, 7)`` SE(3)
        poses: planar poses lifted once and kept, the ground truth read from a 3D file as it was."""
        poses = self.ground_truth if ground_truth else self.initial
        if self.kind is PoseKind.SE3 or poses is None:
            return poses
        if ground_truth and self.ground_truth_se3 is not None:
            return self.ground_truth_se3
        key = "_se3_truth" if ground_truth else "_se3_initial"
        lifted = self.__dict__.get(key)
        if lifted is None:
            lifted = planar_poses_to_se3(poses)
            object.__setattr__(self, key, lifted)
        return lifted

    def to_se3(self) -> AgentGraph:
        if self.kind is PoseKind.SE3:
            return self
        initial = self.se3_poses()
        assert initial is not None
        return AgentGraph(
            self.name,
            PoseKind.SE3,
            self.stamps_ns,
            initial,
            self.se3_poses(ground_truth=True),
            self.odometry.to_se3(),
            self.loop_closures.to_se3(),
        )


@dataclass(frozen=True, eq=False)
class PoseGraph:
    """Several agents and the loop closures between them."""

    kind: PoseKind
    agents: tuple[AgentGraph, ...]
    inter: InterAgentEdges
    metadata: dict[str, Any] = field(default_factory=dict)
    """Free-form facts about the dataset (config that made it, source files); not compared."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "agents", tuple(self.agents))
        if not self.agents:
            raise GraphError("a pose graph needs at least one agent")
        names = [a.name for a in self.agents]
        if len(set(names)) != len(names):
            raise GraphError(f"agent names must be unique: {names}")
        for a in self.agents:
            if a.kind is not self.kind:
                raise GraphError(f"agent {a.name} is {a.kind.value}, graph is {self.kind.value}")
        if self.inter.kind is not self.kind:
            raise GraphError("inter-agent edges must have the graph's pose kind")
        sizes = np.array([a.num_poses for a in self.agents])
        for side in ("from", "to"):
            agent = getattr(self.inter, f"{side}_agent")
            index = getattr(self.inter, f"{side}_index")
            first = _first_outside(agent, len(self.agents))
            if first is not None:
                raise GraphError(f"inter-agent edge {first} refers to unknown agent {int(agent[first])}")
            if not len(index) or (index.min() >= 0 and index.max() < sizes.min()):
                continue  # every vertex inside the smallest agent
            k = _first_outside(index, sizes[agent])
            if k is not None:
                raise GraphError(
                    f"inter-agent edge {k} refers to vertex {int(index[k])} of agent "
                    f"{self.agents[agent[k]].name}, which has {int(sizes[agent[k]])} poses"
                )

    @property
    def num_poses(self) -> int:
        return sum(a.num_poses for a in self.agents)

    def edge_counts(self) -> dict[str, int]:
        return {
            "odometry": sum(len(a.odometry) for a in self.agents),
            "intra_loop_closures": sum(len(a.loop_closures) for a in self.agents),
            "inter_loop_closures": len(self.inter),
        }

    def to_se3(self) -> PoseGraph:
        """The same graph with SE(3) poses (planar poses lifted; computed once, then cached)."""
        if self.kind is PoseKind.SE3:
            return self
        cached: PoseGraph | None = self.__dict__.get("_se3")
        if cached is not None:
            return cached
        lifted = PoseGraph(
            PoseKind.SE3, tuple(a.to_se3() for a in self.agents), self.inter.to_se3(), dict(self.metadata)
        )
        object.__setattr__(self, "_se3", lifted)
        return lifted


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    same: bool = a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()
    return same


def graphs_equal(a: PoseGraph, b: PoseGraph) -> bool:
    """True when both graphs hold bit-identical columns (metadata is ignored)."""
    if a.kind is not b.kind or len(a.agents) != len(b.agents):
        return False
    cols = ("from_index", "to_index", "measurements", "information_upper")
    for x, y in zip(a.agents, b.agents):
        if x.name != y.name or not all(
            _same(getattr(x, c), getattr(y, c)) for c in ("stamps_ns", "initial", "ground_truth")
        ):
            return False
        for ex, ey in ((x.odometry, y.odometry), (x.loop_closures, y.loop_closures)):
            if not all(_same(getattr(ex, c), getattr(ey, c)) for c in cols):
                return False
    return all(_same(getattr(a.inter, c), getattr(b.inter, c)) for c in cols + ("from_agent", "to_agent"))


@dataclass(frozen=True, eq=False)
class RangeBearing:
    """Range-bearing sightings of one agent by another (MR.CLAM's robot-to-robot measurements), as
    columns, one row per sighting. Agents are 0-based positions in :attr:`PoseGraph.agents`; each
    side of a sighting is tied to the agent's keyframe nearest in time (``*_index``), and
    ``*_offset_ns`` says how far that keyframe is from the sighting (``stamp - keyframe stamp``).

    ``range_m`` is the distance from the observer's body origin to the observed agent, ``bearing_rad``
    the direction of the observed agent in the observer's body frame (from the x axis, counter-clockwise
    about z), both in the plane; ``sigma_*`` their standard deviations.
    """

    stamps_ns: np.ndarray
    observer_agent: np.ndarray
    observer_index: np.ndarray
    observed_agent: np.ndarray
    observed_index: np.ndarray
    range_m: np.ndarray
    bearing_rad: np.ndarray
    sigma_range_m: np.ndarray
    sigma_bearing_rad: np.ndarray
    observer_offset_ns: np.ndarray
    observed_offset_ns: np.ndarray

    _INT = ("stamps_ns", "observer_agent", "observer_index", "observed_agent", "observed_index")
    _OFFSETS = ("observer_offset_ns", "observed_offset_ns")
    _FLOAT = ("range_m", "bearing_rad", "sigma_range_m", "sigma_bearing_rad")

    def __post_init__(self) -> None:
        for name in (*self._INT, *self._OFFSETS):
            object.__setattr__(self, name, _as_index(getattr(self, name), name))
        for name in self._FLOAT:
            arr = np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            if arr.ndim != 1:
                raise GraphError(f"{name} must be one-dimensional, got shape {arr.shape}")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise GraphError(f"{name} row {int(bad[0])} is not finite")
            object.__setattr__(self, name, arr)
        n = len(self.stamps_ns)
        names = (*self._INT, *self._OFFSETS, *self._FLOAT)
        if any(len(getattr(self, name)) != n for name in names):
            raise GraphError("range-bearing columns must have matching lengths")
        if n and (self.range_m.min() < 0 or min(self.sigma_range_m.min(), self.sigma_bearing_rad.min()) <= 0):
            raise GraphError("ranges must be >= 0 and standard deviations > 0")
        same = np.flatnonzero(self.observer_agent == self.observed_agent)
        if same.size:
            raise GraphError(f"range-bearing row {int(same[0])}: an agent does not sight itself")

    def __len__(self) -> int:
        return len(self.stamps_ns)

    @classmethod
    def empty(cls) -> RangeBearing:
        z, f = np.zeros(0, dtype=np.int64), np.zeros(0)
        return cls(z, z, z, z, z, f, f, f, f, z, z)

    def check_against(self, graph: PoseGraph) -> None:
        """Every agent and vertex exists in ``graph``; raises :class:`GraphError` naming the row."""
        sizes = np.array([a.num_poses for a in graph.agents])
        for side in ("observer", "observed"):
            agent, index = getattr(self, f"{side}_agent"), getattr(self, f"{side}_index")
            bad = np.flatnonzero((agent < 0) | (agent >= len(sizes)))
            if bad.size:
                raise GraphError(f"range-bearing row {int(bad[0])}: unknown {side} agent {int(agent[bad[0]])}")
            bad = np.flatnonzero((index < 0) | (index >= sizes[agent]))
            if bad.size:
                k = int(bad[0])
                raise GraphError(
                    f"range-bearing row {k}: {side} vertex {int(index[k])} of agent "
                    f"{graph.agents[agent[k]].name}, which has {int(sizes[agent[k]])} poses"
                )


@dataclass(frozen=True, eq=False)
class Priors:
    """Pose priors (JRL's ``PriorFactorPose2``/``PriorFactorPose3``: COSMO-Bench anchors each robot at
    its first pose), as columns, one row per prior. ``agent`` is a 0-based position in
    :attr:`PoseGraph.agents`, ``index`` the pose within it; ``poses`` the prior's value in the graph's
    pose layout and ``information_upper`` its information in the edges' convention (the prior is a
    measurement of the pose from the world origin)."""

    kind: PoseKind
    agent: np.ndarray
    index: np.ndarray
    poses: np.ndarray
    information_upper: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "agent", _as_index(self.agent, "prior agent"))
        object.__setattr__(self, "index", _as_index(self.index, "prior index"))
        object.__setattr__(self, "poses", _as_rows(self.poses, self.kind.pose_width, "prior poses"))
        object.__setattr__(
            self,
            "information_upper",
            _as_rows(self.information_upper, self.kind.information_width, "prior information_upper"),
        )
        if not len(self.agent) == len(self.index) == len(self.poses) == len(self.information_upper):
            raise GraphError("prior columns must have matching lengths")
        _check_poses(self.poses, self.kind, "prior poses")

    def __len__(self) -> int:
        return len(self.agent)

    @classmethod
    def empty(cls, kind: PoseKind) -> Priors:
        z = np.zeros(0, dtype=np.int64)
        return cls(kind, z, z, np.zeros((0, kind.pose_width)), np.zeros((0, kind.information_width)))

    def check_against(self, graph: PoseGraph) -> None:
        """Every prior is on a pose of ``graph``, of its kind; raises :class:`GraphError` naming the row."""
        if self.kind is not graph.kind:
            raise GraphError(f"priors are {self.kind.value}, the graph {graph.kind.value}")
        sizes = np.array([a.num_poses for a in graph.agents])
        bad = _first_outside(self.agent, len(sizes))
        if bad is not None:
            raise GraphError(f"prior {bad}: unknown agent {int(self.agent[bad])}")
        bad = _first_outside(self.index, sizes[self.agent])
        if bad is not None:
            a = graph.agents[self.agent[bad]]
            raise GraphError(
                f"prior {bad}: vertex {int(self.index[bad])} of agent {a.name}, which has {a.num_poses} poses"
            )
