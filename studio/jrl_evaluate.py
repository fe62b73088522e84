"""JRL results and metrics as a pipeline: score a ``.jrr`` as jrl's ``computeMetricSummary`` does
(``include/jrl/Metrics-inl.h``, with its defaults: ATE aligned, without scale, shared variables
included, all entries) and write the ``.jrm``; build a ``.jrr`` from the studio's own estimates
(``studio solve``, ``studio replay``).

The dataset is a JRL file (``.jrl``/``.json``), or anything ``studio evaluate`` reads (a multi-g2o
folder, with its labelled outliers from ``outliers.txt`` when present), seen through the studio's
JRL export (:func:`studio.io.jrl.jrl_document`): the same FactorIds, priors and outlier labels a
MESA tool would read from ``studio export --format jrl``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import EvaluationError
from studio.core.jrl_metrics import RobotValues, ate, mean_residual, precision_recall, sve
from studio.core.model import PoseGraph, PoseKind
from studio.core.types import PathLike
from studio.io.jrl_factors import JrlDatasetView, dataset_view
from studio.io.jrm import MetricSummary
from studio.io.jrr import JrlResults

__all__ = [
    "factor_ids_of_edges",
    "metric_summary",
    "evaluate_jrr",
    "JrrEvaluation",
    "graph_results",
    "load_dataset_view",
    "format_summary",
]

_SHIFT = 56


def _symbol(key: int) -> str:
    c = key >> _SHIFT
    return f"{chr(c) if 32 < c < 127 else '?'}{key & ((1 << _SHIFT) - 1)}"


def _solutions(view: JrlDatasetView, results: JrlResults, where: str) -> list[RobotValues]:
    """The results' solutions in the dataset's robot order; a robot the dataset lacks fails."""
    for k, c in enumerate(results.robots):
        if c not in view.robots:
            raise EvaluationError(
                f"{where}: robots[{k}]: robot {c!r} is not in the dataset's robots {list(view.robots)}"
            )
    if results.kind is not view.kind:
        raise EvaluationError(
            f"{where}: the results hold {results.kind.value} poses, the dataset {view.kind.value} ones"
        )
    sol = dict(zip(results.robots, results.solutions))
    empty = RobotValues(np.zeros(0, np.int64), np.zeros((0, view.kind.pose_width)))
    return [sol.get(c, empty) for c in view.robots]


def _robot_ate(c: str, ref: RobotValues, est: RobotValues, where: str, partial: bool) -> tuple[float, float]:
    """jrl ``computeATE`` of robot ``c``; ``partial``: its ``allow_partial_results`` (only the
    ground-truth keys the robot's solution holds are scored), else a missing key fails."""
    missing = est.missing(ref.keys)
    if len(missing) and partial:
        held = ~np.isin(ref.keys, missing)
        ref = RobotValues(ref.keys[held], ref.poses[held])
    elif len(missing):
        k = int(missing[0])
        raise EvaluationError(
            f"{where}: solutions.{c}: robot {c!r} has no estimate of {_symbol(k)} (key {k}), which its ground "
            f"truth holds ({len(missing)} missing; partial results score only the poses each robot holds)"
        )
    return ate(est.take(ref.keys), ref.poses)


def _own(c: str, values: RobotValues) -> RobotValues:
    mine = (values.keys >> _SHIFT) == ord(c)
    return RobotValues(values.keys[mine], values.poses[mine])


def metric_summary(
    view: JrlDatasetView, results: JrlResults, *, where: str = "results", partial: bool = False
) -> MetricSummary:
    """jrl ``computeMetricSummary``: mean residual always; per-robot ATE, their sum and the joint
    aligned ATE with ground truth; SVE with more than one robot; precision and recall with
    potential and labelled outliers in the dataset and rejected outliers in the results. ``where``
    names the results in errors; ``partial``: ATE as jrl scores partial results
    (``allow_partial_results``: each robot over the ground-truth keys its solution holds, e.g. a
    replay's robots, which keep copies only of the poses they were sent)."""
    sols = _solutions(view, results, where)
    try:
        kw: dict[str, object] = {"mean_residual": mean_residual(view.factors, sols)}
    except EvaluationError as err:
        raise EvaluationError(f"{where}: {err}") from None
    if view.groundtruth is not None:
        per = {c: _robot_ate(c, ref, est, where, partial) for c, ref, est in zip(view.robots, view.groundtruth, sols)}
        kw["robot_ate"] = per
        kw["total_ate"] = (sum(v[0] for v in per.values()), sum(v[1] for v in per.values()))
        refs = [_own(c, g) for c, g in zip(view.robots, view.groundtruth)]
        ests = [e.take(r.keys) for r, e in zip(refs, sols)]
        kw["joint_aligned_ate"] = ate(np.concatenate(ests), np.concatenate([r.poses for r in refs]))
    if len(view.robots) > 1:
        kw["sve"] = sve([dict(zip(view.robots, sols))[c] for c in results.robots])
    if view.potential is not None and view.outliers is not None and results.outliers is not None:
        rejected = dict(zip(results.robots, results.outliers))
        rej = [{(int(e), int(m)) for e, m in rejected.get(c, np.zeros((0, 2), np.int64)).tolist()} for c in view.robots]
        total, per_robot = precision_recall(view.measured, view.potential, view.outliers, rej)
        kw["precision_recall"] = total
        kw["robot_precision_recall"] = {view.robots[k]: v for k, v in per_robot.items()}
    return MetricSummary(view.name, results.method_name, view.robots, **kw)  # type: ignore[arg-type]


def _is_jrl_file(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in (".jrl", ".json")


def load_dataset_view(dataset: PathLike) -> JrlDatasetView:
    """The :class:`JrlDatasetView` of a JRL file, or of the studio's JRL export of a multi-g2o
    folder (labelled outliers from its ``outliers.txt``) or single g2o file."""
    from studio.io.jrl import jrl_document
    from studio.io.jrr import load_json

    path = Path(dataset)
    if _is_jrl_file(path):
        doc, where = load_json(path, "JRL")
        return dataset_view(doc, where)
    graph, outliers = _read_graph(path)
    doc = jrl_document(graph, name=path.name, outliers=outliers)
    return dataset_view(doc, str(path))


def _single_g2o_graph(path: Path) -> PoseGraph:
    """A single g2o file as one robot, with its edges (the residual needs them) and, where
    ``NAME_GT.tum`` is beside it, its ground truth and stamps (else none, and ids as seconds)."""
    from studio.core.errors import FormatError
    from studio.core.units import NS_PER_S
    from studio.io.g2o import read_g2o
    from studio.io.graph_table import AgentPoses, EdgeTable, assemble_graph
    from studio.io.singleg2o import read_single_g2o_dataset

    doc = read_g2o(path)
    n = len(doc.vertex_ids)
    order = np.argsort(doc.vertex_ids, kind="stable")
    if n == 0 or not np.array_equal(doc.vertex_ids[order], np.arange(n)):
        raise FormatError(f"{path}: vertex ids must be 0..{max(n - 1, 0)} to be scored as JRL results")
    stamps, truth = np.arange(n, dtype=np.int64) * NS_PER_S, None
    if path.with_name(f"{path.stem}_GT.tum").is_file():
        agent = read_single_g2o_dataset(path).agents[0]
        stamps, truth = agent.stamps_ns, agent.ground_truth
    rows = np.zeros(len(doc.edge_from), dtype=np.int64)
    table = EdgeTable(
        doc.kind, rows, doc.edge_from, rows, doc.edge_to, doc.edge_measurements, doc.edge_information_upper
    )
    agent_poses = AgentPoses(path.stem, stamps, doc.vertex_poses[order], truth)
    return assemble_graph([agent_poses], table, where=str(path), metadata={"source": str(path)})


def _read_graph(path: Path) -> tuple[PoseGraph, np.ndarray | None]:
    from studio.io.multig2o import read_multi_g2o

    if path.is_file():
        return _single_g2o_graph(path), None
    graph = read_multi_g2o(path)
    labels = path / "outliers.txt"
    if not labels.is_file():
        return graph, None
    from studio.io.outliers_txt import read_outliers_txt

    return graph, read_outliers_txt(labels, [a.num_poses for a in graph.agents])[0]


@dataclass(frozen=True, eq=False)
class JrrEvaluation:
    summary: MetricSummary
    jrm_path: Path
    skipped: dict[str, int]


def evaluate_jrr(
    dataset: PathLike, jrr: PathLike, *, jrm: PathLike | None = None, force: bool = False, partial: bool = False
) -> JrrEvaluation:
    """Score the ``.jrr`` ``jrr`` on ``dataset`` (:func:`metric_summary`, ``partial`` as there) and
    write the ``.jrm`` (default: beside the ``.jrr``, same stem) through the output guard."""
    from studio.io.atomic import check_outputs, staged_outputs
    from studio.io.jrm import write_jrm
    from studio.io.jrr import read_jrr

    out = Path(jrm) if jrm is not None else Path(jrr).with_suffix(".jrm")
    if out.suffix != ".jrm":
        raise EvaluationError(f"{out}: a JRL metrics file must end in .jrm")
    check_outputs(out.parent, [out.name], force=force, inputs=[dataset, jrr])  # every refusal before any work
    results = read_jrr(jrr)
    view = load_dataset_view(dataset)
    summary = metric_summary(view, results, where=str(jrr), partial=partial)
    with staged_outputs(out.parent, [out.name], force=force, inputs=[dataset, jrr]) as staging:
        write_jrm(staging / out.name, summary)
    return JrrEvaluation(summary, out, view.skipped)


def _fmt(p: tuple[float, float] | None, unit: str = "m / rad") -> str:
    if p is not None and all(np.isnan(p)):
        return "- (no variable is shared)"
    return "-" if p is None else f"{p[0]:.6g}, {p[1]:.6g}  ({unit})"


def format_summary(summary: MetricSummary) -> str:
    """The metrics as lines of text (translation, rotation)."""
    lines = [f"dataset: {summary.dataset_name}", f"method:  {summary.method_name}"]
    for c, v in (summary.robot_ate or {}).items():
        lines.append(f"ATE robot {c}:        {_fmt(v)}")
    lines.append(f"ATE total:          {_fmt(summary.total_ate)}")
    lines.append(f"ATE joint aligned:  {_fmt(summary.joint_aligned_ate)}")
    lines.append(f"SVE:                {_fmt(summary.sve)}")
    mr = summary.mean_residual
    lines.append(f"mean residual:      {'-' if mr is None else f'{mr:.9g}'}")
    lines.append(f"precision, recall:  {_fmt(summary.precision_recall, 'inliers positive')}")
    return "\n".join(lines) + "\n"


def graph_results(
    kind: PoseKind,
    robots: list[str],
    own: list[np.ndarray],
    *,
    dataset_name: str,
    method_name: str,
    shared: list[tuple[np.ndarray, np.ndarray]] | None = None,
    outliers: list[np.ndarray] | None = None,
) -> JrlResults:
    """A :class:`JrlResults` of per-robot estimates: robot ``k`` (character ``robots[k]``) holds its
    own poses ``own[k]`` (pose ``i`` is Symbol ``robots[k]`` ``i``) and, with ``shared``, ``(keys,
    poses)`` of the other robots' poses it keeps."""
    sols = []
    for k, (c, poses) in enumerate(zip(robots, own)):
        keys = (ord(c) << _SHIFT) + np.arange(len(poses), dtype=np.int64)
        rows = np.asarray(poses, dtype=np.float64)
        if shared is not None and len(shared[k][0]):
            keys = np.concatenate([keys, shared[k][0]])
            rows = np.concatenate([rows, shared[k][1]])
        order = np.argsort(keys, kind="stable")
        sols.append(RobotValues(keys[order], rows[order]))
    return JrlResults(
        dataset_name,
        method_name,
        tuple(robots),
        kind,
        tuple(sols),
        None if outliers is None else tuple(np.asarray(o, dtype=np.int64).reshape(-1, 2) for o in outliers),
    )


def factor_ids_of_edges(doc: dict[str, Any], keys: np.ndarray) -> dict[str, np.ndarray]:
    """Per robot of a JRL document, the FactorIds ``(entry, measurement)`` of the between factors
    whose ``(key1, key2)`` are rows of ``keys`` (``(k, 2)`` int64); a pair listed twice takes two
    factors of those keys, in the document's order (repeated measurements)."""
    wanted = Counter(map(tuple, np.asarray(keys, dtype=np.int64).reshape(-1, 2).tolist()))
    out: dict[str, list[list[int]]] = {}
    for c, entries in doc["measurements"].items():
        found = out.setdefault(c, [])
        for e, entry in enumerate(entries):
            for m, factor in enumerate(entry.get("measurements", [])):
                pair = (factor.get("key1"), factor.get("key2"))
                if wanted.get(pair, 0) > 0:  # type: ignore[call-overload]
                    wanted[pair] -= 1  # type: ignore[index]
                    found.append([e, m])
    return {c: np.array(v, dtype=np.int64).reshape(-1, 2) for c, v in out.items()}
