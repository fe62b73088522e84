"""JRL ("JSON Robot Log", DanMcGann/jrl; MESA's, riMESA's and COSMO-Bench's format).

Read and written as jrl's own code reads and writes it (``src/Parser.cpp``, ``src/Writer.cpp``,
``include/jrl/IOMeasurements.h``, ``src/IOValues.cpp``; where ``format/*.md`` differs, the code
wins)::

    {"name": NAME,
     "robots": [97, 98, ...],                     # robot k's character, as a number
     "measurements": {"a": [{"stamp": 12, "measurements": [FACTOR, ...]}, ...], ...},
     "groundtruth":    {"a": [{"key": K, "type": "Pose3", "translation": [x, y, z],
                               "rotation": [w, x, y, z]}, ...], ...},
     "initialization": {"a": [...], ...},
     "potential_outlier_factors": {"a": [[entry, measurement], ...], ...},
     "outlier_factors":           {"a": [[entry, measurement], ...], ...},
     "studio": {"format": "cslam-studio jrl 1", "agents": [NAME, ...], "stamps_ns": {"a": [...]}}}

* Robot ids are ``char``: the ``Writer`` (nlohmann's json) writes each as a number and the
  ``Parser`` reads them with ``get<std::vector<char>>()``, which takes numbers only; the studio
  writes numbers and reads numbers 1..127 and, as ``format/DATASET_FORMAT.md`` and hand-written
  files show them, one-character strings. A section's robot is its key, a one-character string.
* Keys are GTSAM Symbols ``ord(robot) << 56 | index`` (robot k's character: studio.io.symbol_g2o).
* A FACTOR is ``{"type": "BetweenFactorPose3", "key1", "key2", "measurement": POSE,
  "covariance": [36 values]}`` (``BetweenFactorPose2`` with ``{"x", "y", "theta"}`` and 9 values
  for planar graphs) or ``{"type": "PriorFactorPose3", "key", "prior": POSE, "covariance"}``. A
  covariance is dense, column-major (``Eigen::Map`` of the list), over GTSAM's tangent order,
  rotation first for Pose3 (``rx ry rz x y z``, the rotation as a rotation vector): the studio's
  g2o-convention information (``x y z`` then the quaternion's vector part) is converted (``J^T I J``
  with ``J = diag(1, 1, 1, 1/2, 1/2, 1/2)``, reordered, inverted) and converted back on reading.
* Each measurement is an entry of the robot that owns it at its stamp (int64 nanoseconds inside the
  studio, written as they are): a prior first in the entry of its pose's stamp, odometry and
  intra-robot loop closures at the later pose's stamp, inter-robot loop closures in the ``from``
  robot's entries at the later of the two stamps. A factor listed by two robots is two measurements,
  as MESA's centralised runner adds every robot's factors.
* A robot's values hold every pose its measurements touch: its own, then copies of the other robots'
  poses (jrl's ``Dataset``: ground-truth copies must agree, initialization copies may differ).
  Reading, a pose takes its owner's value, else the first copy; ground-truth copies that disagree
  are one warning.
* Potential outliers: the dataset's ``potential_outliers.txt`` where it has one (a JRL read keeps the
  file's), else every inter-robot loop closure; every labelled outlier (``outliers.txt``,
  ``outlier_factors``) is a potential one. FactorIds are per robot, ``[entry, measurement]``, as
  jrl's ``Parser`` reads a ``std::set<FactorId>``; labels on factors the studio does not hold (a
  prior, a skipped type) are dropped with one warning.
* JRL values carry no stamps: the poses' stamps and the agents' names are in the ``studio`` block,
  which jrl's parser ignores. Without it (a file from elsewhere), pose ``k > 0`` takes the stamp of
  the entry holding the odometry into it, pose 0 the robot's first entry's.

Reading accepts ``BetweenFactorPose2/3``, ``PriorFactorPose2/3`` (kept: :attr:`JrlGraph.priors`)
and ``BearingRangeFactorPose2`` between two robots' poses, read back into the
sightings table :mod:`studio.io.range_bearing` holds (:attr:`JrlGraph.range_bearing`, in stamp order
as ``studio convert mrclam`` makes it); range factors, bearing-range factors of other kinds
(``Pose3``'s ``Unit3`` bearing, landmarks' ``2D``/``3D``) and point factors are counted in one
warning and skipped. A ``BearingRangeFactorPose2`` is read as jrl's ``Parser`` reads it
(``parseBearingRange``: the bearing a ``Rot2`` object's ``theta``, the range a ``Scalar`` object's
``value``; the bare numbers ``format/VALUE_FORMAT.md`` lists are accepted too) with its covariance
over (bearing, range); a bearing-range correlation is dropped with one warning (the
sightings table holds two standard deviations). Missing keys, robots not in ``robots``, keys of
unknown robots, mixed Pose2/Pose3, a prior on a pose no value or pose-graph measurement names, a
FactorId past its robot's entries or its entry's measurements, a quaternion off unit length by more
than 1e-6, a bearing-range factor in a Pose3 graph or between poses of one robot, a negative range
and a covariance that is not positive definite are a :class:`FormatError` naming the JSON path.
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
from studio.core.model import PoseGraph, PoseKind, Priors, RangeBearing
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
    """jrl's ``serialize<Pose2/Pose3>`` of each pose (its quaternion ``w x y z``)."""
    tag = _VALUE[kind]
    if kind is PoseKind.SE2:
        return [{"type": tag, "x": x, "y": y, "theta": t} for x, y, t in poses.tolist()]
    return [
        {"type": tag, "translation": [x, y, z], "rotation": [qw, qx, qy, qz]}
        for x, y, z, qx, qy, qz, qw in poses.tolist()
    ]


