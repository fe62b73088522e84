"""``studio export`` as a library function: a multi-g2o dataset out in a distributed back-end's format.

The formats are the entries of :data:`studio.export_formats.EXPORT_FORMATS` (the one place an export
format is declared; the CLI's choices and help come from it; re-exported here):

* ``jrl``: one JRL file (``studio.io.jrl``) for JRL, MESA and COSMO-Bench tooling;
* ``dpgo``: a folder with ``NAME.g2o`` (edges only, ids ``0..n-1`` in robot order) for DPGO's
  examples, ``robotR/measurements.csv`` per robot in its logger's format (``studio.io.dpgo``) and
  ``robotR/robotR_GT.tum``;
* ``symbols``: a folder of Symbol-keyed g2o files, one per robot plus ``fullGraph.g2o``
  (``studio.io.symbol_g2o``), for DGS / distributed-mapper, Kimera-Multi and anything on
  ``gtsam.readG2o``.

Folder exports hold ``export.json``: the format, the source dataset, each agent's robot id and
Symbol character, and the warnings (what the format loses). Everything is written through
:func:`studio.io.atomic.staged_outputs`: nothing appears unless all of it was written, and an existing
output is replaced only with ``force``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from studio.core.errors import ConfigError, FormatError, GraphError
from studio.core.model import PoseGraph, PoseKind, Priors, RangeBearing
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.export_formats import EXPORT_FORMATS, ExportFormat
from studio.io.atomic import staged_outputs
from studio.io.dpgo import contiguous_split, write_dpgo_csv_folder, write_dpgo_g2o
from studio.io.graph_table import graph_edge_table, information_matrix
from studio.io.jrl import write_jrl
from studio.io.multig2o import read_multi_g2o
from studio.io.names import check_name_component
from studio.io.outliers_txt import POTENTIAL_OUTLIERS_NAME, read_outlier_kinds, write_outliers_txt
from studio.io.priors_txt import PRIORS_NAME, read_priors_txt
from studio.io.range_bearing import RANGE_BEARING_NAME, read_range_bearing
from studio.io.strict_json import dumps_strict
from studio.io.symbol_g2o import robot_prefix, write_symbol_g2o_folder
from studio.io.tum import write_tum

__all__ = [
    "ExportFormat",
    "EXPORT_FORMATS",
    "ExportResult",
    "DatasetExtras",
    "export_dataset",
    "read_dataset_outliers",
]

_EXPORT_FORMAT = "cslam-studio export 1"


@dataclass(frozen=True)
class ExportResult:
    format: str
    path: Path
    files: tuple[str, ...]
    """Files written, relative to ``path`` for folder exports."""
    warnings: tuple[str, ...] = field(default_factory=tuple)


@dataclass(frozen=True, eq=False)
class DatasetExtras:
    """What a dataset folder may hold beside its graph and ``outliers.txt``: range-bearing sightings
    (``range_bearing.txt``), pose priors (``priors.txt``) and potential outliers
    (``potential_outliers.txt``, edge rows); None where the folder has none or the format carries none."""

    range_bearing: RangeBearing | None = None
    priors: Priors | None = None
    potential_outliers: np.ndarray | None = None


def _write_jrl(
    graph: PoseGraph,
    target: Path,
    name: str,
    outliers: np.ndarray,
    warn: Callable[[str], None],
    extras: DatasetExtras,
) -> list[str]:
    sightings = extras.range_bearing
    if sightings is not None and len(sightings) and graph.kind is not PoseKind.SE2:
        warn(
            f"jrl: the {len(sightings)} range-bearing sightings (range_bearing.txt) are left out: the dataset has "
            "3D records and JRL's 3D bearing is a Unit3; convert with --planar to carry them as BearingRangeFactorPose2"
        )
        sightings = None
    write_jrl(
        target,
        graph,
        name=name,
        outliers=outliers,
        range_bearing=sightings,
        priors=extras.priors,
        potential_outliers=extras.potential_outliers,
    )
    return [target.name]


def _anisotropic(graph: PoseGraph) -> int:
    """How many edges have information that DPGO's tau/kappa do not keep (not isotropic per block)."""
    se3 = graph.to_se3()
    info = information_matrix(PoseKind.SE3, graph_edge_table(se3).information_upper)
    tt, rr = info[:, :3, :3], info[:, 3:, 3:]
    off = np.abs(info[:, :3, 3:]).max(axis=(1, 2)) if len(info) else np.zeros(0)
    iso = (
        np.all(np.isclose(tt, tt[:, :1, :1] * np.eye(3), rtol=1e-12, atol=0), axis=(1, 2))
        & np.all(np.isclose(rr, rr[:, :1, :1] * np.eye(3), rtol=1e-12, atol=0), axis=(1, 2))
        & (off == 0)
    )
    return int(np.count_nonzero(~iso))


