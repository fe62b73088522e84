"""JRL results (``.jrr``, "JSON Robot Results"): every robot's solution, as jrl writes and reads them.

The layout is the one jrl's code writes (``Writer::writeResults``, ``src/Writer.cpp``) and reads
(``Parser::parseResults``, ``src/Parser.cpp``), which differs from ``format/RESULT_FORMATS.md`` in
the robot ids (``char``, which nlohmann's JSON writes as integers)::

    {"dataset_name": NAME, "method_name": METHOD,
     "robots": [97, 98, ...],
     "solutions": {"a": [{"key": K, "rotation": [w, x, y, z], "translation": [x, y, z],
                          "type": "Pose3"}, ...], "b": [...]},
     "outliers":  {"a": [[entry, measurement], ...], ...}}          # optional

* ``solutions`` are keyed by the robot's character (``std::string(1, robot)``); each robot's list
  holds every value that robot estimates, its own poses and its copies of other robots' poses it
  shares (the same key may appear under several robots with different values). Keys are GTSAM
  Symbols (``robot char << 56 | index``); values ``Pose3`` (``rotation`` is ``[w, x, y, z]``,
  ``toQuaternion().coeffs()`` reordered) or ``Pose2`` (``x``, ``y``, ``theta``), written in
  ascending key order (``ValueTypes`` is a ``std::map``).
* ``outliers`` are, per robot, the FactorIds ``[entry index, measurement index]`` of the robot's
  measurements that the method rejected (``Results::robot_outliers``).
* Object keys are written sorted and the JSON compact, as nlohmann's ``std::map`` objects and
  ``operator<<`` write them.

Reading also accepts robot ids written as one-character strings (hand-written files). A robot
that ``solutions`` or ``outliers`` names but ``robots`` does not, a value of another type, a
non-finite number, a quaternion off unit length by more than 1e-5 (normalised within it, as
GTSAM's ``Rot3::Quaternion``) or a key listed twice for one robot is a :class:`FormatError` naming
the file and the JSON path.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import FormatError
from studio.core.jrl_metrics import RobotValues
from studio.core.model import PoseKind
from studio.core.types import PathLike
from studio.io.g2o import MAX_TEXT_BYTES
from studio.io.strict_json import dumps_strict

__all__ = [
    "pose_rows",
    "read_values",
    "kind_name",
    "JrlResults",
    "read_jrr",
    "write_jrr",
    "jrr_document",
    "robot_id",
    "load_json",
    "QUAT_TOLERANCE",
]

#: How far from unit length a quaternion may be and still be read (then normalised).
QUAT_TOLERANCE = 1e-5
_TYPES = {"Pose2": PoseKind.SE2, "Pose3": PoseKind.SE3}


@dataclass(frozen=True, eq=False)
class JrlResults:
    """jrl's ``Results``: per robot (in ``robots`` order) its solution and, optionally, the
    FactorIds of its measurements it rejected as outliers."""

    dataset_name: str
    method_name: str
    robots: tuple[str, ...]
    """One-character robot ids."""
    kind: PoseKind
    solutions: tuple[RobotValues, ...]
    outliers: tuple[np.ndarray, ...] | None = None
    """Per robot, ``(k, 2)`` int64 rows ``entry measurement``; None when the file has none."""


def _pose_dict(kind: PoseKind, key: int, row: list[float]) -> dict[str, Any]:
    if kind is PoseKind.SE2:
        x, y, theta = row
        return {"key": key, "theta": theta, "type": "Pose2", "x": x, "y": y}
    x, y, z, qx, qy, qz, qw = row
    return {"key": key, "rotation": [qw, qx, qy, qz], "translation": [x, y, z], "type": "Pose3"}


def jrr_document(results: JrlResults) -> dict[str, Any]:
    """The JSON object jrl's ``Writer::writeResults`` writes for ``results`` (see the module doc)."""
    solutions = {}
    for c, sol in zip(results.robots, results.solutions):
        order = np.argsort(sol.keys, kind="stable")
        keys, rows = sol.keys[order].tolist(), sol.poses[order].tolist()
        solutions[c] = [_pose_dict(results.kind, k, r) for k, r in zip(keys, rows)]
    doc: dict[str, Any] = {
        "dataset_name": results.dataset_name,
        "method_name": results.method_name,
        "robots": [ord(c) for c in results.robots],
        "solutions": solutions,
    }
    if results.outliers is not None:
        doc["outliers"] = {
            c: sorted(map(list, np.asarray(o, dtype=np.int64).reshape(-1, 2).tolist()))
            for c, o in zip(results.robots, results.outliers)
        }
    return dict(sorted(doc.items()))


