"""JRL ("JSON Robot Log", DanMcGann/jrl ``format/*.md``; MESA's and COSMO-Bench's format).

What the studio writes, following jrl's ``Writer`` and ``Parser`` (``src/Writer.cpp``,
``src/Parser.cpp``, ``include/jrl/IOMeasurements.h``)::

    {"name": NAME,
     "robots": ["a", "b", ...],                   # robot k's character: studio.io.symbol_g2o
     "measurements": {"a": [{"stamp": 12, "measurements": [FACTOR, ...]}, ...], ...},
     "groundtruth":    {"a": [{"key": K, "type": "Pose3", "translation": [x, y, z],
                               "rotation": [w, x, y, z]}, ...], ...},
     "initialization": {"a": [...], ...},
     "potential_outlier_factors": {"a": [[entry, measurement], ...], ...},
     "outlier_factors":           {"a": [[entry, measurement], ...], ...},
     "studio": {"format": "cslam-studio jrl 1", "agents": [NAME, ...], "stamps_ns": {"a": [...]}}}

* Keys are GTSAM Symbols ``ord(robot) << 56 | index``.
* A FACTOR is ``{"type": "BetweenFactorPose3", "key1", "key2", "measurement": POSE,
  "covariance": [36 values, row-major]}`` (``BetweenFactorPose2`` with ``{"x", "y", "theta"}`` and 9
  values for planar graphs). The covariance is over GTSAM's tangent order, rotation first for Pose3
  (``rx ry rz x y z``, the rotation as a rotation vector): the studio's g2o-convention information
  (``x y z`` then the quaternion's vector part) is converted (``J^T I J`` with
  ``J = diag(1, 1, 1, 1/2, 1/2, 1/2)``, reordered, inverted) and converted back on reading.
* Each measurement is an entry of the robot that owns it at its stamp (int64 nanoseconds inside the
  studio, written as they are): odometry and intra-robot loop closures at the later pose's stamp,
  inter-robot loop closures in the ``from`` robot's entries at the later of the two stamps.
* Every inter-robot loop closure (and every labelled outlier) is a potential outlier; the dataset's
  labelled outliers (``outliers.txt``) are the outlier factors. FactorIds are per robot, as jrl's
  ``Parser`` reads them.
* JRL values carry no stamps: the poses' stamps and the agents' names are in the ``studio`` block,
  which jrl's parser ignores. Without it (a file from elsewhere), pose ``k > 0`` takes the stamp of
  the entry holding the odometry into it.

Reading accepts ``BetweenFactorPose2/3`` and ``PriorFactorPose2/3`` (priors are dropped: the studio's
graphs have no priors) and ``BearingRangeFactorPose2`` between two robots' poses, read back into the
sightings table :mod:`studio.io.range_bearing` holds (:attr:`JrlGraph.range_bearing`, in stamp order
as ``studio convert mrclam`` makes it); range factors, bearing-range factors of other kinds
(``Pose3``'s ``Unit3`` bearing, landmarks' ``2D``/``3D``) and point factors are counted in one
warning and skipped. A ``BearingRangeFactorPose2`` is read as jrl's ``Parser`` reads it
(``parseBearingRange``: the bearing a ``Rot2`` object's ``theta``, the range a ``Scalar`` object's
``value``; the bare numbers ``format/VALUE_FORMAT.md`` lists are accepted too) with its covariance
row-major over (bearing, range); a bearing-range correlation is dropped with one warning (the
sightings table holds two standard deviations). Missing keys, robots not in ``robots``, keys of
unknown robots, mixed Pose2/Pose3, a bearing-range factor in a Pose3 graph or between poses of one
robot, a negative range and a covariance that is not symmetric positive definite are a
:class:`FormatError` naming the JSON path.
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import FormatError, GraphError
from studio.core.model import PoseGraph, PoseKind, RangeBearing
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE, NS_PER_S
from studio.io.g2o import MAX_TEXT_BYTES
from studio.io.graph_table import (
    AgentPoses,
    EdgeTable,
    assemble_graph,
    graph_edge_table,
    information_matrix,
    matrix_to_upper,
)
from studio.io.input_files import read_input_bytes
from studio.io.numbers import json_float
from studio.io.strict_json import dumps_strict, unique_keys
from studio.io.symbol_g2o import INDEX_BITS, robot_prefix

__all__ = [
    "JrlGraph",
    "jrl_document",
    "write_jrl",
    "read_jrl",
    "information_to_covariance",
    "covariance_to_information",
    "STUDIO_BLOCK_FORMAT",
]

STUDIO_BLOCK_FORMAT = "cslam-studio jrl 1"
_INDEX_MASK = (1 << INDEX_BITS) - 1
#: GTSAM's Pose3 tangent (rx ry rz x y z) from the studio's order (x y z rx ry rz).
_PERM = np.array([3, 4, 5, 0, 1, 2])
_HALF = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
_BETWEEN = {PoseKind.SE2: "BetweenFactorPose2", PoseKind.SE3: "BetweenFactorPose3"}
_PRIOR = {PoseKind.SE2: "PriorFactorPose2", PoseKind.SE3: "PriorFactorPose3"}
_VALUE = {PoseKind.SE2: "Pose2", PoseKind.SE3: "Pose3"}
_BEARING_RANGE = "BearingRangeFactorPose2"
_SKIPPED_TYPES = (
    "RangeFactor",
    "BearingRangeFactor",
    "BetweenFactorPoint",
    "PriorFactorPoint",
)


def information_to_covariance(kind: PoseKind, upper: np.ndarray) -> np.ndarray:
    """``(n, d, d)`` GTSAM covariances of the studio's information upper triangles."""
    info = information_matrix(kind, upper)
    if kind is PoseKind.SE3:
        info = info * _HALF[None, :, None] * _HALF[None, None, :]
        info = info[:, _PERM][:, :, _PERM]
    sign, _ = np.linalg.slogdet(info)
    if np.any(sign <= 0):
        k = int(np.flatnonzero(sign <= 0)[0])
        raise GraphError(f"edge {k}: its information is not positive definite, so it has no covariance")
    return np.linalg.inv(info)


