"""``studio convert`` of a graph source (jrl, symbols, dpgo, g2o): the graph itself into a dataset.

A trajectory source gets synthetic measurements (:mod:`studio.convert`); a graph source already holds
its measurements, and they are written as they are::

    OUT/
    ├── agentK/posegraph.g2o, agentK/agentK_GT.tum   # 3D records (2D for planar graphs), %.17g
    ├── agents.json                                  # agentK -> the robots' names
    ├── inter_agent_lc.dat
    ├── outliers.txt                                 # the labelled outliers (JRL's outlier_factors)
    ├── potential_outliers.txt                       # JRL's potential_outlier_factors, if the file has them
    ├── priors.txt                                   # JRL's PriorFactorPose2/3, if any
    ├── range_bearing.txt                            # JRL's BearingRangeFactorPose2 sightings, if any
    ├── import.json                                  # source, inputs, options, counts, warnings
    └── OUT.rrd                                      # the recording (unless rrd=False)

so that ``studio record``, ``check``, ``solve`` and ``evaluate`` take it like any other dataset.
``split`` cuts a single-robot graph (``studio convert g2o``) into robots
(:mod:`studio.converters.graph_split`). Everything is staged and renamed into place; nothing is
written when an input is bad.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.convert_config import check_source_options
from studio.converters.graph_split import GraphImportOptions, ImportedGraph
from studio.converters.registry import check_inputs, get_source
from studio.core.errors import ConfigError, FormatError, OutputError
from studio.core.model import PoseGraph, PoseKind, RangeBearing
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE
from studio.io.atomic import check_not_overlapping, staged_outputs
from studio.io.multig2o import write_multi_g2o
from studio.io.outliers_txt import POTENTIAL_HEAD, POTENTIAL_OUTLIERS_NAME, write_outliers_txt
from studio.io.priors_txt import PRIORS_NAME, write_priors_txt
from studio.io.range_bearing import RANGE_BEARING_NAME, write_range_bearing
from studio.io.strict_json import dumps_strict
from studio.runtime.progress import Progress

__all__ = ["ImportResult", "import_graph", "graph_source_names", "IMPORT_NAME"]

IMPORT_NAME = "import.json"
_FORMAT = "studio-import/1"


@dataclass(frozen=True, eq=False)
class ImportResult:
    source: str
    dataset_dir: Path
    graph: PoseGraph
    outliers: np.ndarray
    warnings: tuple[str, ...]
    rrd_path: Path | None
    range_bearing: RangeBearing | None = None


def graph_source_names() -> list[str]:
    from studio.converters.registry import SOURCES

    return [name for name, src in SOURCES.items() if src.read_graph is not None]


def _check_magnitudes(graph: PoseGraph, where: str) -> None:
    """Every pose and measurement translation within the documented bound (``MAX_MAGNITUDE``,
    1e9 m), whichever reader made the graph: a measurement of 1e300 m was imported as data."""
    from studio.io.graph_table import graph_edge_table

    width = 2 if graph.kind is PoseKind.SE2 else 3
    table = graph_edge_table(graph)
    bad = np.flatnonzero((np.abs(table.measurements[:, :width]) > MAX_MAGNITUDE).any(axis=1))
    if bad.size:
        k = int(bad[0])
        a, i = graph.agents[table.from_agent[k]].name, int(table.from_index[k])
        b, j = graph.agents[table.to_agent[k]].name, int(table.to_index[k])
        raise FormatError(
            f"{where}: the measurement from {a} pose {i} to {b} pose {j} is beyond {MAX_MAGNITUDE:g} m "
            f"({table.measurements[k, :width].tolist()})"
        )
    for agent in graph.agents:
        for truth in (False, True):
            poses = agent.se3_poses(ground_truth=truth)
            far = np.zeros(0) if poses is None else np.flatnonzero((np.abs(poses[:, :3]) > MAX_MAGNITUDE).any(axis=1))
            if far.size:
                what = "ground-truth pose" if truth else "pose"
                raise FormatError(f"{where}: {agent.name} {what} {int(far[0])} lies beyond {MAX_MAGNITUDE:g} m")


def import_graph(
    source: str,
    inputs: Sequence[PathLike],
    out: PathLike,
    *,
    options: GraphImportOptions | None = None,
    force: bool = False,
    rrd: bool = True,
    warn: Callable[[str], None] | None = None,
    progress: Progress | None = None,
) -> ImportResult:
    """Read the graph source ``source`` (a name of ``converters.registry.SOURCES`` with a graph
    reader) and write its dataset folder ``out`` (see the module doc)."""
    options = options or GraphImportOptions()
    src = get_source(source)
    if src.read_graph is None:
        raise ConfigError(f"{source} is not a graph source (graph sources: {', '.join(graph_source_names())})")
    # an option set away from its default that this source's reader would ignore is refused
    unset = GraphImportOptions()
    changed = {k: v for k, v in asdict(options).items() if v != getattr(unset, k)}
    check_source_options(source, changed, synthesize=False)
    out = Path(out).absolute()
    if out.name in ("", ".", ".."):
        raise OutputError(f"{out}: -o must name the dataset folder itself")
    if (out.exists() or out.is_symlink()) and not force:
        raise OutputError(f"{out} already exists (use --force to overwrite)")
    paths = []
    for p in inputs:
        if not Path(p).exists():
            raise FormatError(f"{p}: no such file or folder")
        paths.append(str(Path(p).resolve()))
    check_inputs(source, paths, ())
    check_not_overlapping([out], paths)
    warnings: list[str] = []

    def _warn(msg: str) -> None:
        warnings.append(msg)
        if warn is not None:
            warn(msg)

    if progress:
        progress("reading", 0, 1, "inputs")
    with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
        try:
            imported = src.read_graph(paths, warn=_warn, options=options)
        except FloatingPointError as err:
            raise FormatError(
                f"{', '.join(Path(p).name for p in paths)}: numbers out of the finite range ({err})"
            ) from None
        except np.linalg.LinAlgError as err:
            raise FormatError(f"{', '.join(Path(p).name for p in paths)}: a singular matrix ({err})") from None
    graph, outliers, sightings = imported.graph, imported.outliers, imported.range_bearing
    _check_magnitudes(graph, ", ".join(Path(p).name for p in paths))
    meta = {
        "format": _FORMAT,
        "source": source,
        "inputs": [Path(p).name for p in paths],
        "options": asdict(options),
        "agents": [
            {"folder": f"agent{k + 1}", "name": a.name, "poses": a.num_poses} for k, a in enumerate(graph.agents)
        ],
        "counts": {
            **graph.edge_counts(),
            "outliers": len(outliers),
            **({"range_bearing": len(sightings)} if sightings is not None else {}),
            **({"priors": len(imported.priors)} if imported.priors is not None else {}),
            **(
                {"potential_outliers": len(imported.potential_outliers)}
                if imported.potential_outliers is not None
                else {}
            ),
        },
        "warnings": warnings,
    }
    with staged_outputs(out.parent, [out.name], force=force, inputs=paths) as staging:
        ds = staging / out.name
        ds.mkdir()
        _write_imported(ds, imported, meta, out, rrd, progress)
    rrd_path = out / f"{out.name}.rrd" if rrd else None
    return ImportResult(source, out, graph, outliers, tuple(warnings), rrd_path, sightings)


def _write_imported(
    ds: Path, imported: ImportedGraph, meta: dict[str, Any], out: Path, rrd: bool, progress: Progress | None
) -> None:
    """The dataset's files in the staged folder ``ds`` of ``out`` (see the module doc); ``meta``:
    import.json."""
    name = out.name
    graph, outliers, sightings = imported.graph, imported.outliers, imported.range_bearing
    write_multi_g2o(
        graph, ds, records="2d" if graph.kind is PoseKind.SE2 else "3d", precision="full", folder_names="agents"
    )
    write_outliers_txt(ds / "outliers.txt", outliers, [f"labelled in the {meta['source']} input"] * len(outliers))
    if sightings is not None:
        write_range_bearing(ds / RANGE_BEARING_NAME, sightings)
    if imported.priors is not None:
        write_priors_txt(ds / PRIORS_NAME, imported.priors)
    if imported.potential_outliers is not None:
        potential = imported.potential_outliers
        kinds = [f"potential in the {meta['source']} input"] * len(potential)
        write_outliers_txt(ds / POTENTIAL_OUTLIERS_NAME, potential, kinds, head=POTENTIAL_HEAD)
    (ds / IMPORT_NAME).write_text(dumps_strict(meta, str(out / IMPORT_NAME), indent=2) + "\n", encoding="utf-8")
    if rrd:
        from studio.recording.dataset import record_graph

        record_graph(
            graph,
            ds / f"{name}.rrd",
            name=name,
            config_json=json.dumps(meta, sort_keys=True),
            outliers=outliers,
            progress=progress,
            range_bearing=sightings,
        )