def _value_sections(
    graph: PoseGraph, truth: bool, touched: list[set[tuple[int, int]]]
) -> dict[str, list[dict[str, Any]]]:
    """Each robot's values as jrl's ``Dataset`` holds them: its own poses, then copies of the other
    robots' poses its measurements touch (``touched``: ``(agent, index)`` per robot), so that every
    key of a robot's factors has a value in its own section (what MESA's robots optimise over)."""
    out = {}
    kind = graph.kind
    for k, a in enumerate(graph.agents):
        prefix = robot_prefix(k)
        poses = a.ground_truth if truth else a.initial
        assert poses is not None
        base = ord(prefix) << INDEX_BITS
        vals = [{"key": base + i, **v} for i, v in enumerate(_pose_values(kind, poses))]
        for b, i in sorted(touched[k]):
            other = graph.agents[b].ground_truth if truth else graph.agents[b].initial
            assert other is not None
            key = (ord(robot_prefix(b)) << INDEX_BITS) + i
            vals.append({"key": key, **_pose_values(kind, other[i : i + 1])[0]})
        out[prefix] = vals
    return out


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
    graph: PoseGraph,
    *,
    name: str,
    outliers: np.ndarray | None = None,
    range_bearing: RangeBearing | None = None,
    priors: Priors | None = None,
    potential_outliers: np.ndarray | None = None,
) -> dict[str, Any]:
    """The JRL object of ``graph`` (see the module doc). ``outliers``: ``(k, 4)`` rows
    ``agent_from vertex_from agent_to vertex_to`` (0-based agents) of the labelled outliers;
    ``potential_outliers`` the same rows of the potential outliers (default: every inter-robot loop
    closure); every labelled outlier is a potential one. ``range_bearing``: sightings written as
    ``BearingRangeFactorPose2`` at their stamps in the observer's measurements (planar graphs only:
    JRL's 3D bearing is a ``Unit3``). ``priors``: ``PriorFactorPose2/3`` first in the entry at their
    pose's stamp."""
    kind = graph.kind
    prefixes = [robot_prefix(k) for k in range(len(graph.agents))]
    for a in graph.agents:
        if len(a.stamps_ns) and int(a.stamps_ns[0]) < 0:
            raise GraphError(f"{a.name}: JRL stamps are unsigned; the first stamp is {int(a.stamps_ns[0])} ns")
    table = graph_edge_table(graph)
    base = np.array([ord(p) << INDEX_BITS for p in prefixes], dtype=np.int64)
    starts = np.cumsum([0] + [a.num_poses for a in graph.agents])
    all_stamps = np.concatenate([a.stamps_ns for a in graph.agents])
    stamp = np.maximum(
        all_stamps[starts[table.from_agent] + table.from_index], all_stamps[starts[table.to_agent] + table.to_index]
    )
    label = _labelled(table, outliers)
    potential = label | (
        table.from_agent != table.to_agent if potential_outliers is None else _labelled(table, potential_outliers)
    )
    between = _between_factors(kind, table, base)
    rb_stamp, rb_factor, rb_robot = _bearing_range_factors(graph, range_bearing, base)
    pr_stamp, pr_factor, pr_robot = _prior_factors(graph, priors, base)
    measurements: dict[str, list[dict[str, Any]]] = {}
    marked: dict[str, list[list[int]]] = {}
    labelled: dict[str, list[list[int]]] = {}
    for k, p in enumerate(prefixes):
        mine = np.flatnonzero(table.from_agent == k)
        # priors first in an entry, then between factors by stamp, then the robot's sightings
        items = [(int(pr_stamp[j]), 0, j) for j in np.flatnonzero(pr_robot == k).tolist()]
        items += [(int(stamp[e]), 1, e) for e in mine[np.argsort(stamp[mine], kind="stable")].tolist()]
        items += [(int(rb_stamp[j]), 2, j) for j in np.flatnonzero(rb_robot == k).tolist()]
        items.sort(key=lambda it: (it[0], it[1]))
        entries: list[dict[str, Any]] = []
        pot: list[list[int]] = []
        out: list[list[int]] = []
        for at, what, e in items:
            if not entries or entries[-1]["stamp"] != at:
                entries.append({"stamp": at, "measurements": []})
            factors = entries[-1]["measurements"]
            if what == 1 and potential[e]:
                pot.append([len(entries) - 1, len(factors)])
            if what == 1 and label[e]:
                out.append([len(entries) - 1, len(factors)])
            factors.append((pr_factor, between, rb_factor)[what][e])
        measurements[p] = entries
        marked[p] = pot
        labelled[p] = out
    # jrl's Writer writes a robot id (a char) as a number; its Parser reads them back as chars
    doc: dict[str, Any] = {"name": name, "robots": [ord(p) for p in prefixes], "measurements": measurements}
    touched = _touched(graph, table, range_bearing)
    if all(a.ground_truth is not None for a in graph.agents):
        doc["groundtruth"] = _value_sections(graph, True, touched)
    doc["initialization"] = _value_sections(graph, False, touched)
    doc["potential_outlier_factors"] = marked
    doc["outlier_factors"] = labelled
    doc["studio"] = {
        "format": STUDIO_BLOCK_FORMAT,
        "agents": [a.name for a in graph.agents],
        "stamps_ns": {p: a.stamps_ns.tolist() for p, a in zip(prefixes, graph.agents)},
    }
    return doc


