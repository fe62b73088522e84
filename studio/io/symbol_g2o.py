"""Per-robot g2o files with GTSAM ``Symbol`` keys, as DGS (CogRob/distributed-mapper) and
Kimera-Multi / Kimera-RPGO read them.

A GTSAM ``Symbol('a', 5)`` is the 64-bit key ``ord('a') << 56 | 5``: the robot's character in the top
byte, the pose's index in the low 56 bits. Robot ``k`` (0-based, in the dataset's agent order) gets
the character :data:`ROBOT_PREFIXES` ``[k]``: ``a..j`` for the first ten (Kimera-Multi's robot ids
0-9), then ``k..z`` and ``A..Z`` (52 robots at most)::

    OUT/
    ├── 0.g2o           # robot a: its vertices, then the separator vertices (the other robots' poses
    │                   # its inter-robot edges reach), its odometry and loop closures, then every
    │                   # inter-robot edge it takes part in
    ├── 1.g2o ...
    ├── fullGraph.g2o   # every vertex and every edge once
    └── 0_GT.tum ...    # ground truth of each robot's own poses, with the dataset's stamps

The keys are written as full decimal integers (``6989586621679009792`` is ``a0``): GTSAM's own
``writeG2o`` drops the Symbol's character (gtsam#1279), the studio does not, and ``gtsam.readG2o``
reads every key back. Records and information are the g2o ones of :mod:`studio.io.g2o`.

Reading (:func:`read_symbol_g2o_folder`) takes such a folder, DGS's own (whose robot files omit
the separator vertices and whose indices need not be contiguous: distributed-mapper#8), or
Kimera-RPGO's (``robot_a.g2o``, ``robot_b.g2o``...: its test graphs): each robot file's own
character is the one of its first vertex; indices are renumbered ``0..n-1`` in increasing order; an
inter-robot edge in both robots' files is taken once. Without robot files, ``fullGraph.g2o`` is
split by the keys' characters.

Keys may also be GTSAM ``LabeledSymbol`` s, as Swarm-SLAM (lajoiepy/cslam) writes its graphs:
``char << 56 | label << 48 | index``, with the character ``'g'`` (its ``GRAPH_LABEL``) and the label
``'A' + robot id`` (``ROBOT_LABEL``). A folder whose keys have a non-zero label byte is read so: a
robot is a character and label (named ``gA``, ``gB``..., GTSAM's ``LabeledSymbol`` print), the
index its low 48 bits.
"""

from __future__ import annotations

import re
import string
from collections.abc import Callable
from pathlib import Path

import numpy as np

from studio.core.errors import ConfigError, FormatError
from studio.core.model import PoseGraph, PoseKind
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.io.g2o import G2oDocument, normalised_note, read_g2o, write_g2o
from studio.io.graph_table import AgentPoses, EdgeTable, assemble_graph, graph_edge_table
from studio.io.tum import read_tum, write_tum

__all__ = [
    "ROBOT_PREFIXES",
    "INDEX_BITS",
    "symbol_key",
    "symbol_parts",
    "symbol_name",
    "robot_code_name",
    "LABEL_BITS",
    "write_symbol_g2o_folder",
    "read_symbol_g2o_folder",
    "FULL_GRAPH",
]

#: The character of robot k (Kimera-Multi: robot ids 0-9 are a..j).
ROBOT_PREFIXES = string.ascii_lowercase + string.ascii_uppercase
#: A Symbol's index takes the low 56 bits of its key.
INDEX_BITS = 56
_INDEX_MASK = (1 << INDEX_BITS) - 1
FULL_GRAPH = "fullGraph.g2o"
_ROBOT_FILE = re.compile(r"^(\d+)\.g2o$")
_NAMED_ROBOT_FILE = re.compile(r"^robot_([A-Za-z0-9]+)\.g2o$")
#: A LabeledSymbol's index takes the low 48 bits of its key, its label the byte above.
LABEL_BITS = 48


def robot_prefix(k: int) -> str:
    if not 0 <= k < len(ROBOT_PREFIXES):
        raise ConfigError(f"Symbol keys name at most {len(ROBOT_PREFIXES)} robots (a..z, A..Z); robot {k} has none")
    return ROBOT_PREFIXES[k]


def symbol_key(prefix: str, index: np.ndarray | int) -> np.ndarray:
    """The keys ``ord(prefix) << 56 | index`` (int64: every character used is below 128)."""
    keys: np.ndarray = (np.int64(ord(prefix)) << np.int64(INDEX_BITS)) | np.asarray(index, dtype=np.int64)
    return keys


