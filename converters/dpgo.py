"""DPGO's ``measurements.csv`` files (``studio convert dpgo FOLDER`` or ``FILE.csv...``): a folder
whose sub-folders hold ``measurements.csv`` (one per robot, as the studio's ``dpgo`` export and
DPGO's logger write them), or the files themselves (:mod:`studio.io.dpgo`). Such files hold no
vertices and no ground truth: the initial estimate is composed along the odometry; with
``robotR/robotR_GT.tum`` beside (the studio's export), that is the ground truth and its stamps."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from studio.converters.graph_split import GraphImportOptions, ImportedGraph, graph_trajectories, outliers_beside
from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import se3_poses_to_planar
from studio.core.model import PoseGraph, PoseKind
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.io.dpgo import read_measurements_csv_files
from studio.io.tum import read_tum

__all__ = ["dpgo_files", "read_dpgo_graph", "read_dpgo_trajectories"]


def dpgo_files(inputs: Sequence[PathLike]) -> list[Path]:
    """The ``measurements.csv`` files of the inputs (a folder's sub-folders in natural order)."""
    import re

    def natural(p: Path) -> list:
        return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", str(p))]

    out: list[Path] = []
    for p in map(Path, inputs):
        if p.is_dir():
            found = sorted(
                (q / "measurements.csv" for q in p.iterdir() if (q / "measurements.csv").is_file()), key=natural
            )
            if (p / "measurements.csv").is_file():
                found.insert(0, p / "measurements.csv")
            if not found:
                raise FormatError(f"{p}: no measurements.csv in it or in its sub-folders")
            out += found
        else:
            out.append(p)
    return out


def _with_truth(graph: PoseGraph, files: list[Path]) -> PoseGraph:
    """Ground truth and stamps from ``robotR/robotR_GT.tum`` beside the files, where there are."""
    agents = list(graph.agents)
    for r, a in enumerate(agents):
        candidates = [f.parent / f"robot{r}_GT.tum" for f in files] + [
            f.parent / f"robot{r}" / f"robot{r}_GT.tum" for f in files
        ]
        gt = next((c for c in candidates if c.is_file()), None)
        if gt is None:
            continue
        traj = read_tum(gt)
        if len(traj) != a.num_poses:
            raise FormatError(f"{gt}: {len(traj)} poses for the {a.num_poses} poses of robot {r}")
        truth = traj.poses_xyz_quat_xyzw
        agents[r] = dataclasses.replace(
            a, stamps_ns=traj.stamps_ns, ground_truth=truth if a.kind is PoseKind.SE3 else se3_poses_to_planar(truth)
        )
    return dataclasses.replace(graph, agents=tuple(agents))


def read_dpgo_graph(
    inputs: Sequence[PathLike], *, warn: Warn | None = None, options: GraphImportOptions | None = None
) -> ImportedGraph:
    if options is not None and options.split:
        raise ConfigError("--split: only single g2o files are split into robots (studio convert g2o)")
    if not inputs:
        raise ConfigError("studio convert dpgo needs a folder or measurements.csv files")
    files = dpgo_files(inputs)
    graph = _with_truth(read_measurements_csv_files(files), files)
    folder = Path(inputs[0]) if Path(inputs[0]).is_dir() else Path(inputs[0]).parent
    return ImportedGraph(graph, outliers_beside(folder, graph))


def read_dpgo_trajectories(
    inputs: Sequence[PathLike], *, agents: Sequence[str] = (), warn: Warn | None = None, progress=None
) -> list[Trajectory]:
    return graph_trajectories(read_dpgo_graph(inputs, warn=warn).graph, str(inputs[0]))