def _touched(graph: PoseGraph, table: EdgeTable, rb: RangeBearing | None) -> list[set[tuple[int, int]]]:
    """Per robot, the other robots' poses its measurements touch (the ``to`` end of the inter-robot
    loop closures in its entries; the observed end of its sightings, planar graphs only)."""
    touched: list[set[tuple[int, int]]] = [set() for _ in graph.agents]
    inter = np.flatnonzero(table.from_agent != table.to_agent)
    for k, b, i in zip(
        table.from_agent[inter].tolist(), table.to_agent[inter].tolist(), table.to_index[inter].tolist()
    ):
        touched[k].add((b, i))
    if rb is not None and graph.kind is PoseKind.SE2:
        for k, b, i in zip(rb.observer_agent.tolist(), rb.observed_agent.tolist(), rb.observed_index.tolist()):
            touched[k].add((b, i))
    return touched


def _covariance_lists(kind: PoseKind, information_upper: np.ndarray) -> list[list[float]]:
    """jrl's covariance lists (column-major, as ``serializeCovariance`` writes an Eigen matrix)."""
    try:
        cov = information_to_covariance(kind, information_upper)
    except GraphError as err:
        raise GraphError(f"JRL: {err}") from None
    lists: list[list[float]] = cov.transpose(0, 2, 1).reshape(len(cov), -1).tolist()
    return lists


