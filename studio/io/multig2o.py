"""The multi-g2o folder: one sub-folder per agent plus the inter-agent loop closures.

::

    DATASET/
    ├── inter_agent_lc.dat          # see studio.io.inter_lc_dat
    ├── agent1/
    │   ├── posegraph.g2o           # vertices 0..n-1 (initial estimate), odometry edges k -> k+1, then
    │   │                           # intra-agent loop closures
    │   └── agent1_GT.tum           # ground truth of the same vertices
    └── agent2/ ...

Agents are the sub-folders holding a ``posegraph.g2o``, in natural order (``agent2`` before
``agent10``); agent ``k`` in ``inter_agent_lc.dat`` is the k-th of them. On reading, the leading run of
edges ``0->1, 1->2, ...`` is the odometry and every later edge an intra-agent loop closure.

Folders are named ``agent1 .. agentN`` by default, as kollagen's own reader (``multig2o::open``)
requires: it accepts only folders whose name starts with ``agent`` and that hold
``<folder>_GT.tum``. When the agents have other names (robots of a converted dataset), those names
and their sources are kept in ``agents.json`` beside the folders and read back as the agents' names::

    {"format": "cslam-studio agents 1",
     "agents": [{"folder": "agent1", "name": "alpha", "source": "alpha_gt.txt"}, ...]}

``folder_names="robots"`` writes the folders under the agents' own names instead (no ``agents.json``).
kollagen's reader sorts folders as strings (``agent10`` before ``agent2``): a dataset of 10 or more
agents is read by it in another order than ``inter_agent_lc.dat`` numbers them.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Literal

import numpy as np

from studio.core.errors import FormatError, GraphError, OutputError
from studio.core.geometry import se3_poses_to_planar
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.io.input_files import read_input_bytes
from studio.io.inter_lc_dat import Precision, read_inter_lc_dat, write_inter_lc_dat
from studio.io.names import safe_file_names
from studio.io.strict_json import unique_keys
from studio.io.tum import read_tum, write_tum

__all__ = [
    "write_multi_g2o",
    "multi_g2o_parts",
    "read_multi_g2o",
    "agent_g2o_document",
    "agent_folders",
    "Records",
    "FolderNames",
    "AGENTS_FILE",
]

Records = Literal["2d", "3d"]
FolderNames = Literal["agents", "robots"]
#: The mapping of agent folders to agent names and sources, beside the folders.
AGENTS_FILE = "agents.json"
_AGENTS_FORMAT = "cslam-studio agents 1"


def _natural_key(name: str) -> list[int | str]:
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def agent_g2o_document(
    agent: AgentGraph, offset: int = 0, odometry_information: np.ndarray | None = None
) -> G2oDocument:
    """An agent's vertices, odometry and loop closures as g2o records (ids shifted by ``offset``)."""
    odo, lc = agent.odometry, agent.loop_closures
    odo_info = odo.information_upper if odometry_information is None else odometry_information
    return G2oDocument(
        agent.kind,
        np.arange(agent.num_poses, dtype=np.int64) + offset,
        agent.initial,
        np.concatenate([odo.from_index, lc.from_index]) + offset,
        np.concatenate([odo.to_index, lc.to_index]) + offset,
        np.concatenate([odo.measurements, lc.measurements]),
        np.concatenate([odo_info, lc.information_upper]),
    )


def write_multi_g2o(
    graph: PoseGraph,
    folder: PathLike,
    *,
    records: Records = "3d",
    precision: Precision = "kollagen",
    folder_names: FolderNames = "agents",
    sources: dict[str, str] | None = None,
) -> None:
    """Write ``graph`` into ``folder`` (which must exist). ``records`` picks 2D or 3D g2o records;
    ``folder_names`` names the agent folders ``agent1..agentN`` (``agents.json`` keeps the agents'
    names where they differ, with ``sources``) or after the agents. A missing folder is an
    :class:`OutputError` naming it (commands write into a staged folder: studio.io.atomic)."""
    if not Path(folder).is_dir():
        raise OutputError(f"{folder}: no such folder (write_multi_g2o writes into an existing folder)")
    for part in multi_g2o_parts(
        graph, folder, records=records, precision=precision, folder_names=folder_names, sources=sources
    ):
        part()


