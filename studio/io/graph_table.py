"""What the readers of the distributed back-ends' formats share: a flat table of edges between
``(agent, vertex)`` pairs, turned into a :class:`~studio.core.model.PoseGraph`.

A JRL file, a folder of Symbol-keyed g2o files, DPGO's ``measurements.csv`` files and a split single
g2o all hold their measurements as one list of edges between robots' poses. :func:`assemble_graph`
sorts such a list into the studio's three kinds, the same way for every format:

* an edge inside one agent from vertex ``k`` to ``k + 1`` is that agent's odometry (the first such
  edge for each ``k``; the odometry is kept in vertex order);
* every other edge inside one agent is an intra-agent loop closure, in table order;
* an edge between two agents is an inter-agent loop closure, in table order.

:func:`dead_reckoning` gives an initial estimate to graphs that have none (files of edges only):
the poses composed along the edges from vertex 0, breadth first. Pure columns, no I/O.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from studio.core.errors import FormatError, GraphError
from studio.core.geometry import upper_to_matrix
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind

__all__ = [
    "EdgeTable",
    "AgentPoses",
    "assemble_graph",
    "dead_reckoning",
    "graph_edge_table",
    "information_matrix",
    "matrix_to_upper",
]


@dataclass(frozen=True, eq=False)
class EdgeTable:
    """Edges between ``(agent, vertex)`` pairs: agents 0-based in the graph's order, vertices
    0-based within their agent; measurements and information as in :mod:`studio.core.model`."""

    kind: PoseKind
    from_agent: np.ndarray
    from_index: np.ndarray
    to_agent: np.ndarray
    to_index: np.ndarray
    measurements: np.ndarray
    information_upper: np.ndarray

    def __len__(self) -> int:
        return len(self.from_agent)

    def rows(self) -> np.ndarray:
        """``(n, 4)`` int64 rows ``agent_from vertex_from agent_to vertex_to``."""
        return np.stack([self.from_agent, self.from_index, self.to_agent, self.to_index], axis=1).astype(np.int64)


@dataclass(frozen=True, eq=False)
class AgentPoses:
    """One agent's poses as a reader found them; ``initial=None``: dead reckoning."""

    name: str
    stamps_ns: np.ndarray
    initial: np.ndarray | None
    ground_truth: np.ndarray | None = None


def graph_edge_table(graph: PoseGraph) -> EdgeTable:
    """Every edge of ``graph`` in one table: each agent's odometry and loop closures in agent order,
    then the inter-agent loop closures (the order the studio's writers use)."""
    kind = graph.kind
    parts = []
    for k, a in enumerate(graph.agents):
        for e in (a.odometry, a.loop_closures):
            col = np.full(len(e), k, dtype=np.int64)
            parts.append((col, e.from_index, col, e.to_index, e.measurements, e.information_upper))
    i = graph.inter
    parts.append((i.from_agent, i.from_index, i.to_agent, i.to_index, i.measurements, i.information_upper))
    cols = [np.concatenate([p[c] for p in parts]) for c in range(6)]
    return EdgeTable(kind, cols[0], cols[1], cols[2], cols[3], cols[4].reshape(-1, kind.pose_width), cols[5])


def information_matrix(kind: PoseKind, upper: np.ndarray) -> np.ndarray:
    """``(n, d, d)`` symmetric information matrices from their upper triangles."""
    return upper_to_matrix(upper, 3 if kind is PoseKind.SE2 else 6)


def matrix_to_upper(matrices: np.ndarray) -> np.ndarray:
    """The upper triangles (row by row) of ``(n, d, d)`` matrices, symmetrised first."""
    d = matrices.shape[-1]
    sym = 0.5 * (matrices + np.swapaxes(matrices, -1, -2))
    rows, cols = np.triu_indices(d)
    return np.ascontiguousarray(sym[:, rows, cols])


def _odometry_mask(table: EdgeTable) -> np.ndarray:
    same = table.from_agent == table.to_agent
    step = same & (table.to_index == table.from_index + 1)
    mask = np.zeros(len(table), dtype=bool)
    if step.any():
        rows = np.flatnonzero(step)
        keys = table.from_agent[rows] * (1 << 40) + table.from_index[rows]
        _, first = np.unique(keys, return_index=True)
        mask[rows[first]] = True
    return mask