def _write_dpgo(
    graph: PoseGraph,
    target: Path,
    name: str,
    outliers: np.ndarray,
    warn: Callable[[str], None],
    extras: DatasetExtras | None = None,
) -> list[str]:
    target.mkdir()
    files = [f"{name}.g2o"]
    write_dpgo_g2o(target / files[0], graph)
    files += write_dpgo_csv_folder(graph, target)
    for r, a in enumerate(graph.agents):
        truth = a.se3_poses(ground_truth=True)
        if truth is not None:
            rel = f"robot{r}/robot{r}_GT.tum"
            write_tum(target / rel, Trajectory.from_poses(a.name, a.stamps_ns, truth))
            files.append(rel)
    sizes = [a.num_poses for a in graph.agents]
    split = np.bincount(contiguous_split(sum(sizes), len(sizes)), minlength=len(sizes)).tolist()
    if split != sizes:
        warn(
            f"dpgo: the robots have {sizes} poses, but DPGO's contiguous split of {name}.g2o into {len(sizes)} "
            f"robots gives {split}: give DPGO the robots' measurements.csv files, not the single g2o"
        )
    lost = _anisotropic(graph)
    if lost:
        warn(
            f"dpgo: {lost} of {sum(graph.edge_counts().values())} edges have anisotropic information, which "
            "DPGO reduces to the isotropic tau and kappa (its rule, docs/formats.md)"
        )
    table = graph_edge_table(graph)
    starts = np.cumsum([0] + sizes)
    gi, gj = starts[table.from_agent] + table.from_index, starts[table.to_agent] + table.to_index
    inlier = np.count_nonzero((table.from_agent != table.to_agent) & (gj == gi + 1))
    if inlier:
        warn(f"dpgo: {inlier} inter-robot loop closures join ids i and i+1, which DPGO's g2o reader takes as odometry")
    files += _write_outliers(target, outliers)
    if graph.kind is PoseKind.SE2:
        warn("dpgo: measurements.csv holds 3D measurements only (DPGO's logger): the planar graph is written lifted")
    return files


def _write_symbols(
    graph: PoseGraph,
    target: Path,
    name: str,
    outliers: np.ndarray,
    warn: Callable[[str], None],
    extras: DatasetExtras | None = None,
) -> list[str]:
    target.mkdir()
    return write_symbol_g2o_folder(graph, target) + _write_outliers(target, outliers)


def _write_outliers(target: Path, outliers: np.ndarray) -> list[str]:
    """The labelled outliers beside a folder export (the formats have no place for them), in the
    studio's ``outliers.txt`` (agents 1-based: robot ``r`` is agent ``r + 1``)."""
    if not len(outliers):
        return []
    write_outliers_txt(target / "outliers.txt", outliers, ["labelled"] * len(outliers))
    return ["outliers.txt"]


def read_dataset_outliers(dataset: PathLike, graph: PoseGraph, name: str = "outliers.txt") -> np.ndarray:
    """The labelled outliers of a dataset folder (``outliers.txt``; ``name``: another file of its
    rows, ``potential_outliers.txt``), ``(k, 4)`` rows with 0-based agents; none when the dataset
    lists none. Rows naming no edge of ``graph`` are refused."""
    path = Path(dataset) / name
    if not path.is_file():
        return np.zeros((0, 4), dtype=np.int64)
    rows, _ = read_outlier_kinds(path)
    table = graph_edge_table(graph).rows()
    have = {tuple(r) for r in table.tolist()}
    for k, r in enumerate(rows.tolist()):
        if tuple(r) not in have:
            raise FormatError(f"{path}: row {k + 1} ({r[0] + 1} {r[1]} {r[2] + 1} {r[3]}) names no edge of the dataset")
    return rows


