"""Folders of GTSAM-Symbol-keyed g2o files, one per robot (DGS / distributed-mapper's
``data/example_*robots/`` ``0.g2o, 1.g2o...``, Kimera-RPGO's ``robot_a.g2o, robot_b.g2o...``,
Kimera-Multi), or Swarm-SLAM's ``LabeledSymbol`` keys: ``studio convert symbols FOLDER``
(:mod:`studio.io.symbol_g2o`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from studio.converters.graph_split import GraphImportOptions, ImportedGraph, graph_trajectories, outliers_beside
from studio.core.errors import ConfigError
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.io.symbol_g2o import read_symbol_g2o_folder

__all__ = ["read_symbols_graph", "read_symbols_trajectories"]


def read_symbols_graph(
    inputs: Sequence[PathLike], *, warn: Warn | None = None, options: GraphImportOptions | None = None
) -> ImportedGraph:
    if len(inputs) != 1:
        raise ConfigError(f"studio convert symbols takes one folder, got {len(inputs)} inputs")
    if options is not None and options.split:
        raise ConfigError("--split: only single g2o files are split into robots (studio convert g2o)")
    graph = read_symbol_g2o_folder(inputs[0], warn=warn)
    return ImportedGraph(graph, outliers_beside(Path(inputs[0]), graph))


def read_symbols_trajectories(
    inputs: Sequence[PathLike], *, agents: Sequence[str] = (), warn: Warn | None = None, progress=None
) -> list[Trajectory]:
    """The robots' ground truth (``N_GT.tum`` beside ``N.g2o``)."""
    return graph_trajectories(read_symbols_graph(inputs, warn=warn).graph, str(inputs[0]))