def multi_g2o_parts(
    graph: PoseGraph,
    folder: PathLike,
    *,
    records: Records = "3d",
    precision: Precision = "kollagen",
    folder_names: FolderNames = "agents",
    sources: dict[str, str] | None = None,
) -> list[Callable[[], None]]:
    """:func:`write_multi_g2o` as independent writes, which may run in any order, in any process that
    has ``graph``: the inter-agent file, each agent's ``posegraph.g2o``, each agent's ground truth,
    then ``agents.json`` (the longer writes first, so that processes sharing them out end together)."""
    folder = Path(folder)
    if folder_names not in ("agents", "robots"):
        raise GraphError(f"folder_names must be agents or robots, got {folder_names!r}")
    if records == "2d" and graph.kind is not PoseKind.SE2:
        raise GraphError("2D records need a planar (SE2) graph")
    dirs = (
        [f"agent{k + 1}" for k in range(len(graph.agents))]
        if folder_names == "agents"  # robots: their names, never a path (safe names stay as they are)
        else safe_file_names([a.name for a in graph.agents], where=f"{folder.name}: agent names")
    )

    def graph_part(k: int) -> Callable[[], None]:
        def write() -> None:
            agent = graph.agents[k]
            sub = folder / dirs[k]
            sub.mkdir(exist_ok=True)  # the agent's other part may come first to it
            write_g2o(sub / "posegraph.g2o", agent_g2o_document(agent.to_se3() if records == "3d" else agent))

        return write

    def truth_part(k: int) -> Callable[[], None]:
        def write() -> None:
            agent = graph.agents[k]
            truth = agent.se3_poses(ground_truth=True)
            if truth is not None:
                sub = folder / dirs[k]
                sub.mkdir(exist_ok=True)
                write_tum(sub / f"{dirs[k]}_GT.tum", Trajectory.from_poses(agent.name, agent.stamps_ns, truth))

        return write

    def inter_part() -> None:
        inter = graph.inter.to_se3() if records == "3d" else graph.inter
        write_inter_lc_dat(folder / "inter_agent_lc.dat", inter, precision)

    def agents_file_part() -> None:
        entries = [
            {"folder": d, "name": a.name, **({"source": sources[a.name]} if sources and a.name in sources else {})}
            for d, a in zip(dirs, graph.agents)
        ]
        (folder / AGENTS_FILE).write_text(
            json.dumps({"format": _AGENTS_FORMAT, "agents": entries}, indent=2, allow_nan=False) + "\n",
            encoding="utf-8",
        )

    n = len(graph.agents)
    parts = [inter_part] + [graph_part(k) for k in range(n)] + [truth_part(k) for k in range(n)]
    if any(d != a.name for d, a in zip(dirs, graph.agents)):
        parts.append(agents_file_part)
    return parts


def _read_agents_file(folder: Path) -> list[tuple[str, str]] | None:
    """``[(folder, name), ...]`` from ``agents.json``, or None where there is none."""
    path = folder / AGENTS_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(read_input_bytes(path).decode("utf-8"), object_pairs_hook=unique_keys)
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise FormatError(f"{path}: not a readable agents file ({err})") from None
    if not isinstance(data, dict):  # [] or null once raised AttributeError in every dataset command
        data = {}
    entries = data.get("agents")
    if data.get("format") != _AGENTS_FORMAT or not isinstance(entries, list) or not entries:
        raise FormatError(f'{path}: expected {{"format": "{_AGENTS_FORMAT}", "agents": [...]}}')
    out: list[tuple[str, str]] = []
    for k, e in enumerate(entries):
        if not (
            isinstance(e, dict)
            and isinstance(e.get("folder"), str)
            and isinstance(e.get("name"), str)
            and e["name"]
            and Path(e["folder"]).name == e["folder"]
            and e["folder"] not in ("", ".", "..")
        ):
            raise FormatError(f"{path}: agents[{k}]: expected a plain folder and a non-empty name")
        for j, (folder_j, name_j) in enumerate(out):
            if e["folder"] == folder_j or e["name"] == name_j:
                same = f"folder {folder_j!r}" if e["folder"] == folder_j else f"name {name_j!r}"
                raise FormatError(f"{path}: agents[{k}]: the {same} is already agents[{j}]'s")
        out.append((e["folder"], e["name"]))
    return out


def check_dataset_links(folder: PathLike) -> None:
    """Refuse, naming it, a symbolic link or special file inside a dataset folder (one level of agent
    folders deep) that is dangling, loops, points outside the folder or to anything but a regular
    file or folder (``/dev/zero``, a FIFO): read silently, it would drop or renumber an agent."""
    import stat

    folder = Path(folder)
    if not folder.is_dir():
        return
    root = Path(os.path.realpath(folder))
    entries = list(folder.iterdir())
    entries += [q for p in entries if p.is_dir() and not p.is_symlink() for q in p.iterdir()]
    for p in entries:
        if p.is_symlink():
            try:
                target = Path(os.path.realpath(p, strict=True))
            except (OSError, RuntimeError):
                raise FormatError(f"{p}: a dangling or looping symbolic link") from None
            if target != root and root not in target.parents:
                raise FormatError(f"{p}: a symbolic link to {target}, outside the dataset folder")
        try:
            mode = os.stat(p).st_mode
        except OSError as err:
            raise FormatError(f"{p}: {err.strerror}") from None
        if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
            raise FormatError(f"{p}: not a regular file (a device, FIFO or socket)")