def assemble_graph(
    agents: Sequence[AgentPoses], table: EdgeTable, *, where: str, metadata: dict[str, Any] | None = None
) -> PoseGraph:
    """The :class:`PoseGraph` of ``agents`` and the edges of ``table`` (see the module doc); a broken
    invariant is a :class:`FormatError` naming ``where`` (the file or folder read)."""
    kind = table.kind
    odo = _odometry_mask(table)
    same = table.from_agent == table.to_agent
    out = []
    for k, a in enumerate(agents):
        mine = table.from_agent == k
        o = np.flatnonzero(odo & mine)
        o = o[np.argsort(table.from_index[o], kind="stable")]
        lc = np.flatnonzero(same & ~odo & mine)
        initial = a.initial
        n = len(a.stamps_ns)
        if initial is None:
            inside = np.flatnonzero(same & mine)
            initial = dead_reckoning(
                kind, n, table.from_index[inside], table.to_index[inside], table.measurements[inside], where=a.name
            )

        def edges(rows: np.ndarray) -> Edges:
            return Edges(
                kind,
                table.from_index[rows],
                table.to_index[rows],
                table.measurements[rows],
                table.information_upper[rows],
            )

        try:
            out.append(AgentGraph(a.name, kind, a.stamps_ns, initial, a.ground_truth, edges(o), edges(lc)))
        except GraphError as err:
            raise FormatError(f"{where}: {err}") from None
    inter = np.flatnonzero(~same)
    try:
        return PoseGraph(
            kind,
            tuple(out),
            InterAgentEdges(
                kind,
                table.from_agent[inter],
                table.from_index[inter],
                table.to_agent[inter],
                table.to_index[inter],
                table.measurements[inter],
                table.information_upper[inter],
            ),
            dict(metadata or {}),
        )
    except GraphError as err:
        raise FormatError(f"{where}: {err}") from None


def _compose(kind: PoseKind, a: list[float], z: list[float], inverse: bool) -> list[float]:
    """``a * z`` (or ``a * z^-1``) for one SE(2) ``[x, y, theta]`` or SE(3) ``[x y z qx qy qz qw]`` pose."""
    if kind is PoseKind.SE2:
        x, y, th = a
        dx, dy, dth = z
        if inverse:
            c, s = math.cos(dth), math.sin(dth)
            dx, dy, dth = -(c * dx + s * dy), -(-s * dx + c * dy), -dth
        c, s = math.cos(th), math.sin(th)
        t = th + dth
        return [x + c * dx - s * dy, y + s * dx + c * dy, math.atan2(math.sin(t), math.cos(t))]
    px, py, pz, qx, qy, qz, qw = a
    tx, ty, tz, bx, by, bz, bw = z
    if inverse:  # z^-1 = (-R^T t, q*)
        bx, by, bz = -bx, -by, -bz
        tx, ty, tz = _rotate(bx, by, bz, bw, -tx, -ty, -tz)
    rx, ry, rz = _rotate(qx, qy, qz, qw, tx, ty, tz)
    cx = qw * bx + qx * bw + qy * bz - qz * by
    cy = qw * by - qx * bz + qy * bw + qz * bx
    cz = qw * bz + qx * by - qy * bx + qz * bw
    cw = qw * bw - qx * bx - qy * by - qz * bz
    norm = math.sqrt(cx * cx + cy * cy + cz * cz + cw * cw)
    return [px + rx, py + ry, pz + rz, cx / norm, cy / norm, cz / norm, cw / norm]


def _rotate(qx: float, qy: float, qz: float, qw: float, vx: float, vy: float, vz: float) -> tuple[float, float, float]:
    """``v`` rotated by the unit quaternion ``q`` (``v + 2w (u x v) + 2 u x (u x v)``)."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (
        vx + qw * tx + (qy * tz - qz * ty),
        vy + qw * ty + (qz * tx - qx * tz),
        vz + qw * tz + (qx * ty - qy * tx),
    )


def dead_reckoning(
    kind: PoseKind, n: int, from_index: np.ndarray, to_index: np.ndarray, measurements: np.ndarray, *, where: str
) -> np.ndarray:
    """Poses composed along the edges from vertex 0 (at the origin), breadth first, the edges in
    table order; every vertex must be reached."""
    adjacency: list[list[tuple[int, int, bool]]] = [[] for _ in range(n)]
    for e, (i, j) in enumerate(zip(from_index.tolist(), to_index.tolist())):
        adjacency[i].append((j, e, False))
        adjacency[j].append((i, e, True))
    identity = [0.0, 0.0, 0.0] if kind is PoseKind.SE2 else [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    poses: list[list[float] | None] = [None] * n
    meas = measurements.tolist()
    if n:
        poses[0] = identity
    queue = deque([0] if n else [])
    while queue:
        i = queue.popleft()
        pi = poses[i]
        assert pi is not None
        for j, e, inverse in adjacency[i]:
            if poses[j] is None:
                poses[j] = _compose(kind, pi, meas[e], inverse)
                queue.append(j)
    missing = [k for k, p in enumerate(poses) if p is None]
    if missing:
        raise FormatError(
            f"{where}: {len(missing)} poses (the first: vertex {missing[0]}) are not connected to vertex 0 "
            "by any edge, so no initial estimate can be composed for them; give their vertices"
        )
    return np.array(poses, dtype=np.float64).reshape(n, kind.pose_width)
