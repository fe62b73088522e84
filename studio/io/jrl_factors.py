"""A JRL dataset as jrl's ``Dataset`` holds it for scoring: the factors of each robot's measurements,
each robot's ground truth (its own poses and its copies of the other robots' poses it shares) and the
outlier labels, by FactorId. Read from a JRL document (a file's JSON, or the studio's export
:func:`studio.io.jrl.jrl_document`), which jrl's ``Parser::parseDataset`` reads the same way:

* ``measurements.<robot>[entry].measurements[m]`` is the factor with FactorId ``(entry, m)`` of that
  robot; ``BetweenFactorPose2/3`` and ``PriorFactorPose2/3`` are kept with their ``covariance``
  (row-major, GTSAM's tangent order) inverted; other factor types count as measurements (their
  FactorIds exist) but are left out of the mean residual and counted in ``skipped``.
* ``groundtruth.<robot>`` is that robot's list of values, shared poses included, as jrl's
  ``computeATE`` takes it with ``include_shared_variables`` (its default).
* ``potential_outlier_factors`` / ``outlier_factors``: per robot, FactorIds.

The studio's own graph reader (:mod:`studio.io.jrl`) turns the same document into a pose graph;
this module keeps what the graph does not hold (which robot's entry a factor is in, its FactorId,
the per-robot copies) and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studio.core.errors import FormatError
from studio.core.jrl_metrics import PoseFactors, RobotValues
from studio.core.model import PoseKind
from studio.io.jrr import kind_name, pose_rows, read_values, robot_id

__all__ = ["JrlDatasetView", "dataset_view"]

_POSE_FACTORS = {
    "BetweenFactorPose2": (PoseKind.SE2, False),
    "BetweenFactorPose3": (PoseKind.SE3, False),
    "PriorFactorPose2": (PoseKind.SE2, True),
    "PriorFactorPose3": (PoseKind.SE3, True),
}


@dataclass(frozen=True, eq=False)
class JrlDatasetView:
    """What jrl's metrics read of a dataset (see the module doc); per-robot tuples in ``robots`` order."""

    name: str
    robots: tuple[str, ...]
    kind: PoseKind
    factors: PoseFactors
    measured: tuple[set[tuple[int, int]], ...]
    """Per robot, the FactorId of every measurement (pose factor or not)."""
    groundtruth: tuple[RobotValues, ...] | None
    potential: tuple[set[tuple[int, int]], ...] | None
    outliers: tuple[set[tuple[int, int]], ...] | None
    skipped: dict[str, int] = field(default_factory=dict)


class _Collect:
    def __init__(self) -> None:
        self.kind: PoseKind | None = None
        self.key1: list[int] = []
        self.key2: list[int] = []
        self.meas: list[Any] = []
        self.cov: list[Any] = []
        self.paths: list[str] = []
        self.skipped: dict[str, int] = {}

    def add(self, factor: Any, where: str, path: str) -> None:
        tag = factor.get("type") if isinstance(factor, dict) else None
        if tag not in _POSE_FACTORS:
            self.skipped[str(tag)] = self.skipped.get(str(tag), 0) + 1
            return
        kind, prior = _POSE_FACTORS[tag]
        if self.kind is None:
            self.kind = kind
        elif kind is not self.kind:
            raise FormatError(f"{where}: {path}.type: {tag} mixed with {kind_name(self.kind)} factors")
        try:
            k1 = factor["key"] if prior else factor["key1"]
            k2 = -1 if prior else factor["key2"]
            self.meas.append(factor["measurement"])
            self.cov.append(factor["covariance"])
        except KeyError as err:
            raise FormatError(f"{where}: {path}: missing key {err.args[0]!r}") from None
        for k in (k1, k2):
            if isinstance(k, bool) or not isinstance(k, int) or not -1 <= k < 1 << 63:
                raise FormatError(f"{where}: {path}: expected GTSAM keys (integers below 2^63)")
        self.key1.append(k1)
        self.key2.append(k2)
        self.paths.append(path)

    def factors(self, where: str) -> PoseFactors:
        kind = self.kind or PoseKind.SE3
        d = 3 if kind is PoseKind.SE2 else 6
        meas = pose_rows(self.meas, kind, where, "", [f"{p}.measurement" for p in self.paths])
        try:
            cov = np.array(self.cov, dtype=np.float64).reshape(len(self.cov), d, d)
        except (TypeError, ValueError):
            bad = next(k for k, c in enumerate(self.cov) if not (isinstance(c, list) and len(c) == d * d))
            raise FormatError(f"{where}: {self.paths[bad]}.covariance: expected {d * d} numbers") from None
        sign, _ = np.linalg.slogdet(cov) if len(cov) else (np.ones(0), None)
        bad_cov = np.flatnonzero(~(sign > 0) | ~np.isfinite(cov).all(axis=(1, 2)))
        if bad_cov.size:
            raise FormatError(f"{where}: {self.paths[bad_cov[0]]}.covariance: not positive definite")
        info = np.linalg.inv(cov) if len(cov) else np.zeros((0, d, d))
        return PoseFactors(
            np.array(self.key1, dtype=np.int64),
            np.array(self.key2, dtype=np.int64),
            meas.reshape(-1, kind.pose_width),
            info,
        )


