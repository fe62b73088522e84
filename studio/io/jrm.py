"""JRL metrics (``.jrm``, "JSON Robot Metrics"): jrl's ``MetricSummary``, as jrl writes and reads it.

The layout is what jrl's code writes (``Writer::writeMetricSummary``, ``src/Writer.cpp``) and reads
(``Parser::parseMetricSummary``, ``src/Parser.cpp``), which differs from ``format/METRIC_FORMAT.md``
where nlohmann's JSON decides: robot ids are integers (``char``), and a ``std::map<char, pair>``
(its key not a string) is written as a list of ``[key, [a, b]]`` pairs, not an object::

    {"dataset_name": NAME, "method_name": METHOD, "robots": [97, 98],
     "robot_ate": [[97, [t, r]], [98, [t, r]]], "total_ate": [t, r],
     "joint_aligned_ate": [t, r], "sve": [t, r], "mean_residual": x,
     "robot_precision_recall": [[97, [p, r]], ...], "precision_recall": [p, r]}

Every field after ``robots`` is optional (jrl writes what it could compute). Translations are in
metres, rotations in radians. A NaN (jrl's SVE with no shared variable) is written ``null``, as
nlohmann writes a NaN; reading gives it back as NaN. Keys are written sorted, the JSON compact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from studio.core.errors import FormatError, OutputError
from studio.core.jrl_metrics import PoseError
from studio.core.types import PathLike
from studio.io.jrr import load_json, robot_id

__all__ = ["MetricSummary", "write_jrm", "read_jrm", "jrm_document"]


@dataclass(frozen=True)
class MetricSummary:
    """jrl's ``MetricSummary`` (``include/jrl/Metrics.h``); None where a metric was not computed."""

    dataset_name: str
    method_name: str
    robots: tuple[str, ...]
    robot_ate: dict[str, PoseError] | None = None
    total_ate: PoseError | None = None
    joint_aligned_ate: PoseError | None = None
    sve: PoseError | None = None
    mean_residual: float | None = None
    robot_precision_recall: dict[str, PoseError] | None = None
    precision_recall: PoseError | None = None


def _num(x: float) -> float | None:
    return None if math.isnan(x) else x


def _pair(p: PoseError) -> list[float | None]:
    return [_num(p[0]), _num(p[1])]


def jrm_document(summary: MetricSummary) -> dict[str, Any]:
    """The JSON object jrl's ``Writer::writeMetricSummary`` writes (see the module doc)."""
    doc: dict[str, Any] = {
        "dataset_name": summary.dataset_name,
        "method_name": summary.method_name,
        "robots": [ord(c) for c in summary.robots],
    }
    for name in ("robot_ate", "robot_precision_recall"):
        per: dict[str, PoseError] | None = getattr(summary, name)
        if per is not None:
            doc[name] = [[ord(c), _pair(v)] for c, v in sorted(per.items(), key=lambda cv: ord(cv[0]))]
    for name in ("total_ate", "joint_aligned_ate", "sve", "precision_recall"):
        pair: PoseError | None = getattr(summary, name)
        if pair is not None:
            doc[name] = _pair(pair)
    if summary.mean_residual is not None:
        doc["mean_residual"] = _num(summary.mean_residual)
    return dict(sorted(doc.items()))


def write_jrm(path: PathLike, summary: MetricSummary) -> None:
    """Write ``summary`` as a ``.jrm`` at ``path`` (call it inside the caller's output guard)."""
    import json

    for v in (summary.mean_residual, *(summary.total_ate or ()), *(summary.sve or ())):
        if v is not None and math.isinf(v):
            raise OutputError(f"{path}: a metric is infinite; nothing written")
    text = json.dumps(jrm_document(summary), separators=(",", ":"), sort_keys=True, allow_nan=False)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def _read_num(v: Any, where: str) -> float:
    if v is None:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FormatError(f"{where}: expected a number")
    return float(v)


def _read_pair(v: Any, where: str) -> PoseError:
    if not isinstance(v, list) or len(v) != 2:
        raise FormatError(f"{where}: expected a pair [a, b]")
    return _read_num(v[0], f"{where}[0]"), _read_num(v[1], f"{where}[1]")


def _read_per_robot(v: Any, where: str) -> dict[str, PoseError]:
    if not isinstance(v, list):
        raise FormatError(f"{where}: expected a list of [robot, [a, b]] pairs")
    out = {}
    for n, item in enumerate(v):
        if not isinstance(item, list) or len(item) != 2:
            raise FormatError(f"{where}[{n}]: expected [robot, [a, b]]")
        out[robot_id(item[0], f"{where}[{n}][0]")] = _read_pair(item[1], f"{where}[{n}][1]")
    return out


def read_jrm(source: PathLike) -> MetricSummary:
    """Read a ``.jrm`` (see the module doc)."""
    doc, where = load_json(source, ".jrm")
    if not isinstance(doc, dict):
        raise FormatError(f"{where}: expected a JSON object at the top")
    for field in ("dataset_name", "method_name"):
        if not isinstance(doc.get(field), str):
            raise FormatError(f"{where}: {field}: expected a string")
    robots = doc.get("robots")
    if not isinstance(robots, list):
        raise FormatError(f"{where}: robots: expected a list of robot ids")
    ids = tuple(robot_id(v, f"{where}: robots[{k}]") for k, v in enumerate(robots))
    kw: dict[str, Any] = {}
    for name in ("robot_ate", "robot_precision_recall"):
        if name in doc:
            kw[name] = _read_per_robot(doc[name], f"{where}: {name}")
    for name in ("total_ate", "joint_aligned_ate", "sve", "precision_recall"):
        if name in doc:
            kw[name] = _read_pair(doc[name], f"{where}: {name}")
    if "mean_residual" in doc:
        kw["mean_residual"] = _read_num(doc["mean_residual"], f"{where}: mean_residual")
    return MetricSummary(doc["dataset_name"], doc["method_name"], ids, **kw)