def covariance_to_information(kind: PoseKind, cov: np.ndarray) -> np.ndarray:
    """The studio's information upper triangles of ``(n, d, d)`` GTSAM covariances."""
    info = np.linalg.inv(cov)
    if kind is PoseKind.SE3:
        back = np.argsort(_PERM)
        info = info[:, back][:, :, back]
        info = info / _HALF[None, :, None] / _HALF[None, None, :]
    return matrix_to_upper(info)


def _pose_values(kind: PoseKind, poses: np.ndarray) -> list[dict[str, Any]]:
    if kind is PoseKind.SE2:
        return [{"x": x, "y": y, "theta": t} for x, y, t in poses.tolist()]
    return [{"translation": [x, y, z], "rotation": [qw, qx, qy, qz]} for x, y, z, qx, qy, qz, qw in poses.tolist()]


def _values(kind: PoseKind, prefix: str, poses: np.ndarray) -> list[dict[str, Any]]:
    base = ord(prefix) << INDEX_BITS
    return [{"key": base + i, "type": _VALUE[kind], **v} for i, v in enumerate(_pose_values(kind, poses))]


def _bearing_range_factors(
    graph: PoseGraph, rb: RangeBearing | None, base: np.ndarray
) -> tuple[np.ndarray, list[dict[str, Any]], np.ndarray]:
    """JRL's ``BearingRangeFactorPose2`` of each sighting (observer keyframe to observed keyframe;
    measurement ``BearingRange`` of a ``Rot2`` bearing and a ``Scalar`` range, covariance over
    (bearing, range) as GTSAM's BearingRange orders them): stamps, factors, observer robots."""
    if rb is None or not len(rb) or graph.kind is not PoseKind.SE2:
        return np.zeros(0, np.int64), [], np.zeros(0, np.int64)
    k1 = (base[rb.observer_agent] + rb.observer_index).tolist()
    k2 = (base[rb.observed_agent] + rb.observed_index).tolist()
    factors = [
        {
            "type": "BearingRangeFactorPose2",
            "key1": a,
            "key2": b,
            "measurement": {
                "type": "BearingRange",
                "bearing": {"type": "Rot2", "theta": brg},
                "range": {"type": "Scalar", "value": rng},
            },
            "covariance": [sb * sb, 0.0, 0.0, sr * sr],
        }
        for a, b, brg, rng, sb, sr in zip(
            k1,
            k2,
            rb.bearing_rad.tolist(),
            rb.range_m.tolist(),
            rb.sigma_bearing_rad.tolist(),
            rb.sigma_range_m.tolist(),
        )
    ]
    return rb.stamps_ns, factors, rb.observer_agent


def _labelled(table: EdgeTable, outliers: np.ndarray | None) -> np.ndarray:
    """Which rows of ``table`` are among ``outliers`` (``(k, 4)`` rows ``agent_from vertex_from
    agent_to vertex_to``)."""
    if outliers is None or not len(outliers):
        return np.zeros(len(table), dtype=bool)
    view = np.ascontiguousarray(table.rows()).view([("", np.int64)] * 4).ravel()
    wanted = np.ascontiguousarray(np.asarray(outliers, dtype=np.int64)).view([("", np.int64)] * 4).ravel()
    label: np.ndarray = np.isin(view, wanted)
    return label