def _dataset_extras(dataset: Path, graph: PoseGraph) -> DatasetExtras:
    """The sightings, priors and potential outliers of the dataset folder, where it has them."""
    rb_path, priors_path = dataset / RANGE_BEARING_NAME, dataset / PRIORS_NAME
    potential = None
    if (dataset / POTENTIAL_OUTLIERS_NAME).is_file():
        potential = read_dataset_outliers(dataset, graph, POTENTIAL_OUTLIERS_NAME)
    return DatasetExtras(
        read_range_bearing(rb_path, graph) if rb_path.is_file() else None,
        read_priors_txt(priors_path, graph) if priors_path.is_file() else None,
        potential,
    )


def export_dataset(
    dataset: PathLike,
    out: PathLike,
    *,
    format: str,
    force: bool = False,
    name: str | None = None,
    warn: Callable[[str], None] | None = None,
) -> ExportResult:
    """Write the multi-g2o dataset ``dataset`` in ``format`` (a name of :data:`EXPORT_FORMATS`) to
    ``out`` (a file for ``jrl``, a folder otherwise). ``name`` (default: the dataset folder's name)
    names the dataset inside the files."""
    if format not in EXPORT_FORMATS:
        raise ConfigError(f"unknown export format {format!r} (known: {', '.join(EXPORT_FORMATS)})", option="format")
    spec = EXPORT_FORMATS[format]
    if name is not None:
        # the name becomes a file (``NAME.g2o``): ``../../DS/agent1/posegraph`` once replaced the input
        check_name_component(name, what="--name", option="name")
    dataset = Path(dataset)
    out = Path(out).absolute()
    if out.name in ("", ".", ".."):
        raise ConfigError(f"{out}: -o must name the {'folder' if spec.folder else 'file'} to write")
    graph = read_multi_g2o(dataset)
    outliers = read_dataset_outliers(dataset, graph)
    extras = _dataset_extras(dataset, graph)
    sightings = extras.range_bearing
    label = name or dataset.resolve().name
    warnings: list[str] = []

    def _warn(msg: str) -> None:
        warnings.append(msg)
        if warn is not None:
            warn(msg)

    if len(graph.agents) > 52:
        robot_prefix(len(graph.agents) - 1)  # raises: Symbol characters name 52 robots at most
    with staged_outputs(out.parent, [out.name], force=force, inputs=[dataset]) as staging:
        target = staging / out.name
        if sightings is not None and len(sightings) and not spec.sightings:
            _warn(
                f"{format}: the {len(sightings)} range-bearing sightings (range_bearing.txt) are left out: the format has none"
            )
        if extras.priors is not None and len(extras.priors) and not spec.priors:
            _warn(f"{format}: the {len(extras.priors)} pose priors (priors.txt) are left out: the format has none")
        carried = DatasetExtras(
            sightings if spec.sightings else None,
            extras.priors if spec.priors else None,
            extras.potential_outliers if spec.priors else None,
        )
        try:
            files = spec.write(graph, target, label, outliers, _warn, carried)
        except GraphError as err:
            raise FormatError(f"{dataset}: {err}") from None
        if spec.folder:
            meta = {
                "format": _EXPORT_FORMAT,
                "export": format,
                "dataset": label,
                "agents": [
                    {"name": a.name, "robot": k, "symbol": robot_prefix(k), "poses": a.num_poses}
                    for k, a in enumerate(graph.agents)
                ],
                "outliers": len(outliers),
                "warnings": warnings,
            }
            (target / "export.json").write_text(
                dumps_strict(meta, str(out / "export.json"), indent=2) + "\n", encoding="utf-8"
            )
            files.append("export.json")
    return ExportResult(format, out, tuple(files), tuple(warnings))
