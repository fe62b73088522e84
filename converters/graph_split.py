"""Split a single-robot pose graph into robots (``studio convert g2o FILE --split N --partition P``).

The graph is the one of a single g2o file (``converters/g2o.py``): vertices ``0..n-1`` (its ids in
increasing order), their stamps, initial estimate and ground truth where there is one, and its edges.
A partition gives each robot its vertices:

* ``contiguous``: DPGO's split (``examples/MultiRobotExample.cpp``): robot ``r`` of ``R`` holds the
  ids ``[r * floor(n/R), (r+1) * floor(n/R))``, the last robot the rest;
* ``metis``: METIS (``pymetis.part_graph``) on the undirected graph of the edges: parts of balanced
  size with the fewest cut edges; robots numbered in the order of their first vertex;
* ``time``: windows of equal duration over the stamps, as ``--split`` of a trajectory source cuts
  them. With ``overlap_s`` consecutive windows overlap: the poses of an overlap belong to both
  robots, each robot with its own copy, and an edge whose two ends lie in a robot's window is that
  robot's (so the measurements of an overlap are in both robots: two robots that drove the same
  stretch with the same odometry).

Every other edge joins two robots (an inter-robot loop closure, from the last robot holding each
end). Each robot's vertices keep their order; within a robot an edge ``k -> k+1`` is odometry.
A split where a robot has no poses, or a robot is not connected to the others by an inter-robot edge,
is refused naming the file: such a graph has no common frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from studio.converters.options import GROUND_TRUTH_CHOICES, PARTITIONS, GraphImportOptions
from studio.converters.transforms import time_windows
from studio.core.errors import ConfigError, FormatError
from studio.core.model import PoseGraph, PoseKind, Priors, RangeBearing
from studio.io.dpgo import contiguous_split
from studio.io.graph_table import AgentPoses, EdgeTable, assemble_graph

__all__ = [
    "SingleGraph",
    "PARTITIONS",
    "GROUND_TRUTH_CHOICES",
    "GraphImportOptions",
    "partition_vertices",
    "split_graph",
    "ImportedGraph",
    "graph_trajectories",
    "outliers_beside",
]


@dataclass(frozen=True, eq=False)
class ImportedGraph:
    """What a graph source reads: the graph, its labelled outliers (``(k, 4)`` rows
    ``agent_from vertex_from agent_to vertex_to``, 0-based agents), its range-bearing sightings
    (JRL's ``BearingRangeFactorPose2``), its pose priors (JRL's ``PriorFactorPose2/3``) and its
    potential outliers (JRL's ``potential_outlier_factors``, rows as ``outliers``); None where the
    source has none."""

    graph: PoseGraph
    outliers: np.ndarray
    range_bearing: RangeBearing | None = None
    priors: Priors | None = None
    potential_outliers: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class SingleGraph:
    """One robot's graph as a single g2o file holds it (vertices renumbered ``0..n-1``)."""

    kind: PoseKind
    stamps_ns: np.ndarray
    initial: np.ndarray
    ground_truth: np.ndarray | None
    from_index: np.ndarray
    to_index: np.ndarray
    measurements: np.ndarray
    information_upper: np.ndarray
    where: str
    vertex_ids: np.ndarray | None = None
    """The file's own ids of the poses (increasing), where the graph came from a file."""
    anchor: int = 0
    """The pose held fixed: the file's first ``FIX`` line, else the first pose."""

    @property
    def num_poses(self) -> int:
        return len(self.stamps_ns)


def _metis(graph: SingleGraph, parts: int) -> np.ndarray:
    try:
        import pymetis
    except ImportError:
        raise ConfigError("--partition metis needs pymetis>=2025.2 (pip install pymetis)") from None
    n = graph.num_poses
    i, j = graph.from_index, graph.to_index
    keep = i != j
    pairs = np.unique(np.sort(np.stack([i[keep], j[keep]], axis=1), axis=1), axis=0)
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.lexsort((dst, src))
    src, dst = src[order], dst[order]
    xadj = np.zeros(n + 1, dtype=np.int64)
    np.add.at(xadj, src + 1, 1)
    xadj = np.cumsum(xadj)
    # a fixed seed: the same file and options give the same robots
    _, membership = pymetis.part_graph(
        parts, adjacency=pymetis.CSRAdjacency(xadj.tolist(), dst.tolist()), options=pymetis.Options(seed=0)
    )
    part = np.asarray(membership, dtype=np.int64)
    # robots in the order of their first vertex
    firsts = {p: int(np.flatnonzero(part == p)[0]) for p in np.unique(part).tolist()}
    rank = {p: r for r, p in enumerate(sorted(firsts, key=firsts.__getitem__))}
    return np.array([rank[p] for p in part.tolist()], dtype=np.int64)


def partition_vertices(graph: SingleGraph, parts: int, partition: str, overlap_s: float = 0.0) -> list[np.ndarray]:
    """Each robot's vertices (sorted ids into the single graph)."""
    n = graph.num_poses
    if partition not in PARTITIONS:
        raise ConfigError(f"--partition: expected one of {', '.join(PARTITIONS)}, got {partition!r}")
    if isinstance(parts, bool) or not isinstance(parts, int) or parts < 2:
        raise ConfigError(f"--split: expected an integer of at least 2, got {parts!r}")
    if parts > n:
        raise FormatError(f"{graph.where}: --split {parts} is more robots than the graph's {n} poses")
    if overlap_s and partition != "time":
        raise ConfigError("--overlap: only --partition time has overlapping windows")
    if not overlap_s >= 0:
        raise ConfigError(f"--overlap: expected a non-negative number of seconds, got {overlap_s!r}")
    if partition == "contiguous":
        robot = contiguous_split(n, parts)
    elif partition == "metis":
        robot = _metis(graph, parts)
    else:
        windows = time_windows(graph.stamps_ns, parts, overlap_s, graph.where, label="--overlap")
        out = [np.flatnonzero(sel) for sel in windows]
        return _checked(graph, out, partition)
    return _checked(graph, [np.flatnonzero(robot == r) for r in range(parts)], partition)


def _checked(graph: SingleGraph, verts: list[np.ndarray], partition: str) -> list[np.ndarray]:
    for r, v in enumerate(verts):
        if not len(v):
            raise FormatError(
                f"{graph.where}: --partition {partition} leaves robot {r + 1} of {len(verts)} without poses"
            )
    return verts


def split_graph(graph: SingleGraph, verts: Sequence[np.ndarray], names: Sequence[str]) -> PoseGraph:
    """The multi-robot graph of ``graph`` with robot ``r`` holding ``verts[r]`` (see the module doc)."""
    n = graph.num_poses
    robots = len(verts)
    member = np.zeros((robots, n), dtype=bool)
    local = np.full((robots, n), -1, dtype=np.int64)
    last = np.full(n, -1, dtype=np.int64)
    for r, v in enumerate(verts):
        member[r, v] = True
        local[r, v] = np.arange(len(v))
        last[v] = r
    i, j = graph.from_index, graph.to_index
    cols: list[list[np.ndarray]] = [[] for _ in range(5)]
    inside_any = np.zeros(len(i), dtype=bool)
    for r in range(robots):
        inside = member[r, i] & member[r, j]
        inside_any |= inside
        rows = np.flatnonzero(inside)
        full = np.full(len(rows), r, dtype=np.int64)
        for c, v in enumerate((full, local[r, i[rows]], full, local[r, j[rows]], rows)):
            cols[c].append(v)
    rows = np.flatnonzero(~inside_any)
    ra, rb = last[i[rows]], last[j[rows]]
    for c, v in enumerate((ra, local[ra, i[rows]], rb, local[rb, j[rows]], rows)):
        cols[c].append(v)
    fa, fi, ta, ti, src = (np.concatenate(c) for c in cols)
    # every robot connected to the others
    inter = fa != ta
    if robots > 1:
        seen = {0}
        frontier = [0]
        links = np.unique(np.stack([fa[inter], ta[inter]], axis=1), axis=0).tolist() if inter.any() else []
        neighbours: dict[int, set[int]] = {r: set() for r in range(robots)}
        for a, b in links:
            neighbours[a].add(b)
            neighbours[b].add(a)
        while frontier:
            r = frontier.pop()
            for q in neighbours[r] - seen:
                seen.add(q)
                frontier.append(q)
        if len(seen) != robots:
            lonely = min(set(range(robots)) - seen)
            raise FormatError(
                f"{graph.where}: disconnected split: robot {lonely + 1} of {robots} shares no edge with robot 1's "
                "group, so the robots have no common frame (use fewer robots, another partition, or no --overlap)"
            )
    agents = []
    for r, v in enumerate(verts):
        agents.append(
            AgentPoses(
                names[r],
                graph.stamps_ns[v],
                graph.initial[v],
                graph.ground_truth[v] if graph.ground_truth is not None else None,
            )
        )
    table = EdgeTable(graph.kind, fa, fi, ta, ti, graph.measurements[src], graph.information_upper[src])
    return assemble_graph(agents, table, where=graph.where, metadata={"source": graph.where})


def graph_trajectories(graph: PoseGraph, where: str) -> list:
    """The agents' ground truth as trajectories (what ``convert()`` builds new measurements along)."""
    from studio.core.trajectory import Trajectory

    out = []
    for a in graph.agents:
        truth = a.se3_poses(ground_truth=True)
        if truth is None:
            raise FormatError(f"{where}: agent {a.name} has no ground truth to build measurements along")
        out.append(Trajectory.from_poses(a.name, a.stamps_ns, truth, where))
    return out


def outliers_beside(folder: Path, graph: PoseGraph) -> np.ndarray:
    """The labelled outliers of ``folder/outliers.txt`` (the studio's exports write it beside formats
    that have no place for them), checked against ``graph``; none without the file."""
    from studio.io.graph_table import graph_edge_table
    from studio.io.outliers_txt import read_outlier_kinds

    path = folder / "outliers.txt"
    if not path.is_file():
        return np.zeros((0, 4), dtype=np.int64)
    rows, _ = read_outlier_kinds(path)
    have = {tuple(r) for r in graph_edge_table(graph).rows().tolist()}
    for k, r in enumerate(rows.tolist()):
        if tuple(r) not in have:
            raise FormatError(
                f"{path}: outlier {k + 1} ({r[0] + 1} {r[1]} {r[2] + 1} {r[3]}) names no edge of the graph"
            )
    return rows