def jrl_document(
    graph: PoseGraph, *, name: str, outliers: np.ndarray | None = None, range_bearing: RangeBearing | None = None
) -> dict[str, Any]:
    """The JRL object of ``graph`` (see the module doc). ``outliers``: ``(k, 4)`` rows
    ``agent_from vertex_from agent_to vertex_to`` (0-based agents) of the labelled outliers.
    ``range_bearing``: sightings written as ``BearingRangeFactorPose2`` at their stamps in the
    observer's measurements (planar graphs only: JRL's 3D bearing is a ``Unit3``)."""
    kind = graph.kind
    prefixes = [robot_prefix(k) for k in range(len(graph.agents))]
    for a in graph.agents:
        if len(a.stamps_ns) and int(a.stamps_ns[0]) < 0:
            raise GraphError(f"{a.name}: JRL stamps are unsigned; the first stamp is {int(a.stamps_ns[0])} ns")
    table = graph_edge_table(graph)
    base = np.array([ord(p) << INDEX_BITS for p in prefixes], dtype=np.int64)
    key1 = (base[table.from_agent] + table.from_index).tolist()
    key2 = (base[table.to_agent] + table.to_index).tolist()
    starts = np.cumsum([0] + [a.num_poses for a in graph.agents])
    all_stamps = np.concatenate([a.stamps_ns for a in graph.agents])
    stamp = np.maximum(
        all_stamps[starts[table.from_agent] + table.from_index], all_stamps[starts[table.to_agent] + table.to_index]
    )
    try:
        cov = information_to_covariance(kind, table.information_upper)
    except GraphError as err:
        raise GraphError(f"JRL: {err}") from None
    cov_lists = cov.reshape(len(table), -1).tolist()
    meas = _pose_values(kind, table.measurements)
    tag = _BETWEEN[kind]
    inter = table.from_agent != table.to_agent
    label = _labelled(table, outliers)
    rb_stamp, rb_factor, rb_robot = _bearing_range_factors(graph, range_bearing, base)
    measurements: dict[str, list[dict[str, Any]]] = {}
    potential: dict[str, list[list[int]]] = {}
    labelled: dict[str, list[list[int]]] = {}
    for k, p in enumerate(prefixes):
        mine = np.flatnonzero(table.from_agent == k)
        order = mine[np.argsort(stamp[mine], kind="stable")].tolist()
        extra = np.flatnonzero(rb_robot == k).tolist()
        # between factors by stamp, then the robot's sightings merged in (after factors of equal stamp)
        items = [(int(stamp[e]), 0, e) for e in order] + [(int(rb_stamp[j]), 1, j) for j in extra]
        if extra:
            items.sort(key=lambda it: (it[0], it[1]))
        entries: list[dict[str, Any]] = []
        pot: list[list[int]] = []
        out: list[list[int]] = []
        last = None
        for at, is_rb, e in items:
            if at != last:
                entries.append({"stamp": at, "measurements": []})
                last = at
            factors = entries[-1]["measurements"]
            if is_rb:
                factors.append(rb_factor[e])
                continue
            if inter[e] or label[e]:
                pot.append([len(entries) - 1, len(factors)])
            if label[e]:
                out.append([len(entries) - 1, len(factors)])
            factors.append(
                {"type": tag, "key1": key1[e], "key2": key2[e], "measurement": meas[e], "covariance": cov_lists[e]}
            )
        measurements[p] = entries
        potential[p] = pot
        labelled[p] = out
    doc: dict[str, Any] = {"name": name, "robots": prefixes, "measurements": measurements}
    if all(a.ground_truth is not None for a in graph.agents):
        doc["groundtruth"] = {p: _values(kind, p, a.ground_truth) for p, a in zip(prefixes, graph.agents)}  # type: ignore[arg-type]
    doc["initialization"] = {p: _values(kind, p, a.initial) for p, a in zip(prefixes, graph.agents)}
    doc["potential_outlier_factors"] = potential
    doc["outlier_factors"] = labelled
    doc["studio"] = {
        "format": STUDIO_BLOCK_FORMAT,
        "agents": [a.name for a in graph.agents],
        "stamps_ns": {p: a.stamps_ns.tolist() for p, a in zip(prefixes, graph.agents)},
    }
    return doc


def write_jrl(
    path: PathLike,
    graph: PoseGraph,
    *,
    name: str,
    outliers: np.ndarray | None = None,
    range_bearing: RangeBearing | None = None,
) -> None:
    """Write ``graph`` as a JRL file (compact JSON, numbers as Python's shortest round-trip repr)."""
    doc = jrl_document(graph, name=name, outliers=outliers, range_bearing=range_bearing)
    text = dumps_strict(doc, str(path), separators=(",", ":"))
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)
        f.write("\n")


@dataclass(frozen=True, eq=False)
class JrlGraph:
    """A JRL file read: the graph, its labelled outliers and what was skipped."""

    graph: PoseGraph
    outliers: np.ndarray
    """``(k, 4)`` rows ``agent_from vertex_from agent_to vertex_to`` (0-based agents)."""
    name: str
    skipped: dict[str, int]
    """Factor types skipped (range, bearing-range but Pose2's, point factors, priors), with their counts."""
    range_bearing: RangeBearing | None = None
    """The ``BearingRangeFactorPose2`` sightings (None when the file has none)."""


