"""``studio check`` as a library function: is a dataset's noise model consistent with its errors?

At the ground truth, each edge's error ``e`` (g2o's, see :mod:`studio.core.residuals`) and its
written information ``Omega`` give ``chi2 = e^T Omega e``. If the measurements were drawn from the
Gaussian the information claims, the sum over ``n`` edges of dimension ``d`` follows a chi-square
distribution with ``n d`` degrees of freedom: its mean per degree of freedom (the **factor**) is 1.
The report gives, per edge class (odometry, intra-agent and inter-agent loop closures), per agent
and per component (translation, rotation), the chi2, the degrees of freedom and the factor, with a
verdict:

* ``consistent``: the total is within the chi-square distribution's central 99.9 % interval, or
  the factor is within 10 % of 1 (with tens of thousands of edges a 2 % mismatch is "significant"
  without mattering to anyone);
* ``over-confident x F``: errors F times larger (in chi2) than the information says;
* ``under-confident x F``: errors smaller than the information says (F < 1).

Outlier candidates are edges whose chi2 exceeds the chi-square quantile 1 - 1e-6 of their dimension,
after scaling by the class's robust scale (its median chi2 over the distribution's median, at least
1), so a mis-scaled class does not flag all its edges. When a class's candidates are at most 10 % of
its edges they are left out of its sums (a few gross outliers would otherwise swamp the factor) and
the report says how many; more than that is a systematic mismatch and stays in. Where the dataset
lists its outliers (``outliers.txt``, written by ``studio convert``), the report says how many were
flagged.

3D datasets whose poses and measurements are all planar (kollagen's 3D records of its planar walk)
are checked in SE(2), as ``studio solve`` solves them. For 3D data the rotation error follows
``convention``: ``g2o`` (the quaternion's vector part, about half the angle: what g2o's
``EDGE_SE3:QUAT`` computes and what the studio's writers' information refers to) or ``rotvec`` (the
rotation vector, as GTSAM's ``readG2o`` + ``BetweenFactorPose3`` use the same numbers).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from studio.check_sightings import RangeBearingCheck, check_range_bearing, format_range_bearing_check
from studio.core.errors import FormatError
from studio.core.geometry import block_diagonal_where_indefinite, is_planar_se3, se3_information_to_se2
from studio.core.model import PoseKind
from studio.core.residuals import Convention, chi2_parts, chi2_terms, edge_errors
from studio.core.types import PathLike
from studio.solvers.validate import indefinite_information

__all__ = ["ClassCheck", "CheckReport", "check", "format_check", "CONSISTENT_TOLERANCE", "SIGNIFICANCE"]

#: Factors within this distance of 1 are called consistent whatever their significance.
CONSISTENT_TOLERANCE = 0.10
#: Two-sided significance of the chi-square test of a class.
SIGNIFICANCE = 1e-3
#: Tail probability above which an edge is an outlier candidate.
OUTLIER_TAIL = 1e-6
#: A class's candidates are left out of its sums when they are at most this fraction of its edges.
MAX_EXCLUDED_FRACTION = 0.10


@dataclass(frozen=True)
class Component:
    chi2: float
    dof: int

    @property
    def factor(self) -> float:
        return self.chi2 / self.dof if self.dof else math.nan


def verdict(chi2: float, dof: int) -> str:
    """``consistent``, ``over-confident x F`` or ``under-confident x F`` (see the module doc)."""
    from scipy.stats import chi2 as chi2_dist

    if dof == 0:
        return "no edges"
    factor = chi2 / dof
    lo, hi = chi2_dist.ppf(SIGNIFICANCE / 2, dof), chi2_dist.ppf(1 - SIGNIFICANCE / 2, dof)
    if lo <= chi2 <= hi or abs(factor - 1.0) <= CONSISTENT_TOLERANCE:
        return "consistent"
    return f"{'over' if factor > 1 else 'under'}-confident x {factor:.3g}"


@dataclass(frozen=True)
class ClassCheck:
    """One edge class (optionally of one agent)."""

    name: str
    agent: str
    """An agent's name, or ``all``."""
    edges: int
    total: Component
    translation: Component
    rotation: Component
    excluded: int = 0
    """Outlier candidates left out of the sums (when they are rare, see the module doc)."""

    @property
    def verdicts(self) -> dict[str, str]:
        return {
            part: verdict(c.chi2, c.dof)
            for part, c in (("total", self.total), ("translation", self.translation), ("rotation", self.rotation))
        }

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "class": self.name,
            "agent": self.agent,
            "edges": self.edges,
            "excluded_outlier_candidates": self.excluded,
        }
        for part in ("total", "translation", "rotation"):
            c = getattr(self, part)
            out[part] = {"chi2": c.chi2, "dof": c.dof, "factor": c.factor, "verdict": verdict(c.chi2, c.dof)}
        return out


