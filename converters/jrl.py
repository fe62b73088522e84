"""JRL files (``studio convert jrl FILE.jrl``): the graph, ground truth, initial estimate, the
labelled and potential outliers, the pose priors and the ``BearingRangeFactorPose2`` sightings as
they are (:mod:`studio.io.jrl`)."""

from __future__ import annotations

from collections.abc import Sequence

from studio.converters.graph_split import GraphImportOptions, ImportedGraph, graph_trajectories
from studio.core.errors import ConfigError
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.io.jrl import read_jrl

__all__ = ["read_jrl_graph", "read_jrl_trajectories"]


def read_jrl_graph(
    inputs: Sequence[PathLike], *, warn: Warn | None = None, options: GraphImportOptions | None = None
) -> ImportedGraph:
    if len(inputs) != 1:
        raise ConfigError(f"studio convert jrl takes one .jrl file, got {len(inputs)} inputs")
    if options is not None and options.split:
        raise ConfigError("--split: only single g2o files are split into robots (studio convert g2o)")
    doc = read_jrl(inputs[0], warn=warn)
    return ImportedGraph(doc.graph, doc.outliers, doc.range_bearing, doc.priors, doc.potential_outliers)


def read_jrl_trajectories(
    inputs: Sequence[PathLike], *, agents: Sequence[str] = (), warn: Warn | None = None, progress=None
) -> list[Trajectory]:
    """The robots' ground truth."""
    return graph_trajectories(read_jrl_graph(inputs, warn=warn).graph, str(inputs[0]))