class _Reader:
    def __init__(self, where: str) -> None:
        self.where = where

    def fail(self, path: str, what: str) -> FormatError:
        return FormatError(f"{self.where}: {path}: {what}")

    def get(self, obj: Any, key: str, path: str) -> Any:
        if type(obj) is not dict:
            raise self.fail(path, "expected a JSON object")
        if key not in obj:
            raise self.fail(path, f"missing key {key!r}")
        return obj[key]

    def number(self, value: Any, path: str, bound: float = sys.float_info.max) -> float:
        # never a string or a boolean (a bool is an int to Python); a 400-digit integer is refused,
        # not an OverflowError
        return json_float(value, f"{self.where}: {path}", bound=bound, what="value")

    def numbers(self, value: Any, n: int, path: str, bound: float = sys.float_info.max) -> list[float]:
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(path, f"expected a list of {n} numbers")
        return [self.number(v, f"{path}[{i}]", bound) for i, v in enumerate(value)]

    def uint(self, value: Any, path: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0 or value >= 1 << 64:
            raise self.fail(path, f"expected an unsigned 64-bit integer, got {json.dumps(value)[:40]}")
        return value

    def pose(self, kind: PoseKind, obj: Any, path: str) -> list[float]:
        if kind is PoseKind.SE2:
            return [self.number(self.get(obj, k, path), f"{path}.{k}", MAX_MAGNITUDE) for k in ("x", "y", "theta")]
        t = self.numbers(self.get(obj, "translation", path), 3, f"{path}.translation", MAX_MAGNITUDE)
        w, x, y, z = self.numbers(self.get(obj, "rotation", path), 4, f"{path}.rotation")
        norm = float(np.sqrt(w * w + x * x + y * y + z * z))
        if abs(norm - 1.0) > 1e-6:
            raise self.fail(f"{path}.rotation", f"quaternion is not unit length (norm {norm:.6g})")
        return [*t, x, y, z, w]


_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1


def _load(source: PathLike) -> tuple[Any, str]:
    path = Path(source)
    try:
        if path.is_dir():
            raise FormatError(f"{path}: is a folder, not a JRL file")
        if path.stat().st_size > MAX_TEXT_BYTES:
            raise FormatError(f"{path}: over the {MAX_TEXT_BYTES} byte (1 GiB) limit of text inputs")
        text = read_input_bytes(path).decode("utf-8")  # a FIFO or device: refused, never waited on
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise FormatError(f"{path}: not UTF-8 text") from None
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None
    try:
        return json.loads(text, parse_int=_parse_int, object_pairs_hook=unique_keys), str(path)
    except json.JSONDecodeError as err:
        raise FormatError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    except RecursionError:
        raise FormatError(f"{path}: JSON nested too deeply") from None
    except ValueError as err:  # an integer of thousands of digits (_parse_int), a key given twice
        raise FormatError(f"{path}: not valid JRL ({err})") from None


def _parse_int(text: str) -> int:
    """JSON integers of at most 40 digits (a key or stamp has 20): Python's own limit, 4300 digits,
    raises a ValueError about itself, and a 400-digit integer overflows a float."""
    if len(text) > 40:
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits, beyond any JRL key, stamp or value")
    return int(text)


def read_jrl(source: PathLike, *, warn: Callable[[str], None] | None = None) -> JrlGraph:
    """Read a JRL file (see the module doc); ``warn`` hears about skipped factors.

    One section at a time: the header (``name``, ``robots``, which robots each section names, the
    ``studio`` block), the measurements' factors, the values (``initialization``, ``groundtruth``),
    each robot's poses, then the graph and its labelled outliers (``outlier_factors``)."""
    data, where = _load(source)
    r = _Reader(where)
    name, robots, studio = _read_header(r, data)
    keys = _Keys(r, robots)
    factors = _read_factors(r, keys, data["measurements"])
    kind = factors.kind
    if kind is None:
        raise FormatError(f"{where}: measurements: no BetweenFactorPose2 or BetweenFactorPose3")
    dim = 3 if kind is PoseKind.SE2 else 6
    meas = _pose_array(r, kind, factors.measurements, [f"{p}.measurement" for p in factors.paths])
    cov = _number_array(r, factors.covariances, dim * dim, [f"{p}.covariance" for p in factors.paths])
    cov = cov.reshape(-1, dim, dim)
    if factors.skipped and warn is not None:
        warn(
            f"{where}: skipped factors the studio's pose graphs do not hold: "
            + ", ".join(f"{n} {t}" for t, n in sorted(factors.skipped.items()))
        )
    init = _read_values(r, keys, data, "initialization", kind)
    truth = _read_values(r, keys, data, "groundtruth", kind)
    edge = np.array(factors.rows, dtype=np.int64).reshape(-1, 4)
    agents, local = _robot_poses(r, robots, studio, edge, factors, init, truth)
    fi = np.array([local[a][i] for a, i in zip(edge[:, 0].tolist(), edge[:, 1].tolist())], dtype=np.int64)
    ti = np.array([local[a][i] for a, i in zip(edge[:, 2].tolist(), edge[:, 3].tolist())], dtype=np.int64)
    sign, _ = np.linalg.slogdet(cov)
    if np.any(sign <= 0):
        bad = int(np.flatnonzero(sign <= 0)[0])
        (c, e, m) = next(key for key, v in factors.ids.items() if v == bad)
        raise r.fail(f"measurements.{c}[{e}].measurements[{m}].covariance", "not positive definite")
    table = EdgeTable(kind, edge[:, 0], fi, edge[:, 2], ti, meas, covariance_to_information(kind, cov))
    graph = assemble_graph(agents, table, where=where, metadata={"source": where, "name": str(name)})
    outliers = _outlier_rows(r, data, factors.ids, table)
    sightings = _sightings(r, kind, factors.bearing_range, local, agents, warn)
    return JrlGraph(graph, outliers, str(name), factors.skipped, sightings)


def _read_header(r: _Reader, data: Any) -> tuple[Any, list[str], dict[str, Any] | None]:
    """The document's ``name``, its ``robots`` (checked, and every section's robots among them) and
    its ``studio`` block (None when absent or of another format)."""
    if not isinstance(data, dict):
        raise FormatError(f"{r.where}: expected a JSON object at the top")
    name = r.get(data, "name", "$")
    robots = r.get(data, "robots", "$")
    if not isinstance(robots, list) or not robots or not all(isinstance(c, str) and len(c) == 1 for c in robots):
        raise r.fail("robots", "expected a non-empty list of one-character robot ids")
    if len(set(robots)) != len(robots):
        raise r.fail("robots", "a robot id is listed twice")
    measurements = r.get(data, "measurements", "$")
    if not isinstance(measurements, dict):
        raise r.fail("measurements", "expected an object from robot id to entries")
    for section in ("measurements", "groundtruth", "initialization", "potential_outlier_factors", "outlier_factors"):
        block = data.get(section)
        if isinstance(block, dict):
            for c in block:
                if c not in robots:
                    raise r.fail(f"{section}.{c}", f"robot {c!r} is not in robots {robots}")
        elif block is not None and section in ("groundtruth", "initialization"):
            raise r.fail(section, "expected an object from robot id to values")
    studio = data.get("studio") if isinstance(data.get("studio"), dict) else None
    if studio is not None and studio.get("format") != STUDIO_BLOCK_FORMAT:
        studio = None
    return name, robots, studio


class _Keys:
    """The robots of a document and the decoding of their Symbol keys."""

    def __init__(self, r: _Reader, robots: list[str]) -> None:
        self.r = r
        self.robots = robots
        self.position = {ord(c): k for k, c in enumerate(robots)}

    def decode(self, key: int, path: str) -> tuple[int, int]:
        """``(robot position, pose index)`` of ``key``; a key of no robot fails naming ``path``."""
        c = key >> INDEX_BITS
        if c not in self.position:
            shown = chr(c) if 0 < c < 0x110000 else "?"
            raise self.r.fail(path, f"key {key} (Symbol {shown!r}) names no robot in robots {self.robots}")
        return self.position[c], key & _INDEX_MASK


@dataclass(eq=False)
class _Factors:
    """The pose-graph factors of the measurements, in reading order, as they were found."""

    kind: PoseKind | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    rows: list[tuple[int, int, int, int]] = field(default_factory=list)
    """``(robot_from, index_from, robot_to, index_to)`` per factor (indices as the keys give them)."""
    measurements: list[Any] = field(default_factory=list)
    covariances: list[Any] = field(default_factory=list)
    stamps: list[int] = field(default_factory=list)
    """The stamp of the entry holding each factor."""
    ids: dict[tuple[str, int, int], int] = field(default_factory=dict)
    """``(robot, entry, measurement)`` -> the factor's row."""
    paths: list[str] = field(default_factory=list)
    first_stamp: dict[int, int] = field(default_factory=dict)
    """Each robot's first entry's stamp."""
    bearing_range: list[_BearingRange] = field(default_factory=list)
    """The ``BearingRangeFactorPose2`` factors, in reading order."""


@dataclass(frozen=True, eq=False)
class _BearingRange:
    """One ``BearingRangeFactorPose2`` as read (keys decoded, values checked)."""

    path: str
    stamp: int
    observer: tuple[int, int]
    observed: tuple[int, int]
    bearing_rad: float
    range_m: float
    covariance: list[float]
    """Row-major over (bearing, range)."""


def _read_factors(r: _Reader, keys: _Keys, measurements: dict[str, Any]) -> _Factors:
    """Every robot's entries and their factors: Between factors kept, priors and non-pose factors
    counted as skipped, anything else (or a kind mixed with the other) a FormatError."""
    out = _Factors()
    between = {v: k for k, v in _BETWEEN.items()}
    for c in keys.robots:
        entries = measurements.get(c, [])
        if not isinstance(entries, list):
            raise r.fail(f"measurements.{c}", "expected a list of entries")
        for e, entry in enumerate(entries):
            path = f"measurements.{c}[{e}]"
            stamp = r.uint(r.get(entry, "stamp", path), f"{path}.stamp")
            if stamp > _INT64_MAX:
                raise r.fail(f"{path}.stamp", f"stamp beyond the studio's int64 nanoseconds ({stamp})")
            out.first_stamp.setdefault(keys.position[ord(c)], stamp)
            factors = entry.get("measurements", []) if isinstance(entry, dict) else []
            if not isinstance(factors, list):
                raise r.fail(f"{path}.measurements", "expected a list of measurements")
            for m, factor in enumerate(factors):
                fpath = f"{path}.measurements[{m}]"
                tag = r.get(factor, "type", fpath)
                if not isinstance(tag, str):
                    raise r.fail(f"{fpath}.type", "expected a type tag")
                if tag == _BEARING_RANGE:
                    out.bearing_range.append(_read_bearing_range(r, keys, factor, fpath, stamp))
                    continue
                if tag in _PRIOR.values() or tag.startswith(_SKIPPED_TYPES):
                    out.skipped[tag] = out.skipped.get(tag, 0) + 1
                    continue
                fkind = between.get(tag)
                if fkind is None:
                    raise r.fail(f"{fpath}.type", f"unknown measurement type {tag[:40]!r}")
                if out.kind is None:
                    out.kind = fkind
                elif fkind is not out.kind:
                    raise r.fail(f"{fpath}.type", f"{tag} mixed with {_BETWEEN[out.kind]} measurements")
                a, i = keys.decode(r.uint(r.get(factor, "key1", fpath), f"{fpath}.key1"), f"{fpath}.key1")
                b, j = keys.decode(r.uint(r.get(factor, "key2", fpath), f"{fpath}.key2"), f"{fpath}.key2")
                out.measurements.append(r.get(factor, "measurement", fpath))
                out.covariances.append(r.get(factor, "covariance", fpath))
                out.ids[(c, e, m)] = len(out.rows)
                out.paths.append(fpath)
                out.rows.append((a, i, b, j))
                out.stamps.append(stamp)
    return out


def _read_bearing_range(r: _Reader, keys: _Keys, factor: Any, path: str, stamp: int) -> _BearingRange:
    """One ``BearingRangeFactorPose2`` at ``path`` (see the module doc)."""
    k1 = keys.decode(r.uint(r.get(factor, "key1", path), f"{path}.key1"), f"{path}.key1")
    k2 = keys.decode(r.uint(r.get(factor, "key2", path), f"{path}.key2"), f"{path}.key2")
    if k1[0] == k2[0]:
        raise r.fail(path, f"key1 and key2 are poses of robot {keys.robots[k1[0]]!r}: a robot does not sight itself")
    m = r.get(factor, "measurement", path)
    mpath = f"{path}.measurement"

    def part(name: str, inner: str) -> float:
        value = r.get(m, name, mpath)
        if type(value) is dict:
            return r.number(r.get(value, inner, f"{mpath}.{name}"), f"{mpath}.{name}.{inner}")
        return r.number(value, f"{mpath}.{name}")

    bearing, rng = part("bearing", "theta"), part("range", "value")
    if rng < 0:
        raise r.fail(f"{mpath}.range", f"a range cannot be negative, got {rng!r}")
    cpath = f"{path}.covariance"
    cov = r.numbers(r.get(factor, "covariance", path), 4, cpath)
    if abs(cov[1] - cov[2]) > 1e-12 * max(abs(cov[0]), abs(cov[3])) or not (
        cov[0] > 0 and cov[3] > 0 and cov[0] * cov[3] - cov[1] * cov[2] > 0
    ):
        raise r.fail(cpath, "not a symmetric positive definite 2x2 covariance over (bearing, range)")
    return _BearingRange(path, stamp, k1, k2, bearing, rng, cov)


def _sightings(
    r: _Reader,
    kind: PoseKind,
    factors: list[_BearingRange],
    local: list[dict[int, int]],
    agents: list[AgentPoses],
    warn: Callable[[str], None] | None,
) -> RangeBearing | None:
    """The sightings table of the ``BearingRangeFactorPose2`` factors (None without any): each side
    the robot's pose its key names, offsets from the entry's stamp, rows in stamp order."""
    if not factors:
        return None
    if kind is not PoseKind.SE2:
        raise r.fail(factors[0].path, f"{_BEARING_RANGE} in a graph of {_BETWEEN[kind]} measurements")
    sides = []
    for f in factors:
        for (a, i), key in ((f.observer, "key1"), (f.observed, "key2")):
            if i not in local[a]:
                raise r.fail(
                    f"{f.path}.{key}", f"pose {i} of {agents[a].name!r} is in no values or pose-graph measurement"
                )
        sides.append(
            (f.observer[0], local[f.observer[0]][f.observer[1]], f.observed[0], local[f.observed[0]][f.observed[1]])
        )
    order = np.argsort(np.array([f.stamp for f in factors], dtype=np.int64), kind="stable")
    rows = [factors[k] for k in order.tolist()]
    side = np.array([sides[k] for k in order.tolist()], dtype=np.int64).reshape(-1, 4)
    cov = np.array([f.covariance for f in rows], dtype=np.float64)
    correlated = int(np.count_nonzero(cov[:, 1] != 0))
    if correlated and warn is not None:
        warn(
            f"{r.where}: {correlated} {_BEARING_RANGE} covariances correlate bearing and range; "
            "the sightings keep their two standard deviations only"
        )
    stamps = np.array([f.stamp for f in rows], dtype=np.int64)

    def offsets(agent: np.ndarray, index: np.ndarray) -> np.ndarray:
        return stamps - np.array([agents[a].stamps_ns[i] for a, i in zip(agent.tolist(), index.tolist())], np.int64)

    return RangeBearing(
        stamps,
        side[:, 0],
        side[:, 1],
        side[:, 2],
        side[:, 3],
        np.array([f.range_m for f in rows]),
        np.array([f.bearing_rad for f in rows]),
        np.sqrt(cov[:, 3]),
        np.sqrt(cov[:, 0]),
        offsets(side[:, 0], side[:, 1]),
        offsets(side[:, 2], side[:, 3]),
    )


def _read_values(
    r: _Reader, keys: _Keys, data: dict[str, Any], section: str, kind: PoseKind
) -> dict[int, dict[int, list[float]]] | None:
    """A values section (``initialization``, ``groundtruth``): robot position -> pose index -> pose
    row; None when the document has no such section."""
    block = data.get(section)
    if block is None:
        return None
    out: dict[int, dict[int, list[float]]] = {}
    for c, vals in block.items():
        items = vals.values() if isinstance(vals, dict) else vals
        if not isinstance(items, (list, type({}.values()))):
            raise r.fail(f"{section}.{c}", "expected a list of values")
        items = list(items)
        vpaths = [f"{section}.{c}[{n}]" for n in range(len(items))]
        decoded = []
        for v, vpath in zip(items, vpaths):
            key = r.uint(r.get(v, "key", vpath), f"{vpath}.key")
            vtype = r.get(v, "type", vpath)
            if vtype != _VALUE[kind]:
                raise r.fail(f"{vpath}.type", f"expected {_VALUE[kind]} values, got {str(vtype)[:40]!r}")
            decoded.append(keys.decode(key, f"{vpath}.key"))
        poses = _pose_array(r, kind, items, vpaths).tolist()
        for (a, i), pose, vpath in zip(decoded, poses, vpaths):
            robot = out.setdefault(a, {})
            if i in robot:  # the second silently won
                raise r.fail(f"{vpath}.key", f"pose {i} of robot {keys.robots[a]!r} is given twice in {section}")
            robot[i] = pose
    return out


def _robot_poses(
    r: _Reader,
    robots: list[str],
    studio: dict[str, Any] | None,
    edge: np.ndarray,
    factors: _Factors,
    init: dict[int, dict[int, list[float]]] | None,
    truth: dict[int, dict[int, list[float]]] | None,
) -> tuple[list[AgentPoses], list[dict[int, int]]]:
    """Each robot's poses: every index a value or a measurement names, renumbered 0..n-1 (the
    second list maps each robot's indices to those), with stamps, initial values and ground truth."""
    agents = []
    local: list[dict[int, int]] = []
    names = list(robots)
    if studio is not None and isinstance(studio.get("agents"), list) and len(studio["agents"]) == len(robots):
        names = [str(n) for n in studio["agents"]]
    stamps_block = studio.get("stamps_ns") if studio is not None else None
    for k, c in enumerate(robots):
        seen = set(edge[edge[:, 0] == k, 1].tolist()) | set(edge[edge[:, 2] == k, 3].tolist())
        for block in (init, truth):
            if block is not None:
                seen |= set(block.get(k, {}))
        if not seen:
            raise r.fail(f"robots[{k}]", f"robot {c!r} has no poses")
        index = sorted(seen)
        local.append({v: n for n, v in enumerate(index)})
        stamps = _stamps(r, c, k, index, edge, factors.stamps, factors.first_stamp, stamps_block)
        poses_init = _robot_values(r, init, "initialization", c, k, index)
        gt = _robot_values(r, truth, "groundtruth", c, k, index)
        agents.append(AgentPoses(names[k], stamps, poses_init, gt))
    return agents, local


def _robot_values(
    r: _Reader, block: dict[int, dict[int, list[float]]] | None, section: str, c: str, k: int, index: list[int]
) -> np.ndarray | None:
    """Robot ``k``'s poses at ``index`` from a values section (None without it); a missing one fails."""
    if block is None:
        return None
    have = block.get(k, {})
    missing = [v for v in index if v not in have]
    if missing:
        raise r.fail(f"{section}.{c}", f"no value for pose {c}{missing[0]}")
    return np.array([have[v] for v in index], dtype=np.float64)


def _outlier_rows(
    r: _Reader, data: dict[str, Any], ids: dict[tuple[str, int, int], int], table: EdgeTable
) -> np.ndarray:
    """``(k, 4)`` rows ``agent_from vertex_from agent_to vertex_to`` of the ``outlier_factors``."""
    outliers = []
    listed: dict[tuple[Any, ...], str] = {}
    labelled = data.get("outlier_factors") or {}
    if not isinstance(labelled, dict):
        raise r.fail("outlier_factors", "expected an object of robot -> [[entry, measurement], ...]")
    for c, pairs in labelled.items():
        if not isinstance(pairs, list):
            raise r.fail(f"outlier_factors.{c}", "expected a list of [entry, measurement] pairs")
        for n, pair in enumerate(pairs):
            if not (isinstance(pair, list) and len(pair) == 2 and all(type(x) is int for x in pair)):
                raise r.fail(f"outlier_factors.{c}[{n}]", "expected [entry, measurement]")
            row = ids.get((c, pair[0], pair[1]))
            if row is None:
                raise r.fail(f"outlier_factors.{c}[{n}]", f"no pose-graph measurement {pair} in measurements.{c}")
            key = (c, pair[0], pair[1])
            if key in listed:  # written twice to outliers.txt otherwise
                raise r.fail(f"outlier_factors.{c}[{n}]", f"{pair} is listed already ({listed[key]})")
            listed[key] = f"outlier_factors.{c}[{n}]"
            outliers.append(
                (
                    int(table.from_agent[row]),
                    int(table.from_index[row]),
                    int(table.to_agent[row]),
                    int(table.to_index[row]),
                )
            )
    return np.array(outliers, dtype=np.int64).reshape(-1, 4)


def _number_array(r: _Reader, values: list[Any], width: int, paths: list[str]) -> np.ndarray:
    """``(n, width)`` floats of JSON number lists; a bad one is named by its path (slow path)."""
    try:
        # numpy reads "0.5" and true as numbers; JRL's parser does not: only ints and floats pass
        plain = set(map(type, itertools.chain.from_iterable(values))) <= {int, float}
        arr = np.array(values, dtype=np.float64)
        if plain and arr.shape == (len(values), width) and np.isfinite(arr).all():
            return arr.reshape(len(values), width)
    except (TypeError, ValueError, OverflowError):
        pass
    for row, path in zip(values, paths):
        r.numbers(row, width, path)
    raise AssertionError("unreachable: the slow path names the bad value")


def _pose_array(r: _Reader, kind: PoseKind, values: list[Any], paths: list[str]) -> np.ndarray:
    """``(n, pose_width)`` poses of JSON Pose2/Pose3 objects (``x y theta``; ``x y z qx qy qz qw``)."""
    try:
        if kind is PoseKind.SE2:
            flat = [[v["x"], v["y"], v["theta"]] for v in values]
            arr = _number_array(r, flat, 3, paths)
        else:
            flat = [[*v["translation"], *v["rotation"]] for v in values]
            arr = _number_array(r, flat, 7, paths)[:, [0, 1, 2, 4, 5, 6, 3]]
        if np.any(np.abs(arr[:, : 2 if kind is PoseKind.SE2 else 3]) > MAX_MAGNITUDE):
            raise r.fail(paths[0], "beyond the bound")  # the slow path below names the value
        if kind is not PoseKind.SE2:
            norms = np.linalg.norm(arr[:, 3:], axis=1)
            bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-6)
            if bad.size:
                raise r.fail(f"{paths[bad[0]]}.rotation", f"quaternion is not unit length (norm {norms[bad[0]]:.6g})")
        return arr
    except (KeyError, TypeError, FormatError):
        pass
    for v, path in zip(values, paths):
        r.pose(kind, v, path)
    raise AssertionError("unreachable: the slow path names the bad value")