def _between_factors(kind: PoseKind, table: EdgeTable, base: np.ndarray) -> list[dict[str, Any]]:
    """``BetweenFactorPose2/3`` of every edge of ``table``, in its order."""
    key1 = (base[table.from_agent] + table.from_index).tolist()
    key2 = (base[table.to_agent] + table.to_index).tolist()
    tag = _BETWEEN[kind]
    return [
        {"type": tag, "key1": a, "key2": b, "measurement": m, "covariance": c}
        for a, b, m, c in zip(
            key1, key2, _pose_values(kind, table.measurements), _covariance_lists(kind, table.information_upper)
        )
    ]


def _prior_factors(
    graph: PoseGraph, priors: Priors | None, base: np.ndarray
) -> tuple[np.ndarray, list[dict[str, Any]], np.ndarray]:
    """``PriorFactorPose2/3`` of each prior (``key``, ``prior``, ``covariance``, as jrl's
    ``serializePrior`` writes them): stamps (their pose's), factors, robots."""
    if priors is None or not len(priors):
        return np.zeros(0, np.int64), [], np.zeros(0, np.int64)
    priors.check_against(graph)
    stamps = np.array([graph.agents[a].stamps_ns[i] for a, i in zip(priors.agent.tolist(), priors.index.tolist())])
    keys = (base[priors.agent] + priors.index).tolist()
    tag = _PRIOR[graph.kind]
    factors = [
        {"type": tag, "key": k, "prior": v, "covariance": c}
        for k, v, c in zip(
            keys, _pose_values(graph.kind, priors.poses), _covariance_lists(graph.kind, priors.information_upper)
        )
    ]
    return stamps.astype(np.int64), factors, priors.agent


def write_jrl(
    path: PathLike,
    graph: PoseGraph,
    *,
    name: str,
    outliers: np.ndarray | None = None,
    range_bearing: RangeBearing | None = None,
    priors: Priors | None = None,
    potential_outliers: np.ndarray | None = None,
) -> None:
    """Write ``graph`` as a JRL file (compact JSON, numbers as Python's shortest round-trip repr)."""
    doc = jrl_document(
        graph,
        name=name,
        outliers=outliers,
        range_bearing=range_bearing,
        priors=priors,
        potential_outliers=potential_outliers,
    )
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
    priors: Priors | None = None
    """The ``PriorFactorPose2/3`` factors (None when the file has none)."""
    potential_outliers: np.ndarray | None = None
    """``(k, 4)`` edge rows of ``potential_outlier_factors`` (None when the file has no such section)."""


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
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, f"expected a number, got {json.dumps(value)[:40]}")
        try:
            v = float(value)
        except OverflowError:
            raise self.fail(path, "a number beyond a double's range") from None
        if not np.isfinite(v):
            raise self.fail(path, "not a finite number")
        if abs(v) > bound:  # translations: the documented bound of every coordinate
            raise self.fail(path, f"{v:g} is beyond {bound:g} m")
        return v

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
#: jrl's robot ids are chars that name a JSON object key (``std::string(1, robot)``): ASCII.
_ROBOT_ID_END = 128


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
    """JSON integers of at most 4000 digits: Python's own limit, 4300 digits, raises a ValueError
    about itself (a longer one than a double holds is refused where it is used, with its path)."""
    if len(text) > 4000:
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
    cov = _column_major(cov, dim)
    if factors.skipped and warn is not None:
        warn(
            f"{where}: skipped factors the studio's pose graphs do not hold: "
            + ", ".join(f"{n} {t}" for t, n in sorted(factors.skipped.items()))
        )
    init = _read_values(r, keys, data, "initialization", kind, warn)
    truth = _read_values(r, keys, data, "groundtruth", kind, warn)
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
    sightings = _sightings(r, kind, factors.bearing_range, local, agents, warn)
    priors = _prior_table(r, kind, factors.priors, local, agents)
    outliers, potential = _labels(r, data, factors, table, warn)
    return JrlGraph(graph, outliers, str(name), factors.skipped, sightings, priors, potential)