def symbol_parts(keys: np.ndarray, bits: int = INDEX_BITS) -> tuple[np.ndarray, np.ndarray]:
    """The robots' codes and the indices of ``keys``: with ``bits`` 56 (``Symbol``) the character,
    with 48 (``LabeledSymbol``) the character and label as ``char << 8 | label``."""
    keys = np.asarray(keys, dtype=np.int64)
    return keys >> np.int64(bits), keys & np.int64((1 << bits) - 1)


def robot_code_name(code: int, bits: int = INDEX_BITS) -> str:
    """``a`` for a Symbol's character, ``gA`` for a LabeledSymbol's character and label."""
    return chr(code) if bits == INDEX_BITS else chr(code >> 8) + chr(code & 0xFF)


def symbol_name(key: int, bits: int = INDEX_BITS) -> str:
    """``a5`` for ``Symbol('a', 5)``, ``gA5`` for ``LabeledSymbol('g', 'A', 5)`` (GTSAM's formatters)."""
    return f"{robot_code_name(key >> bits, bits)}{key & ((1 << bits) - 1)}"


def write_symbol_g2o_folder(graph: PoseGraph, folder: PathLike) -> list[str]:
    """Write ``graph`` into the existing ``folder`` (layout in the module doc); returns the file names."""
    folder = Path(folder)
    prefixes = [robot_prefix(k) for k in range(len(graph.agents))]
    table = graph_edge_table(graph)
    offsets = [symbol_key(p, 0) for p in prefixes]
    keys_from = np.array(offsets, dtype=np.int64)[table.from_agent] + table.from_index
    keys_to = np.array(offsets, dtype=np.int64)[table.to_agent] + table.to_index
    all_keys = np.concatenate([symbol_key(p, np.arange(a.num_poses)) for p, a in zip(prefixes, graph.agents)])
    all_poses = np.concatenate([a.initial for a in graph.agents])
    starts = np.cumsum([0] + [a.num_poses for a in graph.agents])
    names = []
    for k, a in enumerate(graph.agents):
        edge_rows = np.flatnonzero((table.from_agent == k) | (table.to_agent == k))
        inter = edge_rows[table.from_agent[edge_rows] != table.to_agent[edge_rows]]
        other = np.where(table.from_agent[inter] == k, table.to_agent[inter], table.from_agent[inter])
        other_index = np.where(table.from_agent[inter] == k, table.to_index[inter], table.from_index[inter])
        sep = np.unique(starts[other] + other_index)
        own = np.arange(starts[k], starts[k + 1])
        vertices = np.concatenate([own, sep])
        doc = G2oDocument(
            graph.kind,
            all_keys[vertices],
            all_poses[vertices],
            keys_from[edge_rows],
            keys_to[edge_rows],
            table.measurements[edge_rows],
            table.information_upper[edge_rows],
        )
        write_g2o(folder / f"{k}.g2o", doc)
        names.append(f"{k}.g2o")
        truth = a.se3_poses(ground_truth=True)
        if truth is not None:
            write_tum(folder / f"{k}_GT.tum", Trajectory.from_poses(a.name, a.stamps_ns, truth))
            names.append(f"{k}_GT.tum")
    full = G2oDocument(graph.kind, all_keys, all_poses, keys_from, keys_to, table.measurements, table.information_upper)
    write_g2o(folder / FULL_GRAPH, full)
    names.append(FULL_GRAPH)
    return names


def _robot_files(folder: Path) -> list[tuple[int | str, Path]]:
    """DGS's ``0.g2o, 1.g2o...`` in number order, else Kimera-RPGO's ``robot_a.g2o...`` in name order."""
    files = [p for p in folder.iterdir() if p.is_file()]
    numbered = [(int(m.group(1)), p) for p in files if (m := _ROBOT_FILE.match(p.name))]
    if numbered:
        return sorted(numbered)  # type: ignore[return-value]
    return sorted((m.group(1), p) for p in files if (m := _NAMED_ROBOT_FILE.match(p.name)))  # type: ignore[misc]