def write_jrr(path: PathLike, results: JrlResults) -> None:
    """Write ``results`` as a ``.jrr`` at ``path`` (call it inside the caller's output guard)."""
    text = dumps_strict(jrr_document(results), str(path), separators=(",", ":"), sort_keys=True)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def load_json(source: PathLike, what: str) -> tuple[Any, str]:
    """The JSON document of ``source`` (a ``what`` file), or a one-line :class:`FormatError`."""
    path = Path(source)
    try:
        if path.is_dir():
            raise FormatError(f"{path}: is a folder, not a {what} file")
        if path.stat().st_size > MAX_TEXT_BYTES:
            raise FormatError(f"{path}: over the {MAX_TEXT_BYTES} byte (1 GiB) limit of text inputs")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FormatError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise FormatError(f"{path}: not UTF-8 text") from None
    except OSError as err:
        raise FormatError(f"{path}: cannot read ({err.strerror})") from None
    try:
        return json.loads(text), str(path)
    except json.JSONDecodeError as err:
        raise FormatError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    except RecursionError:
        raise FormatError(f"{path}: JSON nested too deeply") from None


def robot_id(value: Any, where: str) -> str:
    """A robot id as jrl writes it (the ``char`` as an integer) or as a one-character string."""
    if isinstance(value, int) and not isinstance(value, bool) and 0 < value < 128:
        return chr(value)
    if isinstance(value, str) and len(value) == 1:
        return value
    raise FormatError(f"{where}: expected a robot id (a character code 1..127 or a one-character string)")


def _robots(doc: dict[str, Any], where: str) -> tuple[str, ...]:
    robots = doc.get("robots")
    if not isinstance(robots, list) or not robots:
        raise FormatError(f"{where}: robots: expected a non-empty list of robot ids")
    ids = tuple(robot_id(v, f"{where}: robots[{k}]") for k, v in enumerate(robots))
    if len(set(ids)) != len(ids):
        raise FormatError(f"{where}: robots: a robot id is listed twice")
    return ids


def pose_rows(values: list[Any], kind: PoseKind, where: str, path: str, paths: list[str] | None = None) -> np.ndarray:
    """``(n, width)`` pose rows of value objects (``x y theta`` or ``x y z qx qy qz qw``); errors
    name ``path[n]``, or ``paths[n]`` when given."""
    try:  # the fast path; anything odd is found and named by the checks below
        if kind is PoseKind.SE2:
            raw = np.array([[v["x"], v["y"], v["theta"]] for v in values]).reshape(-1, 3)
        else:
            if any(len(v["translation"]) != 3 for v in values):
                raise TypeError
            raw = np.array([[*v["translation"], *v["rotation"]] for v in values]).reshape(-1, 7)
        # a string among the numbers makes a text array (numpy would parse "1" as 1.0 if asked for floats)
        fast = raw.astype(np.float64) if raw.dtype.kind in "fiu" else np.full(raw.shape, np.nan)
        if kind is PoseKind.SE3:
            fast = fast[:, [0, 1, 2, 4, 5, 6, 3]]
        if np.isfinite(fast).all() and len(fast) == len(values):
            return _unit_quaternions(fast, kind, where, path, paths)
    except (KeyError, TypeError, ValueError):
        pass
    rows = []
    for n, v in enumerate(values):
        vpath = paths[n] if paths is not None else f"{path}[{n}]"
        try:
            if kind is PoseKind.SE2:
                row = [v["x"], v["y"], v["theta"]]
            else:
                t, q = v["translation"], v["rotation"]
                if not (isinstance(t, list) and len(t) == 3 and isinstance(q, list) and len(q) == 4):
                    raise TypeError
                row = [*t, q[1], q[2], q[3], q[0]]
        except (KeyError, TypeError):
            need = "x, y, theta" if kind is PoseKind.SE2 else "translation [3] and rotation [4]"
            raise FormatError(f"{where}: {vpath}: a {kind_name(kind)} value needs {need}") from None
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in row):
            raise FormatError(f"{where}: {vpath}: not a finite number in the pose")
        rows.append(row)
    out = np.array(rows, dtype=np.float64).reshape(len(rows), 3 if kind is PoseKind.SE2 else 7)
    return _unit_quaternions(out, kind, where, path, paths)


