"""An optimizer's estimate of a dataset, read from one of three layouts and split per agent.

* **single g2o** (a ``.g2o`` file): every agent's vertices with ids concatenated in the order of the
  dataset's single g2o (agent 1's vertices first, see :func:`studio.io.singleg2o.agent_offsets`);
  edges and ``FIX`` lines are ignored.
* **multi-g2o** (a folder of ``<agent>/posegraph.g2o``): one file per agent, ids ``0..n-1``.
* **TUM** (a folder of ``<agent>.tum`` or ``<agent>_*.tum``, ``*_GT.tum`` excluded): one trajectory
  per agent; its poses are matched to the ground truth by timestamp when scoring.

The folder ``studio solve`` writes (or its ``solve.json``) stands for the estimate it holds: the entry
``"estimate"`` of ``solve.json`` names it (``estimate/``, a multi-g2o folder, or ``<stem>.g2o``); a
folder without ``solve.json`` but with a multi-g2o ``estimate/`` inside is taken the same way.

Every layout gives one :class:`~studio.core.trajectory.Trajectory` per dataset agent. g2o estimates
give one pose per dataset vertex, stamped with the dataset's stamps (``Estimate.by_time`` is false:
pose k is the estimate of vertex k); a vertex count or id that does not match the dataset raises
:class:`~studio.core.errors.EvaluationError` naming the agent and how many vertices are off. Planar
(``VERTEX_SE2``) files are lifted to ``[x, y, 0, 0, 0, sin(theta/2), cos(theta/2)]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from studio.core.errors import EvaluationError, FormatError
from studio.core.geometry import planar_poses_to_se3
from studio.core.model import PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.io.g2o import G2oDocument, read_g2o
from studio.io.multig2o import agent_folders
from studio.io.names import safe_file_name
from studio.io.singleg2o import agent_offsets
from studio.io.tum import read_tum

__all__ = ["Estimate", "EstimateLayout", "read_estimate", "estimate_layout", "solve_output_estimate"]

EstimateLayout = Literal["single-g2o", "multi-g2o", "tum"]


@dataclass(frozen=True, eq=False)
class Estimate:
    layout: EstimateLayout
    source: str
    agents: tuple[Trajectory, ...]
    """One entry per dataset agent, in the dataset's order."""

    @property
    def by_time(self) -> bool:
        """True when poses are matched to the ground truth by timestamp (TUM), false when pose k
        is the estimate of dataset vertex k (g2o)."""
        return self.layout == "tum"


def _poses7(doc: G2oDocument) -> np.ndarray:
    return doc.vertex_poses if doc.kind is PoseKind.SE3 else planar_poses_to_se3(doc.vertex_poses)


def _range_text(first: int, count: int) -> str:
    return f"id {first}" if count == 1 else f"ids {first}..{first + count - 1}"


def _check_ids(ids: np.ndarray, first: int, count: int, where: str, agent: str) -> np.ndarray:
    """The row order that sorts ``ids`` into ``first..first+count-1``, or an EvaluationError."""
    inside = (ids >= first) & (ids < first + count)
    n_in = int(inside.sum())
    if n_in != count:
        have = np.zeros(count, dtype=bool)
        have[ids[inside] - first] = True
        missing = np.flatnonzero(~have)
        raise EvaluationError(
            f"{where}: {agent} has {n_in} of its {count} vertices ({_range_text(first, count)}); "
            f"{len(missing)} missing, the first is id {first + int(missing[0])}"
        )
    return np.argsort(ids, kind="stable")


def _read_single_g2o(path: Path, graph: PoseGraph, vertex_ids: np.ndarray | None = None) -> tuple[Trajectory, ...]:
    doc = read_g2o(path, edges=False)
    offsets = agent_offsets(graph)
    total = int(offsets[-1])
    ids = doc.vertex_ids
    if vertex_ids is not None:  # the dataset file's own ids, renumbered 0..n-1 as it was read
        at = np.minimum(np.searchsorted(vertex_ids, ids), len(vertex_ids) - 1)
        unknown = vertex_ids[at] != ids
        if unknown.any():
            raise EvaluationError(
                f"{path}: {int(unknown.sum())} vertices have ids the dataset's file does not have; "
                f"the first is id {int(ids[unknown][0])}"
            )
        ids = at
    outside = (ids < 0) | (ids >= total)
    if outside.any():
        raise EvaluationError(
            f"{path}: {int(outside.sum())} vertices have ids outside the dataset's {total} "
            f"(ids 0..{total - 1}); the first is id {int(ids[outside][0])}"
        )
    poses = _poses7(doc)
    out = []
    for k, agent in enumerate(graph.agents):
        first, count = int(offsets[k]), agent.num_poses
        sel = (ids >= first) & (ids < first + count)
        order = _check_ids(ids[sel], first, count, str(path), agent.name)
        out.append(Trajectory.from_poses(agent.name, agent.stamps_ns, poses[sel][order], str(path)))
    return tuple(out)


def _has_agent_dirs(folder: Path) -> bool:
    return any(p.is_dir() and (p / "posegraph.g2o").is_file() for p in folder.iterdir())