def _column_major(flat: np.ndarray, dim: int) -> np.ndarray:
    """``(n, dim, dim)`` matrices of jrl's covariance lists: ``parseCovariance`` maps them with
    ``Eigen::Map<gtsam::Matrix>``, column-major (one matrix whatever the order when symmetric)."""
    out: np.ndarray = flat.reshape(-1, dim, dim).transpose(0, 2, 1)
    return out


def _labels(
    r: _Reader, data: dict[str, Any], factors: _Factors, table: EdgeTable, warn: Callable[[str], None] | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """The labelled outliers (``outlier_factors``; none without the section) and the potential
    outliers (``potential_outlier_factors``; None without it), as edge rows."""
    outliers = _labelled_rows(r, data, "outlier_factors", factors, table)
    potential = _labelled_rows(r, data, "potential_outlier_factors", factors, table)
    elsewhere = (outliers[1] if outliers else 0) + (potential[1] if potential else 0)
    if elsewhere and warn is not None:
        warn(
            f"{r.where}: {elsewhere} outlier labels name factors the studio's graphs do not hold (priors, skipped types); dropped"
        )
    rows = outliers[0] if outliers else np.zeros((0, 4), dtype=np.int64)
    return rows, potential[0] if potential else None


def _prior_table(
    r: _Reader, kind: PoseKind, found: list[_Prior], local: list[dict[int, int]], agents: list[AgentPoses]
) -> Priors | None:
    """The ``PriorFactorPose2/3`` factors as a :class:`Priors` table (None without any): each on a
    pose of the graph (one a value or a pose-graph measurement names), of the graph's kind, with a
    positive definite covariance."""
    if not found:
        return None
    dim = 3 if kind is PoseKind.SE2 else 6
    for p in found:
        if p.kind is not kind:
            raise r.fail(f"{p.path}.type", f"{_PRIOR[p.kind]} in a graph of {_BETWEEN[kind]} measurements")
        a, i = p.pose
        if i not in local[a]:
            raise r.fail(
                f"{p.path}.key",
                f"a prior on pose {i} of {agents[a].name!r}, which no value or pose-graph measurement names",
            )
    poses = _pose_array(r, kind, [p.value for p in found], [f"{p.path}.prior" for p in found])
    cov = _column_major(
        _number_array(r, [p.covariance for p in found], dim * dim, [f"{p.path}.covariance" for p in found]), dim
    )
    sign, _ = np.linalg.slogdet(cov)
    if np.any(sign <= 0):
        raise r.fail(f"{found[int(np.flatnonzero(sign <= 0)[0])].path}.covariance", "not positive definite")
    agent = np.array([p.pose[0] for p in found], dtype=np.int64)
    index = np.array([local[p.pose[0]][p.pose[1]] for p in found], dtype=np.int64)
    return Priors(kind, agent, index, poses, covariance_to_information(kind, cov))


def _read_header(r: _Reader, data: Any) -> tuple[Any, list[str], dict[str, Any] | None]:
    """The document's ``name``, its ``robots`` (checked, and every section's robots among them) and
    its ``studio`` block (None when absent or of another format)."""
    if not isinstance(data, dict):
        raise FormatError(f"{r.where}: expected a JSON object at the top")
    name = r.get(data, "name", "$")
    robots = _robot_ids(r, r.get(data, "robots", "$"))
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


def _robot_ids(r: _Reader, robots: Any) -> list[str]:
    """The robots' characters. jrl's ``Parser`` reads ``robots`` with ``get<std::vector<char>>()``
    and its ``Writer`` writes a ``char`` as a number (``"robots": [97, 98]``); one-character strings,
    as ``format/DATASET_FORMAT.md`` shows them and hand-written files have them, are read too. A
    section's robot is the first character of its key (``el.key()[0]``), a key's the top byte."""
    if not isinstance(robots, list) or not robots:
        raise r.fail("robots", "expected a non-empty list of robot ids (jrl writes each char as a number)")
    out = []
    for n, c in enumerate(robots):
        if isinstance(c, int) and not isinstance(c, bool) and 0 < c < _ROBOT_ID_END:
            out.append(chr(c))
        elif isinstance(c, str) and len(c) == 1 and 0 < ord(c) < _ROBOT_ID_END:
            out.append(c)
        else:
            raise r.fail(
                f"robots[{n}]",
                f"expected a robot id, a char code 1..127 or a one-character string, got {json.dumps(c)[:40]}",
            )
    return out


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
    priors: list[_Prior] = field(default_factory=list)
    """The ``PriorFactorPose2/3`` factors, in reading order."""
    entry_sizes: dict[str, list[int]] = field(default_factory=dict)
    """Each robot's entries' numbers of measurements (what a FactorId may name)."""


@dataclass(frozen=True, eq=False)
class _Prior:
    """One ``PriorFactorPose2/3`` as read (key decoded; value and covariance as JSON)."""

    path: str
    kind: PoseKind
    pose: tuple[int, int]
    value: Any
    covariance: Any


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
    """Every robot's entries and their factors: Between and Prior factors kept, non-pose factors
    counted as skipped, anything else (or a kind mixed with the other) a FormatError."""
    out = _Factors()
    between = {v: k for k, v in _BETWEEN.items()}
    prior = {v: k for k, v in _PRIOR.items()}
    for c in keys.robots:
        entries = measurements.get(c, [])
        if not isinstance(entries, list):
            raise r.fail(f"measurements.{c}", "expected a list of entries")
        sizes = out.entry_sizes.setdefault(c, [])
        for e, entry in enumerate(entries):
            path = f"measurements.{c}[{e}]"
            stamp = r.uint(r.get(entry, "stamp", path), f"{path}.stamp")
            if stamp > _INT64_MAX:
                raise r.fail(f"{path}.stamp", f"stamp beyond the studio's int64 nanoseconds ({stamp})")
            out.first_stamp.setdefault(keys.position[ord(c)], stamp)
            factors = entry.get("measurements", []) if isinstance(entry, dict) else []
            if not isinstance(factors, list):
                raise r.fail(f"{path}.measurements", "expected a list of measurements")
            sizes.append(len(factors))
            for m, factor in enumerate(factors):
                fpath = f"{path}.measurements[{m}]"
                tag = r.get(factor, "type", fpath)
                if not isinstance(tag, str):
                    raise r.fail(f"{fpath}.type", "expected a type tag")
                if tag == _BEARING_RANGE:
                    out.bearing_range.append(_read_bearing_range(r, keys, factor, fpath, stamp))
                    continue
                if tag in prior:
                    key = keys.decode(r.uint(r.get(factor, "key", fpath), f"{fpath}.key"), f"{fpath}.key")
                    value, cov = r.get(factor, "prior", fpath), r.get(factor, "covariance", fpath)
                    out.priors.append(_Prior(fpath, prior[tag], key, value, cov))
                    continue
                if tag.startswith(_SKIPPED_TYPES):
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
    r: _Reader, keys: _Keys, data: dict[str, Any], section: str, kind: PoseKind, warn: Callable[[str], None] | None
) -> dict[int, dict[int, list[float]]] | None:
    """A values section (``initialization``, ``groundtruth``): robot position -> pose index -> pose
    row; None when the document has no such section.

    A robot's values hold every pose it observed, so a pose another robot owns can be listed by
    several robots (jrl's ``Dataset``: ground-truth copies must agree, initialization copies may
    differ). A pose takes its owner's value, where the owner lists it, else the first copy; ground-
    truth copies that disagree with it are counted in one warning."""
    block = data.get(section)
    if block is None:
        return None
    own: dict[int, dict[int, list[float]]] = {}
    copies: dict[int, dict[int, list[float]]] = {}
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
        mine = keys.position[ord(c)]
        for (a, i), pose, vpath in zip(decoded, poses, vpaths):
            if a == mine:
                robot = own.setdefault(a, {})
                if i in robot:  # its owner gives it twice: the second silently won
                    raise r.fail(f"{vpath}.key", f"pose {i} of robot {c!r} is given twice in {section}.{c}")
                robot[i] = pose
            else:
                copies.setdefault(a, {}).setdefault(i, pose)
    differ = 0
    for a, got in copies.items():
        have = own.setdefault(a, {})
        for i, pose in got.items():
            if i not in have:
                have[i] = pose
            elif not _same_pose(kind, have[i], pose):
                differ += 1
    if differ and section == "groundtruth" and warn is not None:
        warn(
            f"{r.where}: groundtruth: {differ} copies of other robots' poses differ from their owners' values "
            "(jrl requires them equal); the owners' values are kept"
        )
    return own