def read_symbol_g2o_folder(folder: PathLike, *, warn: Callable[[str], None] | None = None) -> PoseGraph:
    """Read a folder of Symbol-keyed g2o files (see the module doc), or one such file holding every
    robot (Swarm-SLAM's graph), into a :class:`PoseGraph`; the agents are named after their
    characters (``a``, ``b``...; ``gA``, ``gB``... for LabeledSymbol keys). ``warn`` gets one line
    with the count of quaternions normalised.

    The steps: read the robot files (or ``fullGraph.g2o``), find each robot's character and own
    vertices, renumber them into agents (with their ground truth), take each edge once and assemble."""
    folder = Path(folder)
    if folder.is_file():
        files: list[tuple[int | str, Path]] = []
        docs = _checked([(folder, read_g2o(folder, dangling=True))])
    elif folder.is_dir():
        files = _robot_files(folder)
        docs = _read_symbol_docs(folder, files)
    else:
        raise FormatError(f"{folder}: no such folder or file")
    normalised = sum(d.normalised_quaternions for _, d in docs)
    if normalised and warn is not None:
        warn(normalised_note(str(folder), normalised))
    kind = docs[0][1].kind
    bits = _key_bits(docs)
    owner, own = _own_vertices(docs, robot_files=bool(files), bits=bits)
    codes = list(owner)
    agents = []
    renumber: dict[int, np.ndarray] = {}
    for c in codes:
        index, poses = own[c]
        order = np.argsort(index, kind="stable")
        index, poses = index[order], poses[order]
        if np.any(np.diff(index) == 0):
            dup = int(index[np.flatnonzero(np.diff(index) == 0)[0]])
            raise FormatError(f"{owner[c]}: Symbol key {robot_code_name(c, bits)}{dup} is defined twice")
        renumber[c] = index
        gt_path = owner[c].with_name(f"{owner[c].stem}_GT.tum") if files else None
        stamps, truth = _robot_truth(gt_path, kind, len(index), owner[c])
        agents.append(AgentPoses(robot_code_name(c, bits), stamps, poses, truth))
    table = _edge_table(kind, _edge_parts(docs, codes, bits), codes, renumber, owner, bits)
    return assemble_graph(agents, table, where=str(folder), metadata={"source": str(folder)})


def _key_bits(docs: list[tuple[Path, G2oDocument]]) -> int:
    """48 where any key has a label byte (GTSAM ``LabeledSymbol``, Swarm-SLAM), else 56 (``Symbol``)."""
    for _, d in docs:
        for col in (d.vertex_ids, d.edge_from, d.edge_to):
            if np.any((col >> np.int64(LABEL_BITS)) & np.int64(0xFF)):
                return LABEL_BITS
    return INDEX_BITS


def _read_symbol_docs(folder: Path, files: list[tuple[int | str, Path]]) -> list[tuple[Path, G2oDocument]]:
    """The robot files (or ``fullGraph.g2o``) read, checked for one record kind and Symbol keys."""
    docs: list[tuple[Path, G2oDocument]]
    if files:
        docs = [(p, read_g2o(p, dangling=True)) for _, p in files]
    elif (folder / FULL_GRAPH).is_file():
        docs = [(folder / FULL_GRAPH, read_g2o(folder / FULL_GRAPH, dangling=True))]
    else:
        raise FormatError(f"{folder}: no robot files (0.g2o, 1.g2o, ... or robot_a.g2o, ...) and no {FULL_GRAPH}")
    return _checked(docs)


def _checked(docs: list[tuple[Path, G2oDocument]]) -> list[tuple[Path, G2oDocument]]:
    """``docs``, refused unless they hold one record kind and Symbol keys."""
    kind = docs[0][1].kind
    for p, d in docs:
        if d.kind is not kind:
            raise FormatError(f"{p}: {d.kind.value} records after {kind.value} ones in {docs[0][0].name}")
        for col in (d.vertex_ids, d.edge_from, d.edge_to):
            bad = np.flatnonzero((col >> np.int64(INDEX_BITS)) <= 0)
            if bad.size:
                raise FormatError(f"{p}: key {int(col[bad[0]])} is not a GTSAM Symbol (no character in its top byte)")
    return docs


def _own_vertices(
    docs: list[tuple[Path, G2oDocument]], *, robot_files: bool, bits: int
) -> tuple[dict[int, Path], dict[int, tuple[np.ndarray, np.ndarray]]]:
    """Each robot's character (in file order) with the file that defines it, and its own vertices'
    indices and poses: a robot file's character is its first vertex's; ``fullGraph.g2o`` is split
    by the keys' characters."""
    owner: dict[int, Path] = {}
    own: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    if robot_files:
        for p, d in docs:
            if not len(d.vertex_ids):
                raise FormatError(f"{p}: no vertices (its first vertex gives the robot's Symbol character)")
            c = int(d.vertex_ids[0] >> np.int64(bits))
            if c in owner:
                raise FormatError(
                    f"{p}: its Symbol character {robot_code_name(c, bits)!r} (key {int(d.vertex_ids[0])}) collides "
                    f"with the robot of {owner[c].name}: two robots with one character"
                )
            owner[c] = p
            chars, index = symbol_parts(d.vertex_ids, bits)
            own[c] = (index[chars == c], d.vertex_poses[chars == c])
    else:
        p, d = docs[0]
        chars, index = symbol_parts(d.vertex_ids, bits)
        for c in dict.fromkeys(chars.tolist()):
            owner[c] = p
            own[c] = (index[chars == c], d.vertex_poses[chars == c])
    return owner, own