def _read_multi_g2o(folder: Path, graph: PoseGraph) -> tuple[Trajectory, ...]:
    subs = dict(agent_folders(folder))
    names = [a.name for a in graph.agents]
    extra = sorted(set(subs) - set(names))
    if extra:
        raise EvaluationError(f"{folder}: agent {extra[0]} is not in the dataset (agents: {', '.join(names)})")
    out = []
    for agent in graph.agents:
        if agent.name not in subs:
            raise EvaluationError(f"{folder}: no {agent.name}/posegraph.g2o for agent {agent.name}")
        path = subs[agent.name] / "posegraph.g2o"
        doc = read_g2o(path, edges=False)
        if len(doc.vertex_ids) != agent.num_poses:
            raise EvaluationError(
                f"{path}: {agent.name} has {len(doc.vertex_ids)} vertices, the dataset {agent.num_poses}"
            )
        order = _check_ids(doc.vertex_ids, 0, agent.num_poses, str(path), agent.name)
        out.append(Trajectory.from_poses(agent.name, agent.stamps_ns, _poses7(doc)[order], str(path)))
    return tuple(out)


def _tum_files(folder: Path, graph: PoseGraph) -> dict[str, Path]:
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix == ".tum" and not p.name.endswith("_GT.tum")]
    found: dict[str, Path] = {}
    for agent in graph.agents:
        # the agent's own file (as ``studio solve`` writes it: its name made safe) wins; else one
        # ``<agent>_*.tum``, as a converter's inputs are often named
        exact = [p for p in files if p.name in (f"{agent.name}.tum", f"{safe_file_name(agent.name)}.tum")]
        mine = exact or sorted(p for p in files if p.name.startswith(f"{agent.name}_"))
        if not mine:
            raise EvaluationError(f"{folder}: no {agent.name}.tum or {agent.name}_*.tum for agent {agent.name}")
        if len(mine) > 1:
            raise EvaluationError(
                f"{folder}: several TUM files for agent {agent.name}: {', '.join(p.name for p in mine)}"
            )
        other = next((name for name, path in found.items() if path == mine[0]), None)
        if other is not None:  # one trajectory would be scored as two agents'
            raise EvaluationError(
                f"{folder}: {mine[0].name} is the TUM file of both agent {other} and agent {agent.name}"
            )
        found[agent.name] = mine[0]
    return found


def _read_tum_folder(folder: Path, graph: PoseGraph) -> tuple[Trajectory, ...]:
    return tuple(read_tum(path, name=name) for name, path in _tum_files(folder, graph).items())


SOLVE_JSON = "solve.json"


def solve_output_estimate(path: PathLike) -> Path | None:
    """The estimate inside a ``studio solve`` output (its folder or its ``solve.json``), or None when
    ``path`` is not one. A ``solve.json`` that cannot be read, or names no estimate inside its folder,
    raises :class:`FormatError` naming it."""
    import json

    path = Path(path)
    if path.is_file() and path.name == SOLVE_JSON:
        folder, record = path.parent, path
    elif path.is_dir():
        folder, record = path, path / SOLVE_JSON
        if not record.is_file():
            inner = path / "estimate"
            return inner if inner.is_dir() and _has_agent_dirs(inner) else None
    else:
        return None
    try:
        if record.stat().st_size > 64 * 2**20:
            raise FormatError(f"{record}: over 64 MiB, not a solve.json")
        data = json.loads(record.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise FormatError(f"{record}: not a readable solve.json ({err.__class__.__name__})") from None
    name = data.get("estimate") if isinstance(data, dict) else None
    if not isinstance(name, str) or not name or name != Path(name).name or name in (".", ".."):
        raise FormatError(f"{record}: $.estimate must name the estimate beside it, got {name!r}")
    inner = folder / name
    if not inner.exists():
        raise FormatError(f"{record}: its estimate {inner} is missing")
    return inner


def estimate_layout(path: PathLike) -> EstimateLayout:
    """Guess the layout from the path: a file is a single g2o; a folder holds agent folders or TUM files
    (a ``studio solve`` output: the estimate it names, see :func:`solve_output_estimate`)."""
    path = Path(path)
    inner = solve_output_estimate(path)
    if inner is not None:
        return estimate_layout(inner)
    if path.is_file():
        return "single-g2o"
    if not path.is_dir():
        raise FormatError(f"{path}: no such file or folder")
    if _has_agent_dirs(path):
        return "multi-g2o"
    if any(p.suffix == ".tum" for p in path.iterdir() if p.is_file()):
        return "tum"
    raise FormatError(
        f"{path}: not an estimate (expected a single .g2o file, a folder of <agent>/posegraph.g2o, "
        "a folder of <agent>.tum files, or the folder studio solve wrote)"
    )


def read_estimate(path: PathLike, graph: PoseGraph, *, vertex_ids: np.ndarray | None = None) -> Estimate:
    """Read an estimate of ``graph`` (layout guessed by :func:`estimate_layout`), split per agent;
    ``vertex_ids``: a single g2o estimate's ids are those (sorted) of the dataset's file, renumbered
    ``0..n-1`` in their order (as ``studio solve`` keeps a file's ids), instead of ``0..n-1``."""
    path = Path(path)
    path = solve_output_estimate(path) or path
    layout = estimate_layout(path)
    if layout == "single-g2o":
        return Estimate(layout, str(path), _read_single_g2o(path, graph, vertex_ids))
    reader = {"multi-g2o": _read_multi_g2o, "tum": _read_tum_folder}[layout]
    return Estimate(layout, str(path), reader(path, graph))