@dataclass(frozen=True, eq=False)
class CheckReport:
    dataset: str
    kind: PoseKind
    """The kind the check ran in (SE2 for planar 3D data)."""
    convention: Convention
    classes: tuple[ClassCheck, ...]
    outliers: np.ndarray
    """Candidate rows ``from_agent from_vertex to_agent to_vertex chi2`` (agents and vertices 0-based)."""
    listed_outliers: int | None = None
    """Outliers the dataset lists (``outliers.txt``), or None where it lists none."""
    listed_flagged: int | None = None
    """How many of the listed outliers are among the candidates."""
    notes: tuple[str, ...] = field(default=())
    range_bearing: RangeBearingCheck | None = None
    """The dataset's range-bearing sightings at the ground truth (studio/check_sightings.py)."""

    def summary(self, name: str) -> ClassCheck:
        return next(c for c in self.classes if c.name == name and c.agent == "all")

    def to_dict(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset,
            "checked_as": self.kind.value,
            "rotation_convention": self.convention,
            "classes": [c.to_dict() for c in self.classes],
            "outlier_candidates": [
                {
                    "from_agent": int(r[0]),
                    "from_vertex": int(r[1]),
                    "to_agent": int(r[2]),
                    "to_vertex": int(r[3]),
                    "chi2": float(r[4]),
                }
                for r in self.outliers
            ],
            "listed_outliers": self.listed_outliers,
            "listed_outliers_flagged": self.listed_flagged,
            "notes": list(self.notes),
            **({"range_bearing": self.range_bearing.to_dict()} if self.range_bearing is not None else {}),
        }

    def to_json(self) -> str:
        return json.dumps(_strict(self.to_dict()), indent=2, allow_nan=False)


def _read_listed_outliers(folder: Path, agent_sizes: list[int] | None) -> np.ndarray | None:
    """``outliers.txt`` through the one reader (:mod:`studio.io.outliers_txt`), checked against the
    dataset's agents and vertices as ``studio record`` checks it."""
    from studio.io.outliers_txt import read_outliers_txt

    path = folder / "outliers.txt"
    if not path.is_file():
        return None
    return read_outliers_txt(path, agent_sizes)[0]


