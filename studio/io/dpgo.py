"""DPGO's inputs (mit-acl/dpgo): the single g2o its examples read and its logger's ``measurements.csv``.

* ``read_g2o_file`` (``src/DPGO_utils.cpp``) reads ``EDGE_SE2`` and ``EDGE_SE3:QUAT`` lines, skips
  ``VERTEX_*`` lines and stops on any other token (dpgo#3: ``FIX``); it keeps no information matrix
  but two precisions per edge, computed from its blocks (:func:`tau_kappa`)::

      SE(2): tau = 2 / tr(I_tt^-1),  kappa = I_33
      SE(3): tau = 3 / tr(I_tt^-1),  kappa = 3 / (2 tr(I_rr^-1))

  ``examples/MultiRobotExample.cpp`` gives robot ``r`` of ``R`` the ids
  ``[r * floor(n/R), (r+1) * floor(n/R))``, the last robot the rest (:func:`contiguous_split`).
  The studio writes the ids ``0..n-1`` in robot order, so that split gives back the studio's robots
  exactly when all robots but the last have ``floor(n/R)`` poses.
* ``PGOLogger::logMeasurements`` (``src/PGOLogger.cpp``) writes 3D measurements as CSV with the header
  :data:`CSV_HEADER`; robots and poses are 0-based, the quaternion comes first, ``is_known_inlier``
  is 1 for odometry. The studio writes one file per robot (``robotR/measurements.csv``): its odometry,
  its loop closures and every inter-robot loop closure it takes part in (in both robots' files), the
  numbers with ``%.17g``; planar graphs are written lifted to 3D, as the logger writes only 3D.

Reading a CSV gives back isotropic information, the only kind these files hold:
``tau * I`` on the translation and ``2 kappa * I`` on the quaternion's vector part (g2o's convention,
for which DPGO's rule gives back ``kappa``).
"""

from __future__ import annotations

import io
import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.core.errors import FormatError
from studio.core.model import PoseGraph, PoseKind
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE, NS_PER_S
from studio.io.g2o import G2oDocument, _open_text, write_g2o
from studio.io.graph_table import AgentPoses, EdgeTable, assemble_graph, graph_edge_table, information_matrix
from studio.io.textfmt import float_columns, int_column, join_array, literal

__all__ = [
    "CSV_HEADER",
    "tau_kappa",
    "contiguous_split",
    "dpgo_g2o_document",
    "write_measurements_csv",
    "write_dpgo_csv_folder",
    "read_measurements_csv_files",
    "isotropic_information",
]

CSV_HEADER = "robot_src,pose_src,robot_dst,pose_dst,qx,qy,qz,qw,tx,ty,tz,kappa,tau,is_known_inlier,weight"