def _unit_quaternions(out: np.ndarray, kind: PoseKind, where: str, path: str, paths: list[str] | None) -> np.ndarray:
    """``out`` with its quaternions normalised; one off unit length beyond the tolerance fails."""
    if kind is PoseKind.SE3 and len(out):
        norms = np.linalg.norm(out[:, 3:7], axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > QUAT_TOLERANCE)
        if bad.size:
            at = paths[int(bad[0])] if paths is not None else f"{path}[{int(bad[0])}]"
            raise FormatError(f"{where}: {at}.rotation: quaternion is not unit length (norm {norms[bad[0]]:.9g})")
        out[:, 3:7] /= norms[:, None]
    return out


def kind_name(kind: PoseKind) -> str:
    return "Pose2" if kind is PoseKind.SE2 else "Pose3"


def read_values(values: Any, where: str, path: str, kind: PoseKind | None) -> tuple[RobotValues, PoseKind | None]:
    """A list of JRL value objects (``Pose2`` or ``Pose3``, one kind in a file) as :class:`RobotValues`."""
    if not isinstance(values, list):
        raise FormatError(f"{where}: {path}: expected a list of values")
    keys = []
    for n, v in enumerate(values):
        if not isinstance(v, dict):
            raise FormatError(f"{where}: {path}[{n}]: expected a value object")
        key, tag = v.get("key"), v.get("type")
        if isinstance(key, bool) or not isinstance(key, int) or not 0 <= key < 1 << 63:
            raise FormatError(f"{where}: {path}[{n}].key: expected a GTSAM key (an integer below 2^63)")
        if tag not in _TYPES:
            raise FormatError(f"{where}: {path}[{n}].type: expected Pose2 or Pose3, got {str(tag)[:40]!r}")
        if kind is None:
            kind = _TYPES[tag]
        elif _TYPES[tag] is not kind:
            raise FormatError(f"{where}: {path}[{n}].type: {tag} mixed with {kind_name(kind)} values")
        keys.append(key)
    if kind is None:
        return RobotValues(np.zeros(0, np.int64), np.zeros((0, 7))), None
    poses = pose_rows(values, kind, where, path)
    k = np.array(keys, dtype=np.int64)
    order = np.argsort(k, kind="stable")
    k, poses = k[order], poses[order]
    dup = np.flatnonzero(k[1:] == k[:-1])
    if dup.size:
        raise FormatError(f"{where}: {path}: key {int(k[dup[0]])} is listed twice")
    return RobotValues(k, poses), kind


def _factor_ids(block: Any, where: str, path: str) -> np.ndarray:
    if not isinstance(block, list) or not all(
        isinstance(p, list)
        and len(p) == 2
        and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in p)
        for p in block
    ):
        raise FormatError(f"{where}: {path}: expected a list of [entry, measurement] pairs")
    return np.array(block, dtype=np.int64).reshape(-1, 2)


def read_jrr(source: PathLike) -> JrlResults:
    """Read a ``.jrr`` (see the module doc)."""
    doc, where = load_json(source, ".jrr")
    if not isinstance(doc, dict):
        raise FormatError(f"{where}: expected a JSON object at the top")
    names = []
    for field in ("dataset_name", "method_name"):
        if not isinstance(doc.get(field), str):
            raise FormatError(f"{where}: {field}: expected a string")
        names.append(doc[field])
    robots = _robots(doc, where)
    solutions = doc.get("solutions")
    if not isinstance(solutions, dict):
        raise FormatError(f"{where}: solutions: expected an object from robot id to values")
    for c in solutions:
        if c not in robots:
            raise FormatError(f"{where}: solutions.{c}: robot {c!r} is not in robots {list(robots)}")
    kind: PoseKind | None = None
    sols = []
    for c in robots:
        sol, kind = read_values(solutions.get(c, []), where, f"solutions.{c}", kind)
        sols.append(sol)
    if kind is None:
        raise FormatError(f"{where}: solutions: no Pose2 or Pose3 value")
    if kind is PoseKind.SE2:
        sols = [RobotValues(s.keys, s.poses.reshape(-1, 3)) if not len(s.keys) else s for s in sols]
    outliers = None
    if "outliers" in doc:
        block = doc["outliers"]
        if not isinstance(block, dict):
            raise FormatError(f"{where}: outliers: expected an object from robot id to FactorIds")
        for c in block:
            if c not in robots:
                raise FormatError(f"{where}: outliers.{c}: robot {c!r} is not in robots {list(robots)}")
        outliers = tuple(_factor_ids(block.get(c, []), where, f"outliers.{c}") for c in robots)
    return JrlResults(names[0], names[1], robots, kind, tuple(sols), outliers)