def agent_folders(folder: PathLike) -> list[tuple[str, Path]]:
    """``[(agent name, folder), ...]`` of a multi-g2o folder, in agent order (see the module doc)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FormatError(f"{folder}: not a folder")
    mapping = _read_agents_file(folder)
    if mapping is not None:
        out = []
        for sub, name in mapping:
            if not (folder / sub / "posegraph.g2o").is_file():
                raise FormatError(f"{folder / AGENTS_FILE}: agent {name}: no {sub}/posegraph.g2o")
            out.append((name, folder / sub))
        listed = {sub for sub, _ in mapping}
        unlisted = sorted(
            (
                p.name
                for p in folder.iterdir()
                if p.is_dir() and (p / "posegraph.g2o").is_file() and p.name not in listed
            ),
            key=_natural_key,
        )
        if unlisted:  # the agents' numbering would shift: inter_agent_lc.dat was blamed for it
            raise FormatError(f"{folder / AGENTS_FILE}: the agent folder {unlisted[0]} is not listed")
        return out
    subs = [p for p in folder.iterdir() if p.is_dir() and (p / "posegraph.g2o").is_file()]
    if not subs:
        raise FormatError(f"{folder}: no agent folder with a posegraph.g2o")
    return [(p.name, p) for p in sorted(subs, key=lambda p: _natural_key(p.name))]


def read_multi_g2o(folder: PathLike, *, edges: bool = True) -> PoseGraph:
    """Read a multi-g2o folder (ours or kollagen's) into a :class:`PoseGraph`.

    The graph is SE3 when the files hold 3D records (kollagen's default), SE2 for 2D records. A
    missing ``<agent>_GT.tum`` gives an agent without ground truth; a missing ``inter_agent_lc.dat``
    gives no inter-agent edges. ``edges=False`` reads only the poses (every edge list is empty), for
    tools such as ``studio evaluate`` that need nothing else.
    """
    folder = Path(folder)
    agents = []
    kind = None
    check_dataset_links(folder)
    for name, sub in agent_folders(folder):
        g2o_path = sub / "posegraph.g2o"
        doc = read_g2o(g2o_path, edges=edges)
        if kind is None:
            kind = doc.kind
        elif doc.kind is not kind:
            raise FormatError(f"{g2o_path}: {doc.kind.value} records after {kind.value} ones in other agents")
        n = len(doc.vertex_ids)
        if n == 0:
            raise FormatError(f"{g2o_path}: no vertices")
        order = np.argsort(doc.vertex_ids, kind="stable")
        if not np.array_equal(doc.vertex_ids[order], np.arange(n)):
            raise FormatError(f"{g2o_path}: vertex ids must be 0..{n - 1}")
        initial = doc.vertex_poses[order]
        fr, to = doc.edge_from, doc.edge_to
        chain = (fr == np.arange(len(fr))) & (to == np.arange(len(fr)) + 1)
        n_odo = int(np.argmin(chain)) if not chain.all() else len(fr)

        def edge_slice(
            sl: slice, kind: PoseKind = kind, fr: np.ndarray = fr, to: np.ndarray = to, doc: G2oDocument = doc
        ) -> Edges:
            return Edges(kind, fr[sl], to[sl], doc.edge_measurements[sl], doc.edge_information_upper[sl])

        gt_path = sub / f"{sub.name}_GT.tum"
        gt = gt3 = None
        stamps = np.arange(n, dtype=np.int64) * NS_PER_S
        if gt_path.is_file():
            traj = read_tum(gt_path)
            if len(traj.stamps_ns) != n:
                raise FormatError(f"{gt_path}: {len(traj.stamps_ns)} poses for {n} vertices in {g2o_path.name}")
            stamps = traj.stamps_ns
            gt3 = traj.poses_xyz_quat_xyzw
            gt = gt3 if kind is PoseKind.SE3 else se3_poses_to_planar(gt3)
        try:
            agents.append(
                AgentGraph(
                    name,
                    kind,
                    stamps,
                    initial,
                    gt,
                    edge_slice(slice(0, n_odo)),
                    edge_slice(slice(n_odo, None)),
                    ground_truth_se3=gt3 if kind is PoseKind.SE2 else None,
                )
            )
        except GraphError as err:
            raise FormatError(f"{sub}: {err}") from None
    dat = folder / "inter_agent_lc.dat"
    assert kind is not None  # agent_folders() returns at least one folder

    inter = read_inter_lc_dat(dat, kind) if edges and dat.is_file() else InterAgentEdges.empty(kind)
    try:
        return PoseGraph(kind, tuple(agents), inter, {"source": str(folder)})
    except GraphError as err:
        raise FormatError(f"{dat}: {err}") from None