def _strict(value: Any) -> Any:
    """``value`` with every non-finite float as None: the JSON printed is strict (no NaN, Infinity)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


#: Edge classes in report order (``loop closures``: a single g2o file cannot tell intra from inter).
CLASSES = ("odometry", "intra", "inter", "loop closures")

EdgeSet = tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _multi_g2o(
    graph: Any, folder: Path, notes: list[str]
) -> tuple[PoseKind, list[np.ndarray], list[EdgeSet], list[str]]:
    """A multi-g2o folder at its ground truth; agents without one (distributed-mapper's examples
    converted) are checked at their own poses, said in a note."""
    missing = [a.name for a in graph.agents if a.ground_truth is None]
    if missing:
        notes.append(
            f"no ground truth for {len(missing)} of {len(graph.agents)} agents (the first: {missing[0]}): "
            "they are checked at their own poses, so their factors say how the initial estimate fits the edges"
        )
    sets: list[EdgeSet] = []
    for k, a in enumerate(graph.agents):
        for name, edges in (("odometry", a.odometry), ("intra", a.loop_closures)):
            ks = np.full(len(edges), k)
            sets.append((name, ks, edges.from_index, ks, edges.to_index, edges.measurements, edges.information_upper))
    i = graph.inter
    sets.append(("inter", i.from_agent, i.from_index, i.to_agent, i.to_index, i.measurements, i.information_upper))
    truth = [a.initial if a.ground_truth is None else a.ground_truth for a in graph.agents]
    return graph.kind, truth, sets, [a.name for a in graph.agents]


def _single_g2o(
    path: Path, warn: Callable[[str], None] | None
) -> tuple[PoseKind, list[np.ndarray], list[EdgeSet], list[str], list[str]]:
    """A single g2o file as ``studio convert g2o`` reads it, at its ground truth (``NAME_GT.tum``
    beside it, kollagen's single view) or, without one, at the file's own poses (its vertices, or
    for a file of edges only the poses composed along a spanning tree of its edges), said in a note.
    Edges between consecutive ids are odometry (kollagen's connectors included), others loop
    closures; the last item is the notes."""
    from studio.converters.g2o import read_single_g2o

    single = read_single_g2o(path, warn=warn)
    notes = []
    truth = single.ground_truth
    if truth is None:
        truth = single.initial
        notes.append(
            f"no ground truth beside it ({path.stem}_GT.tum): checked at the file's own poses (its vertices, or "
            "poses composed along its edges), so the factors say how its initial estimate fits its edges"
        )
    info = single.information_upper
    fr, to = single.from_index, single.to_index
    odo = to == fr + 1
    zeros = np.zeros(len(fr), dtype=np.int64)
    sets: list[EdgeSet] = [
        (name, zeros[sel], fr[sel], zeros[sel], to[sel], single.measurements[sel], info[sel])
        for name, sel in (("odometry", odo), ("loop closures", ~odo))
    ]
    return single.kind, [truth], sets, [path.stem], notes


def _weighable(edge_sets: list[EdgeSet], kind: PoseKind, notes: list[str]) -> list[EdgeSet]:
    """Each information matrix that is not positive definite weighed by its translation and rotation
    blocks where they are (as SE-Sync reads them; cubicle.g2o), with a note of how many."""
    d = 3 if kind is PoseKind.SE2 else 6
    out, total = [], 0
    for name, fa, fv, ta, tv, meas, upper in edge_sets:
        info, count = block_diagonal_where_indefinite(upper, d)
        total += count
        out.append((name, fa, fv, ta, tv, meas, info))
    if total:
        notes.append(
            f"{total} information matrices are not positive definite: each weighed by its translation and "
            "rotation blocks, as SE-Sync reads them"
        )
    return out


@dataclass(frozen=True, eq=False)
class _EdgeChi2:
    """Every checked edge's class, endpoints and chi2 (total and per component), as columns."""

    classes: np.ndarray
    agent: np.ndarray
    """The ``from`` agent of each edge (0-based)."""
    rows: np.ndarray
    """``(n, 4)``: ``from_agent from_vertex to_agent to_vertex`` (0-based)."""
    total: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray


def check(
    dataset: PathLike, *, convention: Convention = "g2o", warn: Callable[[str], None] | None = None
) -> CheckReport:
    """Check ``dataset`` at its ground truth (see the module docstring): a multi-g2o folder, or a
    single g2o file (with ``<stem>_GT.tum`` beside it, kollagen's single view, or checked at its own
    poses); ``warn`` gets the reader's warnings (normalised quaternions, skipped records).

    The steps: read the dataset and its listed outliers, decide whether it is checked in SE(2),
    compute every edge's chi2, flag the outlier candidates, sum per class and agent, and count the
    listed outliers among the candidates."""
    from studio.core.errors import ConfigError
    from studio.io.multig2o import read_multi_g2o

    if convention not in ("g2o", "rotvec"):
        raise ConfigError(f"convention: expected g2o or rotvec, got {convention!r}")
    folder = Path(dataset)
    notes: list[str] = []
    graph = None
    if folder.is_file():
        kind, truth, edge_sets, names, notes = _single_g2o(folder, warn)
    else:
        graph = read_multi_g2o(folder)
        kind, truth, edge_sets, names = _multi_g2o(graph, folder, notes)
    edge_sets = _weighable(edge_sets, kind, notes)
    listed = _read_listed_outliers(folder, [len(t) for t in truth]) if folder.is_dir() else None
    planar = (
        kind is PoseKind.SE3
        and all(is_planar_se3(t) for t in truth)
        and all(is_planar_se3(e[5]) for e in edge_sets if len(e[5]))
    )
    if planar:
        notes.append("3D records of planar data: checked in SE(2) (x, y, yaw); z, roll and pitch are not scored")
    checked = PoseKind.SE2 if planar or kind is PoseKind.SE2 else PoseKind.SE3
    d = 3 if checked is PoseKind.SE2 else 6
    edges = _edge_chi2(folder, truth, edge_sets, names, planar=planar, d=d, convention=convention)
    flagged = _outlier_candidates(edges, d)
    order = np.argsort(-edges.total[flagged], kind="stable")
    candidates = np.column_stack([edges.rows[flagged][order].astype(np.float64), edges.total[flagged][order]])
    classes = _class_checks(edges, flagged, names, d=d, dt=2 if checked is PoseKind.SE2 else 3)
    if graph is not None:
        classes += _prior_check(folder, graph, truth, planar=planar, convention=convention)
    listed_n = listed_flagged = None
    if listed is not None:
        listed_n = len(listed)
        have = {tuple(r) for r in edges.rows[flagged].tolist()}
        listed_flagged = sum(tuple(r) in have for r in listed.tolist())
    sightings = check_range_bearing(folder, truth) if folder.is_dir() else None
    return CheckReport(
        str(folder), checked, convention, tuple(classes), candidates, listed_n, listed_flagged, tuple(notes), sightings
    )


def _edge_file(folder: Path, a_from: int, a_to: int) -> Path:
    """The file holding an edge from agent ``a_from`` to ``a_to``: the agent's ``posegraph.g2o`` or
    ``inter_agent_lc.dat`` of a multi-g2o folder; a single g2o file itself."""
    if folder.is_file():
        return folder
    if a_from != a_to:
        return folder / "inter_agent_lc.dat"
    from studio.io.multig2o import agent_folders

    return agent_folders(folder)[a_from][1] / "posegraph.g2o"


def _edge_chi2(
    folder: Path,
    truth: list[np.ndarray],
    edge_sets: list[EdgeSet],
    names: list[str],
    *,
    planar: bool,
    d: int,
    convention: Convention,
) -> _EdgeChi2:
    """Each edge's error at the ground truth and its chi2 (in SE(2) when ``planar``); an edge whose
    information is not positive definite, or a dataset without edges, is a FormatError."""
    from studio.core.geometry import se3_poses_to_planar

    def rows(poses: np.ndarray) -> np.ndarray:
        return se3_poses_to_planar(poses) if planar else poses

    stacked = np.concatenate([rows(t) for t in truth])
    offsets = np.concatenate([[0], np.cumsum([len(t) for t in truth])])
    cls, agent_of, fa, fv, ta, tv, total, ttrans, trot = [], [], [], [], [], [], [], [], []
    for name, a_from, v_from, a_to, v_to, meas, upper in edge_sets:
        if len(v_from) == 0:
            continue
        e = edge_errors(
            stacked[offsets[a_from] + v_from], stacked[offsets[a_to] + v_to], rows(meas), convention=convention
        )
        up = se3_information_to_se2(upper) if planar else upper
        bad = indefinite_information(up, d)
        if len(bad):
            k = int(bad[0])
            raise FormatError(
                f"{_edge_file(folder, int(np.asarray(a_from)[k]), int(np.asarray(a_to)[k]))}: {name} edge "
                f"{names[int(np.asarray(a_from)[k])]} vertex {int(v_from[k])} -> "
                f"{names[int(np.asarray(a_to)[k])]} vertex {int(v_to[k])}: the information matrix is not positive "
                f"definite ({len(bad)} such edges); chi2 cannot judge it"
            )
        t, r = chi2_parts(e, up)
        cls.append(np.full(len(e), name))
        agent_of.append(np.asarray(a_from))
        fa.append(a_from)
        fv.append(v_from)
        ta.append(a_to)
        tv.append(v_to)
        total.append(chi2_terms(e, up))
        ttrans.append(t)
        trot.append(r)
    if not cls:
        raise FormatError(f"{folder}: the dataset has no edges to check")
    return _EdgeChi2(
        np.concatenate(cls),
        np.concatenate(agent_of),
        np.column_stack([np.concatenate(fa), np.concatenate(fv), np.concatenate(ta), np.concatenate(tv)]),
        np.concatenate(total),
        np.concatenate(ttrans),
        np.concatenate(trot),
    )


def _prior_check(
    folder: Path, graph: Any, truth: list[np.ndarray], *, planar: bool, convention: Convention
) -> list[ClassCheck]:
    """The dataset's pose priors (``priors.txt``, COSMO-Bench's ``PriorFactorPose3``) at the ground
    truth, as one class ``priors``: each prior is a measurement of its pose from the origin."""
    from studio.core.geometry import se3_poses_to_planar
    from studio.io.priors_txt import PRIORS_NAME, read_priors_txt

    if not (folder / PRIORS_NAME).is_file():
        return []
    priors = read_priors_txt(folder / PRIORS_NAME, graph)
    if not len(priors):
        return []
    poses = np.array([truth[a][v] for a, v in zip(priors.agent.tolist(), priors.index.tolist())])
    values, upper = priors.poses, priors.information_upper
    if planar:
        poses, values, upper = se3_poses_to_planar(poses), se3_poses_to_planar(values), se3_information_to_se2(upper)
    origin = np.zeros_like(poses)
    origin[:, -1] = 1.0 if not planar and graph.kind is PoseKind.SE3 else 0.0  # the identity (qw = 1)
    e = edge_errors(origin, poses, values, convention=convention)
    t, r = chi2_parts(e, upper)
    n, d = len(priors), e.shape[1]
    dt = 2 if d == 3 else 3
    return [
        ClassCheck(
            "priors",
            "all",
            n,
            Component(float(chi2_terms(e, upper).sum()), n * d),
            Component(float(t.sum()), n * dt),
            Component(float(r.sum()), n * (d - dt)),
        )
    ]


def _outlier_candidates(edges: _EdgeChi2, d: int) -> np.ndarray:
    """The mask of outlier candidates: chi2 over the tail quantile, per class with its robust scale."""
    from scipy.stats import chi2 as chi2_dist

    tot = edges.total
    flagged = np.zeros(len(tot), dtype=bool)
    limit = chi2_dist.ppf(1 - OUTLIER_TAIL, d)
    for name in CLASSES:
        sel = edges.classes == name
        if not sel.any():
            continue
        scale = max(1.0, float(np.median(tot[sel])) / chi2_dist.median(d))
        flagged |= sel & (tot > limit * scale)
    return flagged


def _class_checks(edges: _EdgeChi2, flagged: np.ndarray, names: list[str], *, d: int, dt: int) -> list[ClassCheck]:
    """The sums per class (and per agent for odometry and intra-agent loop closures of several
    agents), rare outlier candidates left out."""
    classes = []
    for name in CLASSES:
        sel = edges.classes == name
        if not sel.any():
            continue
        # a few gross outliers would swamp a class's sum: leave them out when they are rare
        rare = flagged[sel].sum() <= MAX_EXCLUDED_FRACTION * sel.sum()
        use = sel & ~flagged if rare else sel
        excluded = int((sel & ~use).sum())
        groups = [("all", use)] + (
            [(names[k], use & (edges.agent == k)) for k in range(len(names))]
            if name in ("odometry", "intra") and len(names) > 1
            else []
        )
        for label, s_ in groups:
            n = int(s_.sum())
            classes.append(
                ClassCheck(
                    name,
                    label,
                    n,
                    Component(float(edges.total[s_].sum()), n * d),
                    Component(float(edges.translation[s_].sum()), n * dt),
                    Component(float(edges.rotation[s_].sum()), n * (d - dt)),
                    excluded if label == "all" else 0,
                )
            )
    return classes


def format_check(report: CheckReport, *, per_agent: bool = False) -> str:
    """A plain-text table: one row per class (and per agent with ``per_agent``)."""
    lines = [
        f"dataset:    {report.dataset}",
        f"checked as: {report.kind.value}; rotation error: "
        + ("quaternion vector part (g2o's EDGE_SE3:QUAT)" if report.convention == "g2o" else "rotation vector (GTSAM)")
        + (" [planar: angle]" if report.kind is PoseKind.SE2 else ""),
        "factor:     chi2 / degrees of freedom at the ground truth (1 = consistent)",
    ]
    lines += [f"note:       {n}" for n in report.notes]
    head = ("class", "agent", "edges", "chi2/dof", "t chi2/dof", "r chi2/dof", "verdict (total; translation; rotation)")
    body = []
    for c in report.classes:
        if c.agent != "all" and not per_agent:
            continue
        v = c.verdicts
        body.append(
            (
                c.name,
                c.agent,
                str(c.edges) + (f" (+{c.excluded} out)" if c.excluded else ""),
                f"{c.total.factor:.4g}",
                f"{c.translation.factor:.4g}",
                f"{c.rotation.factor:.4g}",
                f"{v['total']}; {v['translation']}; {v['rotation']}",
            )
        )
    widths = [max(len(r[i]) for r in [head, *body]) for i in range(len(head))]
    lines += ["", "  ".join(h.ljust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(x.ljust(w) for x, w in zip(r, widths)) for r in body]
    n = len(report.outliers)
    lines += [
        "",
        f"outlier candidates: {n}"
        + (
            ""
            if report.listed_outliers is None
            else f" (the dataset lists {report.listed_outliers} outliers; {report.listed_flagged} of them flagged)"
        ),
    ]
    for r in report.outliers[:10]:
        lines.append(
            f"  agent {int(r[0]) + 1} vertex {int(r[1])} -> agent {int(r[2]) + 1} vertex {int(r[3])}: chi2 {r[4]:.4g}"
        )
    if n > 10:
        lines.append(f"  ... {n - 10} more (--json lists all)")
    lines += format_range_bearing_check(report.range_bearing)
    return "\n".join(lines) + "\n"