def _id_sets(
    doc: dict[str, Any], section: str, robots: tuple[str, ...], where: str
) -> tuple[set[tuple[int, int]], ...] | None:
    block = doc.get(section)
    if block is None:
        return None
    if not isinstance(block, dict):
        raise FormatError(f"{where}: {section}: expected an object from robot id to FactorIds")
    for c in block:
        if c not in robots:
            raise FormatError(f"{where}: {section}.{c}: robot {c!r} is not in robots {list(robots)}")
    out = []
    for c in robots:
        pairs = block.get(c, [])
        if not isinstance(pairs, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(x, int) for x in p) for p in pairs
        ):
            raise FormatError(f"{where}: {section}.{c}: expected a list of [entry, measurement] pairs")
        out.append({(p[0], p[1]) for p in pairs})
    return tuple(out)


def dataset_view(doc: Any, where: str) -> JrlDatasetView:
    """The :class:`JrlDatasetView` of a JRL document (``where`` names it in errors)."""
    if not isinstance(doc, dict):
        raise FormatError(f"{where}: expected a JSON object at the top")
    raw = doc.get("robots")
    if not isinstance(raw, list) or not raw:
        raise FormatError(f"{where}: robots: expected a non-empty list of robot ids")
    robots = tuple(robot_id(v, f"{where}: robots[{k}]") for k, v in enumerate(raw))
    measurements = doc.get("measurements")
    if not isinstance(measurements, dict):
        raise FormatError(f"{where}: measurements: expected an object from robot id to entries")
    for c in measurements:
        if c not in robots:
            raise FormatError(f"{where}: measurements.{c}: robot {c!r} is not in robots {list(robots)}")
    collect = _Collect()
    measured = []
    for c in robots:
        ids = set()
        entries = measurements.get(c, [])
        if not isinstance(entries, list):
            raise FormatError(f"{where}: measurements.{c}: expected a list of entries")
        for e, entry in enumerate(entries):
            factors = entry.get("measurements", []) if isinstance(entry, dict) else None
            if not isinstance(factors, list):
                raise FormatError(f"{where}: measurements.{c}[{e}]: expected an entry with a list of measurements")
            for m, factor in enumerate(factors):
                ids.add((e, m))
                collect.add(factor, where, f"measurements.{c}[{e}].measurements[{m}]")
        measured.append(ids)
    factors = collect.factors(where)
    kind = collect.kind or PoseKind.SE3
    truth = None
    if isinstance(doc.get("groundtruth"), dict):
        gt = doc["groundtruth"]
        truth = tuple(read_values(gt.get(c, []), where, f"groundtruth.{c}", kind)[0] for c in robots)
        truth = tuple(RobotValues(t.keys, t.poses.reshape(-1, kind.pose_width)) for t in truth)
    return JrlDatasetView(
        str(doc.get("name", "")),
        robots,
        kind,
        factors,
        tuple(measured),
        truth,
        _id_sets(doc, "potential_outlier_factors", robots, where),
        _id_sets(doc, "outlier_factors", robots, where),
        collect.skipped,
    )