def _same_pose(kind: PoseKind, a: list[float], b: list[float]) -> bool:
    """Whether two pose rows are one pose (a quaternion and its negation are one rotation)."""
    if kind is PoseKind.SE2:
        return bool(np.allclose(a[:2], b[:2], rtol=0, atol=1e-9) and abs(np.angle(np.exp(1j * (a[2] - b[2])))) <= 1e-9)
    close_t = np.allclose(a[:3], b[:3], rtol=0, atol=1e-9)
    return bool(close_t and abs(abs(float(np.dot(a[3:], b[3:]))) - 1.0) <= 1e-12)


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


def _labelled_rows(
    r: _Reader, data: dict[str, Any], section: str, factors: _Factors, table: EdgeTable
) -> tuple[np.ndarray, int] | None:
    """``(k, 4)`` rows ``agent_from vertex_from agent_to vertex_to`` of the FactorIds of ``section``
    (``outlier_factors``, ``potential_outlier_factors``: robot -> ``[[entry, measurement], ...]``, as
    jrl's ``Parser`` reads a ``std::set<FactorId>``) and how many name a factor the graph does not
    hold (a prior, a skipped type); None when the document has no such section. A FactorId past its
    robot's entries or its entry's measurements is a FormatError."""
    labelled = data.get(section)
    if labelled is None:
        return None
    if not isinstance(labelled, dict):
        raise r.fail(section, "expected an object of robot -> [[entry, measurement], ...]")
    rows, elsewhere = [], 0
    listed: dict[tuple[str, int, int], str] = {}
    for c, pairs in labelled.items():
        if not isinstance(pairs, list):
            raise r.fail(f"{section}.{c}", "expected a list of [entry, measurement] pairs")
        sizes = factors.entry_sizes.get(c, [])
        for n, pair in enumerate(pairs):
            path = f"{section}.{c}[{n}]"
            if not (isinstance(pair, list) and len(pair) == 2 and all(type(x) is int and x >= 0 for x in pair)):
                raise r.fail(path, "expected a FactorId [entry, measurement] of two unsigned integers")
            e, m = pair
            if e >= len(sizes):
                raise r.fail(path, f"FactorId {pair} is out of range: measurements.{c} has {len(sizes)} entries")
            if m >= sizes[e]:
                raise r.fail(
                    path, f"FactorId {pair} is out of range: measurements.{c}[{e}] has {sizes[e]} measurements"
                )
            if (c, e, m) in listed:  # written (and counted) twice otherwise
                raise r.fail(path, f"{pair} is listed already ({listed[(c, e, m)]})")
            listed[(c, e, m)] = path
            row = factors.ids.get((c, e, m))
            if row is None:
                elsewhere += 1
                continue
            rows.append(
                (
                    int(table.from_agent[row]),
                    int(table.from_index[row]),
                    int(table.to_agent[row]),
                    int(table.to_index[row]),
                )
            )
    return np.array(rows, dtype=np.int64).reshape(-1, 4), elsewhere


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