def _robot_truth(
    gt_path: Path | None, kind: PoseKind, n: int, robot_file: Path
) -> tuple[np.ndarray, np.ndarray | None]:
    """A robot's stamps and ground truth from ``gt_path`` (``<k>_GT.tum``), or stamps 0, 1, 2... s
    and no ground truth where there is no such file."""
    if gt_path is None or not gt_path.is_file():
        return np.arange(n, dtype=np.int64) * NS_PER_S, None
    traj = read_tum(gt_path)
    if len(traj) != n:
        raise FormatError(f"{gt_path}: {len(traj)} poses for the {n} vertices of {robot_file.name}")
    truth = traj.poses_xyz_quat_xyzw
    if kind is PoseKind.SE2:
        from studio.core.geometry import se3_poses_to_planar

        truth = se3_poses_to_planar(truth)
    return traj.stamps_ns, truth


_EdgePart = tuple[Path, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""One file's edges: ``(file, from_char, from_index, to_char, to_index, measurements, information)``."""


def _edge_parts(docs: list[tuple[Path, G2oDocument]], codes: list[int], bits: int) -> list[_EdgePart]:
    """The edges of each file: inside a robot from its file; between robots once (the first file
    that holds one keeps it). An edge reaching a character of no robot is a FormatError."""
    parts = []
    seen_inter: set[tuple[int, int]] = set()
    for p, d in docs:
        fc, fi = symbol_parts(d.edge_from, bits)
        tc, ti = symbol_parts(d.edge_to, bits)
        for codes_col, keys in ((fc, d.edge_from), (tc, d.edge_to)):
            unknown = ~np.isin(codes_col, codes)
            if unknown.any():
                k = int(np.flatnonzero(unknown)[0])
                raise FormatError(
                    f"{p}: edge {k} reaches {symbol_name(int(keys[k]), bits)} (key {int(keys[k])}), a character of no robot"
                )
        keep = np.ones(len(fc), dtype=bool)
        inter = np.flatnonzero(fc != tc)
        pairs = list(zip(d.edge_from[inter].tolist(), d.edge_to[inter].tolist()))
        file_pairs = set(pairs)
        for r, pair in zip(inter.tolist(), pairs):
            if pair in seen_inter:
                keep[r] = False
        seen_inter |= file_pairs
        parts.append(
            (p, fc[keep], fi[keep], tc[keep], ti[keep], d.edge_measurements[keep], d.edge_information_upper[keep])
        )
    return parts


def _edge_table(
    kind: PoseKind,
    parts: list[_EdgePart],
    codes: list[int],
    renumber: dict[int, np.ndarray],
    owner: dict[int, Path],
    bits: int,
) -> EdgeTable:
    """The edges in agents and renumbered vertices (``renumber[c]``: robot ``c``'s sorted indices);
    an edge reaching an index its robot does not define is a FormatError."""
    position = {c: k for k, c in enumerate(codes)}
    cols: list[list[np.ndarray]] = [[], [], [], [], [], []]
    for p, fc, fi, tc, ti, meas, info in parts:
        for codes_col, index_col, out_a, out_i in ((fc, fi, cols[0], cols[1]), (tc, ti, cols[2], cols[3])):
            agent = np.array([position[c] for c in codes_col.tolist()], dtype=np.int64)
            local = np.zeros(len(index_col), dtype=np.int64)
            for c in np.unique(codes_col).tolist():
                sel = codes_col == c
                known = renumber[c]
                pos = np.searchsorted(known, index_col[sel])
                pos_c = np.minimum(pos, len(known) - 1)
                missing = known[pos_c] != index_col[sel]
                if missing.any():
                    missing_index = int(index_col[sel][np.flatnonzero(missing)[0]])
                    raise FormatError(
                        f"{p}: an edge reaches {robot_code_name(c, bits)}{missing_index}, which {owner[c].name} does not "
                        "define as a vertex"
                    )
                local[sel] = pos
            out_a.append(agent)
            out_i.append(local)
        cols[4].append(meas)
        cols[5].append(info)
    return EdgeTable(
        kind,
        np.concatenate(cols[0]),
        np.concatenate(cols[1]),
        np.concatenate(cols[2]),
        np.concatenate(cols[3]),
        np.concatenate(cols[4]).reshape(-1, kind.pose_width),
        np.concatenate(cols[5]).reshape(-1, kind.information_width),
    )
