"""The export formats of ``studio export``, by name: the one place an export format is declared (the
command line's ``--format`` choices and help come from :data:`EXPORT_FORMATS`).

Each entry names its writer by module and attribute (:class:`~studio.core.lazy.Lazy`), imported when
the format is used, so declaring the command line's options loads no writer and no numpy;
:mod:`studio.export` re-exports both names.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from studio.core.lazy import Lazy

if TYPE_CHECKING:
    import numpy as np

    from studio.core.model import PoseGraph
    from studio.export import DatasetExtras

__all__ = ["ExportFormat", "EXPORT_FORMATS"]


@dataclass(frozen=True)
class ExportFormat:
    """One export format: its help line, whether it writes a file or a folder, its writer
    ``write(graph, target, name, outliers, warn, extras) -> [files written]`` (``extras``: a
    :class:`studio.export.DatasetExtras` holding only what the format carries), whether it carries
    range-bearing sightings (``range_bearing.txt``) and whether it carries pose priors and potential
    outliers (``priors.txt``, ``potential_outliers.txt``); the others say they leave them out."""

    help: str
    folder: bool
    write: Callable[[PoseGraph, Path, str, np.ndarray, Callable[[str], None], DatasetExtras], list[str]]
    sightings: bool = False
    priors: bool = False


#: The export formats, by name.
EXPORT_FORMATS: dict[str, ExportFormat] = {
    "jrl": ExportFormat(
        "one JRL file (JRL, MESA, COSMO-Bench)",
        False,
        Lazy("studio.export", "_write_jrl"),
        sightings=True,
        priors=True,
    ),
    "dpgo": ExportFormat(
        "DPGO's single g2o and a measurements.csv per robot", True, Lazy("studio.export", "_write_dpgo")
    ),
    "symbols": ExportFormat(
        "one GTSAM-Symbol g2o per robot and fullGraph.g2o (DGS, Kimera-Multi, gtsam.readG2o)",
        True,
        Lazy("studio.export", "_write_symbols"),
    ),
}