def _stamps(
    r: _Reader,
    c: str,
    k: int,
    index: list[int],
    edge: np.ndarray,
    edge_stamps: list[int],
    first_stamp: dict[int, int],
    block: Any,
) -> np.ndarray:
    """The poses' stamps: the studio block's, else those of the odometry entries (see the module doc)."""
    n = len(index)
    if isinstance(block, dict) and c in block:
        stamps = block[c]
        if not (isinstance(stamps, list) and len(stamps) == n and all(isinstance(s, int) for s in stamps)):
            raise r.fail(f"studio.stamps_ns.{c}", f"expected {n} integer stamps, one per pose")
        if any(isinstance(s, bool) or not _INT64_MIN <= s <= _INT64_MAX for s in stamps):
            raise r.fail(f"studio.stamps_ns.{c}", "expected 64-bit signed integer stamps (nanoseconds)")
        out = np.array(stamps, dtype=np.int64)
        if n > 1 and np.any(np.diff(out) <= 0):
            raise r.fail(f"studio.stamps_ns.{c}", "stamps must increase")
        return out
    position = {v: p for p, v in enumerate(index)}
    out = np.full(n, -1, dtype=np.int64)
    stamps_arr = np.array(edge_stamps, dtype=np.int64)
    odo = np.flatnonzero((edge[:, 0] == k) & (edge[:, 2] == k) & (edge[:, 3] == edge[:, 1] + 1))
    for e in odo[::-1].tolist():
        out[position[int(edge[e, 3])]] = stamps_arr[e]
    if n > 1 and out[1] >= 0:
        out[0] = min(first_stamp.get(k, out[1] - 1), out[1] - 1)
    if n > 1 and (np.any(out < 0) or np.any(np.diff(out) <= 0)):
        return np.arange(n, dtype=np.int64) * NS_PER_S
    if n == 1:
        return np.zeros(1, dtype=np.int64)
    return out