def tau_kappa(kind: PoseKind, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DPGO's isotropic precisions of each edge (see the module doc)."""
    info = information_matrix(kind, upper)
    d = 2 if kind is PoseKind.SE2 else 3
    tt = info[:, :d, :d]
    tau = d / np.trace(np.linalg.inv(tt), axis1=1, axis2=2)
    if kind is PoseKind.SE2:
        kappa = info[:, 2, 2].copy()
    else:
        kappa = 3.0 / (2.0 * np.trace(np.linalg.inv(info[:, 3:, 3:]), axis1=1, axis2=2))
    return tau, kappa


def isotropic_information(kind: PoseKind, tau: np.ndarray, kappa: np.ndarray) -> np.ndarray:
    """Information upper triangles whose DPGO precisions are ``tau`` and ``kappa``."""
    n = len(tau)
    if kind is PoseKind.SE2:
        out = np.zeros((n, 6))
        out[:, 0] = out[:, 3] = tau
        out[:, 5] = kappa
        return out
    out = np.zeros((n, 21))
    diag = np.cumsum([0, 6, 5, 4, 3, 2])
    for k in range(3):
        out[:, diag[k]] = tau
        out[:, diag[k + 3]] = 2.0 * kappa
    return out


def contiguous_split(n: int, robots: int) -> np.ndarray:
    """The robot of each id ``0..n-1`` under DPGO's split (``MultiRobotExample.cpp``)."""
    per = n // robots
    return np.minimum(np.arange(n) // max(per, 1), robots - 1).astype(np.int64)


def dpgo_g2o_document(graph: PoseGraph) -> G2oDocument:
    """Every edge of ``graph`` with the ids ``offset_r + i`` (robots in order), no vertices."""
    table = graph_edge_table(graph)
    starts = np.cumsum([0] + [a.num_poses for a in graph.agents])
    return G2oDocument(
        graph.kind,
        np.zeros(0, dtype=np.int64),
        np.zeros((0, graph.kind.pose_width)),
        starts[table.from_agent] + table.from_index,
        starts[table.to_agent] + table.to_index,
        table.measurements,
        table.information_upper,
    )


def _csv_bytes(table: EdgeTable, rows: np.ndarray, tau: np.ndarray, kappa: np.ndarray) -> bytes:
    inlier = (table.from_agent == table.to_agent) & (table.to_index == table.from_index + 1)
    if not len(rows):
        return (CSV_HEADER + "\n").encode("ascii")
    m = table.measurements[rows]
    nums = np.column_stack([m[:, 3:7], m[:, 0:3], kappa[rows], tau[rows]])
    cols = [
        int_column(table.from_agent[rows]),
        int_column(table.from_index[rows]),
        int_column(table.to_agent[rows]),
        int_column(table.to_index[rows]),
        *float_columns(nums, ["%.17g"] * 9),
        int_column(inlier[rows].astype(np.int64)),
        literal("1"),
    ]
    return (CSV_HEADER + "\n").encode("ascii") + join_array(cols, sep=",").tobytes()


def write_measurements_csv(path: PathLike, graph: PoseGraph, robot: int) -> None:
    """Robot ``robot``'s ``measurements.csv`` (see the module doc)."""
    write_dpgo_csv_folder(graph, Path(path).parent, robots=[robot], names={robot: Path(path).name})


def write_dpgo_csv_folder(
    graph: PoseGraph, folder: PathLike, *, robots: Sequence[int] | None = None, names: dict[int, str] | None = None
) -> list[str]:
    """``robotR/measurements.csv`` for every robot (or those of ``robots``) inside ``folder``."""
    folder = Path(folder)
    se3 = graph.to_se3()
    table = graph_edge_table(se3)
    tau, kappa = tau_kappa(PoseKind.SE3, table.information_upper)
    written = []
    for r in robots if robots is not None else range(len(graph.agents)):
        rows = np.flatnonzero((table.from_agent == r) | (table.to_agent == r))
        if names and r in names:
            target = folder / names[r]
        else:
            (folder / f"robot{r}").mkdir(exist_ok=True)
            target = folder / f"robot{r}" / "measurements.csv"
        with open(target, "wb") as f:
            f.write(_csv_bytes(table, rows, tau, kappa))
        written.append(str(target.relative_to(folder)))
    return written


def write_dpgo_g2o(path: PathLike, graph: PoseGraph) -> None:
    write_g2o(path, dpgo_g2o_document(graph))


def _lines(body: str) -> list[tuple[int, list[str]]]:
    return [(n, line.split(",")) for n, line in enumerate(body.split("\n"), start=2) if line.strip()]


def _locate_csv_error(body: str, name: str) -> None:
    """Raise the FormatError naming the first bad line of a CSV body (the slow path)."""
    for lineno, fields in _lines(body):
        if len(fields) != 15:
            raise FormatError(f"{name}:{lineno}: expected 15 comma-separated fields, found {len(fields)}")
        try:
            [int(v) for v in fields[:4]]
            [float(v) for v in fields[4:]]
        except ValueError:
            raise FormatError(f"{name}:{lineno}: a field is not a number") from None
    raise FormatError(f"{name}: not a DPGO measurements table")


def _check_csv_rows(table: np.ndarray, body: str, name: str) -> None:
    line_of = [n for n, _ in _lines(body)]

    def fail(k: int, what: str) -> None:
        raise FormatError(f"{name}:{line_of[k]}: {what}")

    bad = np.flatnonzero(~np.isfinite(table).all(axis=1))
    if bad.size:
        fail(int(bad[0]), "value is not finite")
    ids = table[:, :4]
    bad = np.flatnonzero((ids != np.round(ids)).any(axis=1) | (ids < 0).any(axis=1) | (ids >= 2**31).any(axis=1))
    if bad.size:
        fail(int(bad[0]), "robot and pose ids must be non-negative integers")
    norms = np.linalg.norm(table[:, 4:8], axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-6)
    if bad.size:
        fail(int(bad[0]), f"quaternion is not unit length (norm {norms[bad[0]]:.6g})")
    bad = np.flatnonzero((table[:, 11] <= 0) | (table[:, 12] <= 0))
    if bad.size:
        fail(int(bad[0]), "kappa and tau must be positive")
    bad = np.flatnonzero((np.abs(table[:, 8:11]) > MAX_MAGNITUDE).any(axis=1))
    if bad.size:  # the documented bound of every coordinate (studio.core.units)
        fail(int(bad[0]), f"translation {table[bad[0], 8:11].tolist()} is beyond {MAX_MAGNITUDE:g} m")


_ID_ROOM, _ID_SLACK = 16, 1024
"""Poses (and robots) a table of ``n`` measurements may name: at most ``16 n + 1024``."""


def _pose_counts(ra: np.ndarray, pa: np.ndarray, rb: np.ndarray, pb: np.ndarray, rows: int, where: str) -> np.ndarray:
    """Each robot's pose count (its largest id + 1), the ids bounded before anything is allocated
    from them (a pose id of 2,000,000,000 asked for 15 GiB). A whole dataset has a row per robot
    and n-1 odometry rows per robot of n poses; the bound leaves room for one robot's file alone
    (the others' poses seen only in its closures, refused later as not connected, saying so)."""
    limit = _ID_ROOM * rows + _ID_SLACK
    n_robots = int(max(ra.max(), rb.max())) + 1
    if n_robots > limit:
        raise FormatError(f"{where}: robot id {n_robots - 1} with only {rows} measurements (ids count from 0)")
    sizes = np.zeros(n_robots, dtype=np.int64)
    np.maximum.at(sizes, ra, pa + 1)
    np.maximum.at(sizes, rb, pb + 1)
    if int(sizes.sum()) > limit:
        r = int(np.argmax(sizes))
        raise FormatError(
            f"{where}: robot {r} pose {int(sizes[r]) - 1}: ids far beyond the {rows} measurements read "
            "(DPGO's pose ids count from 0, each pose joined to the next by odometry)"
        )
    return sizes


def read_measurements_csv_files(paths: Sequence[PathLike]) -> PoseGraph:
    """Read DPGO ``measurements.csv`` files (one per robot, or one for all) into a graph of
    ``robot0..robotR-1``: poses ``0..max`` per robot, the initial estimate by dead reckoning along
    the odometry, stamps the poses' indices in seconds. An edge in several files is taken once."""
    if not paths:
        raise FormatError("no measurements.csv files given")
    blocks = []
    # several robots' files: the folder holding them all (robotR/measurements.csv of one export)
    where = os.path.commonpath([str(Path(p).parent) for p in paths]) if len(paths) > 1 else str(paths[0])
    for p in paths:
        text, name = _open_text(p)
        first, _, body = text.partition("\n")
        if first.strip() != CSV_HEADER:
            got = first.strip()[:80] or "nothing"
            raise FormatError(f"{name}:1: expected DPGO's header {CSV_HEADER!r}, got {got!r}")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # an empty body is no rows, not a warning
                parsed = (
                    np.loadtxt(io.StringIO(body), delimiter=",", dtype=np.float64, ndmin=2) if body.strip() else None
                )
        except (ValueError, UserWarning):
            parsed = None
            _locate_csv_error(body, name)
        if parsed is None:
            continue
        if parsed.shape[1] != 15:
            _locate_csv_error(body, name)
        _check_csv_rows(parsed, body, name)
        blocks.append(parsed)
    if not blocks:
        many = f" in its {len(paths)} measurements.csv files" if len(paths) > 1 else ""
        raise FormatError(f"{where}: no measurements{many} (only DPGO's header)")
    allrows = np.concatenate(blocks)
    ids = allrows[:, :4].astype(np.int64)
    # a loop closure between two robots is in both robots' files: keep its first row
    inter = ids[:, 0] != ids[:, 2]
    keep = np.ones(len(ids), dtype=bool)
    if inter.any():
        rows = np.flatnonzero(inter)
        _, first_rows = np.unique(ids[rows], axis=0, return_index=True)
        keep[rows] = False
        keep[rows[first_rows]] = True
    allrows, ids = allrows[keep], ids[keep]
    ra, pa, rb, pb = ids.T
    quat = allrows[:, 4:8]
    trans = allrows[:, 8:11]
    kappa = allrows[:, 11]
    tau = allrows[:, 12]
    sizes = _pose_counts(ra, pa, rb, pb, len(ids), where)
    n_robots = len(sizes)
    if np.any(sizes == 0):
        raise FormatError(f"{where}: robot {int(np.flatnonzero(sizes == 0)[0])} has no measurements")
    agents = [
        AgentPoses(f"robot{r}", np.arange(int(sizes[r]), dtype=np.int64) * NS_PER_S, None) for r in range(n_robots)
    ]
    table = EdgeTable(
        PoseKind.SE3,
        ra,
        pa,
        rb,
        pb,
        np.hstack([trans, quat]),
        isotropic_information(PoseKind.SE3, tau, kappa),
    )
    return assemble_graph(agents, table, where=where, metadata={"source": where})
