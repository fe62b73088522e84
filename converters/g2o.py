"""Any single g2o file (the single-robot benchmarks: M3500, INTEL, CSAIL, sphere2500, KITTI...), as
one robot or split into robots (:mod:`studio.converters.graph_split`).

This is the one reader of a single g2o file: ``studio convert g2o``, ``solve``, ``check`` and
``replay`` all read it through :func:`read_single_g2o`. The file's vertex ids are renumbered
``0..n-1`` in increasing order. A file of edges only (SE-Sync's CSAIL, manhattan, KITTI files) gets
its initial estimate composed along a breadth-first spanning tree of all its edges from the first
id, so a missing odometry link (ais2klinik lacks 7289->7290) is bridged by the loop closures.
Repeated edges are kept, each a measurement. ``FIX`` names the pose held fixed (the gauge).
Quaternions within 1e-5 of unit length are normalised (one warning with the count). Records the
studio does not read (``EDGE_SE2_XY``, ``VERTEX_XY``...) are counted in one warning and skipped. The
ground truth is ``<stem>_GT.tum`` beside the file where there is one (its stamps are the poses'
stamps), or with ``ground_truth="vertices"`` the file's own vertices (the initial estimate is then
composed along the edges); otherwise the graph has none, and the stamps are the indices in seconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.converters.graph_split import (
    GraphImportOptions,
    ImportedGraph,
    SingleGraph,
    graph_trajectories,
    partition_vertices,
    split_graph,
)
from studio.converters.names import safe_agent_name
from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import se3_poses_to_planar
from studio.core.model import PoseKind
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import G2oDocument, normalised_note, read_g2o
from studio.io.graph_table import AgentPoses, EdgeTable, assemble_graph, dead_reckoning
from studio.io.tum import read_tum

__all__ = ["read_single_g2o", "read_g2o_graph", "read_g2o_trajectories", "truth_file"]


def truth_file(path: Path) -> Path | None:
    """``<stem>_GT.tum`` (or ``_gt.tum``) beside ``path``, where there is one."""
    for suffix in ("_GT.tum", "_gt.tum"):
        p = path.with_name(path.stem + suffix)
        if p.is_file():
            return p
    return None


def _read_doc(path: Path, warn: Warn | None) -> G2oDocument:
    """The file's records, its warnings given once each (skipped records, normalised quaternions)."""
    unknown: dict[str, int] = {}
    doc = read_g2o(path, unknown=unknown, dangling=True)
    if warn is not None:
        if unknown:
            warn(
                f"{path}: skipped records the studio does not read: "
                + ", ".join(f"{n} {tag}" for tag, n in sorted(unknown.items()))
            )
        if doc.normalised_quaternions:
            warn(normalised_note(str(path), doc.normalised_quaternions))
    if len(doc.vertex_ids):
        if len(doc.edge_from) and not np.isin(np.concatenate([doc.edge_from, doc.edge_to]), doc.vertex_ids).all():
            read_g2o(path, unknown={})  # names the line of the first edge to an unknown vertex
    elif not len(doc.edge_from):
        raise FormatError(f"{path}: no vertices and no edges")
    return doc


def read_single_g2o(path: PathLike, *, ground_truth: str = "auto", warn: Warn | None = None) -> SingleGraph:
    """One g2o file as one robot's graph (see the module doc)."""
    path = Path(path)
    doc = _read_doc(path, warn)
    kind = doc.kind
    has_vertices = len(doc.vertex_ids) > 0
    ids = doc.vertex_ids if has_vertices else np.unique(np.concatenate([doc.edge_from, doc.edge_to]))
    order = np.argsort(ids, kind="stable")
    sorted_ids = ids[order]
    n = len(sorted_ids)
    fi = np.searchsorted(sorted_ids, doc.edge_from)
    ti = np.searchsorted(sorted_ids, doc.edge_to)
    anchor = int(np.searchsorted(sorted_ids, doc.fixed_ids[0])) if len(doc.fixed_ids) else 0
    where = str(path)
    truth_path = truth_file(path) if ground_truth == "auto" else None
    stamps = np.arange(n, dtype=np.int64) * NS_PER_S
    truth = None
    if truth_path is not None:
        traj = read_tum(truth_path)
        if len(traj) != n:
            raise FormatError(f"{truth_path}: {len(traj)} poses for the {n} vertices of {path.name}")
        stamps = traj.stamps_ns
        truth = traj.poses_xyz_quat_xyzw
        if kind is PoseKind.SE2:
            truth = se3_poses_to_planar(truth)
    if has_vertices and ground_truth == "vertices":
        truth = doc.vertex_poses[order]
    if has_vertices and ground_truth != "vertices":
        initial = doc.vertex_poses[order]
    else:
        if ground_truth == "vertices" and not has_vertices:
            raise ConfigError(f"{path}: --ground-truth vertices needs a file with vertices")
        initial = dead_reckoning(kind, n, fi, ti, doc.edge_measurements, where=where)
    return SingleGraph(
        kind,
        stamps,
        initial,
        truth,
        fi,
        ti,
        doc.edge_measurements,
        doc.edge_information_upper,
        where,
        sorted_ids,
        anchor,
    )


def read_g2o_graph(
    inputs: Sequence[PathLike], *, warn: Warn | None = None, options: GraphImportOptions | None = None
) -> ImportedGraph:
    """``studio convert g2o FILE.g2o [--split N --partition P]``."""
    options = options or GraphImportOptions()
    if len(inputs) != 1:
        raise ConfigError(f"studio convert g2o takes one .g2o file, got {len(inputs)} inputs")
    single = read_single_g2o(inputs[0], ground_truth=options.ground_truth, warn=warn)
    if options.split:
        verts = partition_vertices(single, options.split, options.partition, options.overlap_s)
        graph = split_graph(single, verts, [f"robot{r}" for r in range(len(verts))])
    else:
        if options.overlap_s:
            raise ConfigError("--overlap: only with --split N --partition time")
        rows = np.zeros(len(single.from_index), dtype=np.int64)
        table = EdgeTable(
            single.kind,
            rows,
            single.from_index,
            rows,
            single.to_index,
            single.measurements,
            single.information_upper,
        )
        agent = AgentPoses(safe_agent_name(Path(inputs[0]).stem), single.stamps_ns, single.initial, single.ground_truth)
        graph = assemble_graph([agent], table, where=single.where, metadata={"source": single.where})
    return ImportedGraph(graph, np.zeros((0, 4), dtype=np.int64))


def read_g2o_trajectories(
    inputs: Sequence[PathLike], *, agents: Sequence[str] = (), warn: Warn | None = None, progress=None
) -> list[Trajectory]:
    """The ground truth of :func:`read_g2o_graph`'s robots (``ground_truth="auto"``)."""
    imported = read_g2o_graph(inputs, warn=warn)
    return graph_trajectories(imported.graph, str(inputs[0]))
