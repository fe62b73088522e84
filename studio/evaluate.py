"""``studio evaluate`` as a library function: score an estimate against a dataset's ground truth with evo.

Conventions (those of the kollagen paper, Tables I and II, unless an option says otherwise):

* Poses are compared in the one world frame all agents share, **unaligned** by default. ``align``
  ``"se3"``/``"sim3"`` fits one Umeyama transform (evo's :func:`~evo.core.geometry.umeyama_alignment`)
  to all agents together, or one per agent with ``align_per_agent``.
* **APE** (evo's :class:`~evo.core.metrics.APE`): translation part in metres, rotation angle in
  degrees, for every pose, the first included. The row ``all`` pools the poses of every agent, as
  evo does on kollagen's concatenated ``NAME_GT.tum``/``NAME.tum``: its translation mean is the
  paper's figure (14.883697 on Multi3500x8, 17.427713 on Multi10000x5).
* **RPE** (evo's :class:`~evo.core.metrics.RPE`, consecutive pairs chosen on the ground truth with
  evo's :func:`~evo.core.metrics.id_pairs_from_delta`, i.e. ``evo_rpe --pairs_from_reference``):
  per ``rpe_delta_m`` metres travelled and per ``rpe_delta_nodes`` nodes, translation in metres and
  rotation angle in degrees. Pairs never span two agents; ``all`` pools every agent's pairs.
* Statistics are evo's (``rmse, mean, median, std, min, max, sse``, std with ``ddof=0``).

evo computes APE rotation and RPE in Python loops over 4x4 matrices (about 15 s for the 50,005 poses
of Multi10000x5). Here the same formulas are evaluated on whole columns with scipy's ``Rotation``
(which evo's ``so3_log`` uses too); ``tests/studio/test_evaluate.py`` checks them against evo's metric objects.
The translation APE is evo's own ``APE.process_data``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from studio.core.alignment import Alignment
from studio.core.errors import ConfigError, EvaluationError, OutputError
from studio.core.model import PoseGraph
from studio.core.types import PathLike
from studio.core.units import MAX_MAGNITUDE, NS_PER_S
from studio.runtime.progress import Progress, report

if TYPE_CHECKING:
    from studio.core.trajectory import Trajectory

__all__ = [
    "Alignment",
    "AgentScore",
    "Evaluation",
    "ErrorStats",
    "evaluate",
    "score",
    "ape_translation",
    "format_table",
    "format_markdown",
    "DEFAULT_TUM_MAX_DIFF_S",
    "write_evaluation_recording",
]

#: Largest time difference [s] at which a TUM estimate pose is matched to a ground-truth pose (evo's default).
DEFAULT_TUM_MAX_DIFF_S = 0.01


@dataclass(frozen=True)
class ErrorStats:
    """evo's statistics of one error series (``StatisticsType``), and how many values it has."""

    count: int
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float

    @classmethod
    def of(cls, errors: np.ndarray) -> ErrorStats | None:
        if len(errors) == 0:
            return None
        from evo.core import metrics

        pe = metrics.APE()  # evo's statistics of an error array (PE.get_all_statistics)
        pe.error = np.asarray(errors, dtype=np.float64)
        s = pe.get_all_statistics()
        return cls(len(errors), *(float(s[k]) for k in ("rmse", "mean", "median", "std", "min", "max", "sse")))


_METRICS = (
    ("ape_translation_m", "APE translation [m]"),
    ("ape_rotation_deg", "APE rotation [deg]"),
    ("rpe_m_translation_m", "RPE per metre, translation [m]"),
    ("rpe_m_rotation_deg", "RPE per metre, rotation [deg]"),
    ("rpe_node_translation_m", "RPE per node, translation [m]"),
    ("rpe_node_rotation_deg", "RPE per node, rotation [deg]"),
)


@dataclass(frozen=True, eq=False)
class AgentScore:
    """The errors of one agent (or of all agents pooled: ``name == "all"``)."""

    name: str
    poses: int
    """Poses scored (matched ones for TUM estimates)."""
    ape_translation_m: ErrorStats
    ape_rotation_deg: ErrorStats
    rpe_m_translation_m: ErrorStats | None
    """None when the ground truth travels less than one RPE distance."""
    rpe_m_rotation_deg: ErrorStats | None
    rpe_node_translation_m: ErrorStats | None
    """None when the agent has no more poses than the RPE node delta."""
    rpe_node_rotation_deg: ErrorStats | None

    def to_dict(self) -> dict:
        out: dict = {"name": self.name, "poses": self.poses}
        for key, _ in _METRICS:
            st = getattr(self, key)
            out[key] = None if st is None else st.__dict__.copy()
        return out


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The result of :func:`score` / :func:`evaluate`."""

    dataset: str
    estimate: str
    """The estimate's path, or ``"initial estimate"``."""
    estimate_layout: str
    """``initial``, ``single-g2o``, ``multi-g2o`` or ``tum``."""
    alignment: Alignment
    align_per_agent: bool
    rpe_delta_m: float
    rpe_delta_nodes: int
    agents: tuple[AgentScore, ...]
    overall: AgentScore
    """All agents pooled (row ``all``)."""
    node_indices: tuple[np.ndarray, ...] = field(repr=False)
    """Per agent, the dataset vertex index of each scored pose (all of them unless TUM matching dropped some)."""
    stamps_ns: tuple[np.ndarray, ...] = field(repr=False)
    """Per agent, the ground-truth stamps of the scored poses."""
    ape_translation_series_m: tuple[np.ndarray, ...] = field(repr=False)
    """Per agent, the APE translation error of each scored pose (for plots and recordings)."""
    ape_rotation_series_deg: tuple[np.ndarray, ...] = field(repr=False)
    ground_truth_xyz: tuple[np.ndarray, ...] = field(repr=False, default=())
    """Per agent, the ground-truth positions of the scored poses (n, 3)."""
    estimate_xyz: tuple[np.ndarray, ...] = field(repr=False, default=())
    """Per agent, the estimate's positions of the scored poses (n, 3), after any alignment."""
    alignment_transforms: tuple[tuple[np.ndarray, np.ndarray, float], ...] = field(repr=False, default=())
    """``(R, t, s)`` of each Umeyama fit (one, or one per agent); empty when unaligned."""
    warnings: tuple[str, ...] = ()
    """Facts worth a warning, e.g. ground-truth poses that no TUM estimate pose matched."""

    @property
    def alignment_text(self) -> str:
        if self.alignment is Alignment.none:
            return "unaligned"
        if self.alignment is Alignment.first_pose:
            return "first pose of each agent put on its ground truth"
        return f"{self.alignment.value} Umeyama alignment, " + (
            "one per agent" if self.align_per_agent else "one for all agents"
        )

    def to_dict(self) -> dict:
        return {
            "dataset": self.dataset,
            "estimate": self.estimate,
            "estimate_layout": self.estimate_layout,
            "alignment": {"mode": self.alignment.value, "per_agent": self.align_per_agent},
            "rpe": {"delta_m": self.rpe_delta_m, "delta_nodes": self.rpe_delta_nodes, "pairs_from": "ground truth"},
            "agents": [a.to_dict() for a in self.agents],
            "all": self.overall.to_dict(),
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)


# ---------------------------------------------------------------------------------------------- scoring


def _trajectory(poses7: np.ndarray, stamps_ns: np.ndarray):
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(
        positions_xyz=poses7[:, 0:3], orientations_quat_wxyz=poses7[:, [6, 3, 4, 5]], timestamps=stamps_ns / NS_PER_S
    )


def _check_finite(poses: np.ndarray, where: str) -> None:
    bad = ~np.isfinite(poses).all(axis=1)
    if bad.any():
        raise EvaluationError(f"{where}: pose {int(np.flatnonzero(bad)[0])} is not finite (NaN or inf)")
    norms = np.linalg.norm(poses[:, 3:7], axis=1)
    if np.any(norms < 1e-9):
        raise EvaluationError(f"{where}: pose {int(np.flatnonzero(norms < 1e-9)[0])} has a zero quaternion")


def _matched(
    graph: PoseGraph, estimate: Sequence[Trajectory] | None, by_time: bool, max_diff_s: float, warnings: list[str]
):
    """Per agent: (gt poses, est poses, gt stamps, vertex indices) of the poses to compare."""
    from evo.core.sync import matching_time_indices

    out = []
    g = graph.to_se3()
    for k, agent in enumerate(g.agents):
        if agent.ground_truth is None:
            src = graph.metadata.get("source")
            hint = f" ({Path(src) / agent.name / (agent.name + '_GT.tum')} is missing)" if src else ""
            raise EvaluationError(f"{agent.name}: no ground truth{hint}")
        far = np.flatnonzero(~(np.abs(agent.ground_truth[:, :3]) <= MAX_MAGNITUDE).all(axis=1))
        if far.size:  # else the estimate was blamed for the error it made not finite
            src = graph.metadata.get("source")
            where = f"{Path(src) / agent.name / (agent.name + '_GT.tum')}" if src else f"{agent.name}'s ground truth"
            raise EvaluationError(f"{where}: pose {int(far[0])} lies beyond {MAX_MAGNITUDE:g} m")
        if estimate is None:
            out.append((agent.ground_truth, agent.initial, agent.stamps_ns, np.arange(agent.num_poses)))
            continue
        est = estimate[k]
        if est.name != agent.name:
            raise EvaluationError(f"estimate agent {k + 1} is {est.name}, the dataset's is {agent.name}")
        poses = np.asarray(est.poses_xyz_quat_xyzw, dtype=np.float64)
        _check_finite(poses, f"estimate of {agent.name}")
        if not by_time:
            if len(poses) != agent.num_poses:
                raise EvaluationError(
                    f"estimate of {agent.name}: {len(poses)} poses for the dataset's {agent.num_poses}"
                )
            out.append((agent.ground_truth, poses, agent.stamps_ns, np.arange(agent.num_poses)))
            continue
        i_gt, i_est = matching_time_indices(
            agent.stamps_ns / NS_PER_S, np.asarray(est.stamps_ns) / NS_PER_S, max_diff_s
        )
        if not i_gt:
            raise EvaluationError(
                f"estimate of {agent.name}: no timestamp matches the ground truth within {max_diff_s} s "
                f"(estimate {est.stamps_ns[0] / NS_PER_S:.9g}..{est.stamps_ns[-1] / NS_PER_S:.9g} s, ground truth "
                f"{agent.stamps_ns[0] / NS_PER_S:.9g}..{agent.stamps_ns[-1] / NS_PER_S:.9g} s)"
            )
        i_gt, i_est = np.asarray(i_gt), np.asarray(i_est)
        if len(i_gt) < agent.num_poses:
            warnings.append(
                f"estimate of {agent.name}: {len(i_gt)} of {agent.num_poses} ground-truth poses "
                f"matched within {max_diff_s} s; only those are scored"
            )
        out.append((agent.ground_truth[i_gt], poses[i_est], agent.stamps_ns[i_gt], i_gt))
    return out


def _umeyama(est_xyz: np.ndarray, gt_xyz: np.ndarray, with_scale: bool, what: str):
    """evo's ``umeyama_alignment`` (Umeyama, PAMI 1991, eqs. 34-43) with its per-point loop over
    outer products written as one matrix product (on 50,000 poses 0.7 s became a few ms)."""
    x, y = np.asarray(est_xyz, dtype=np.float64).T, np.asarray(gt_xyz, dtype=np.float64).T
    if x.shape != y.shape:
        raise EvaluationError(f"{what}: cannot align (data matrices must have the same shape)")
    m, n = x.shape
    mean_x, mean_y = x.mean(axis=1), y.mean(axis=1)
    xc, yc = x - mean_x[:, None], y - mean_y[:, None]
    sigma_x = np.linalg.norm(xc) ** 2 / n
    u, d, v = np.linalg.svd((yc @ xc.T) / n)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < m - 1:
        raise EvaluationError(f"{what}: cannot align (Degenerate covariance rank, Umeyama alignment is not possible)")
    s = np.eye(m)
    if np.linalg.det(u) * np.linalg.det(v) < 0.0:
        s[m - 1, m - 1] = -1  # a right-handed frame (Kabsch)
    r = u @ s @ v
    c = float(np.trace(np.diag(d) @ s) / sigma_x) if with_scale else 1.0
    return r, mean_y - c * (r @ mean_x), c


def _apply(poses: np.ndarray, r: np.ndarray, t: np.ndarray, s: float) -> np.ndarray:
    """``T * (scaled pose)`` as evo's ``scale(s)`` then ``transform(se3(r, t))``, on columns."""
    from scipy.spatial.transform import Rotation

    out = np.empty_like(poses)
    out[:, 0:3] = (s * poses[:, 0:3]) @ r.T + t
    out[:, 3:7] = (Rotation.from_matrix(r) * Rotation.from_quat(poses[:, 3:7])).as_quat()
    return out


def _first_pose_transform(gt0: np.ndarray, est0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` of the rigid transform that takes the pose ``est0`` onto ``gt0``: ``T = G E^-1``."""
    from scipy.spatial.transform import Rotation

    r = (Rotation.from_quat(gt0[3:7]) * Rotation.from_quat(est0[3:7]).inv()).as_matrix()
    return r, gt0[0:3] - r @ est0[0:3]


def _rpe(gt: np.ndarray, est: np.ndarray, delta: float, unit) -> tuple[np.ndarray, np.ndarray]:
    """RPE translation [m] and rotation [deg] of evo's consecutive pairs, pairs taken on the ground truth."""
    from evo.core import filters, metrics
    from scipy.spatial.transform import Rotation

    n = len(gt)
    poses: range | np.ndarray
    if unit is metrics.Unit.frames:
        poses = range(n)  # filter_pairs_by_index only counts them
    else:
        poses = np.zeros((n, 4, 4))
        poses[:, 0:3, 3] = gt[:, 0:3]
    try:
        pairs = np.asarray(
            metrics.id_pairs_from_delta(poses, delta, unit, 0.1, all_pairs=False), dtype=np.int64
        ).reshape(-1, 2)
    except filters.FilterException:
        return np.zeros(0), np.zeros(0)
    i, j = pairs[:, 0], pairs[:, 1]
    rq, rp = Rotation.from_quat(gt[:, 3:7]), Rotation.from_quat(est[:, 3:7])
    # Q_rel = Q_i^-1 Q_j, P_rel = P_i^-1 P_j, E = Q_rel^-1 P_rel (evo's RPE.rpe_base)
    q_rel_r, p_rel_r = rq[i].inv() * rq[j], rp[i].inv() * rp[j]
    q_rel_t = rq[i].inv().apply(gt[j, 0:3] - gt[i, 0:3])
    p_rel_t = rp[i].inv().apply(est[j, 0:3] - est[i, 0:3])
    trans = np.linalg.norm(q_rel_r.inv().apply(p_rel_t - q_rel_t), axis=1)
    rot = np.rad2deg((q_rel_r.inv() * p_rel_r).magnitude())
    return trans, rot


def _ape_rotation_deg(gt: np.ndarray, est: np.ndarray) -> np.ndarray:
    """evo's APE rotation angle: the angle of ``est^-1 * gt`` in degrees."""
    from scipy.spatial.transform import Rotation

    return np.rad2deg((Rotation.from_quat(est[:, 3:7]).inv() * Rotation.from_quat(gt[:, 3:7])).magnitude())


def _quiet_numpy(func):
    """Run ``func`` with numpy's floating-point warnings off: overflow shows up as a non-finite
    error, which :func:`score` refuses in one line naming the agent and pose."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with np.errstate(all="ignore"):
            return func(*args, **kwargs)

    return wrapper


def check_alignment(align: Alignment | str, align_per_agent: bool) -> Alignment:
    """The alignment named ``align``; one per agent (``align_per_agent``) only for se3 and sim3
    (first-pose is one per agent by nature, none has nothing to align)."""
    try:
        align = Alignment(align)
    except ValueError:
        raise EvaluationError(f"unknown alignment {align!r} (known: {', '.join(a.value for a in Alignment)})") from None
    if align_per_agent and align not in (Alignment.se3, Alignment.sim3):
        raise ConfigError(
            f"align_per_agent: one alignment per agent needs an se3 or sim3 alignment, not {align.value}",
            option="align_per_agent",
        )
    return align


@_quiet_numpy
def score(
    graph: PoseGraph,
    estimate: Sequence[Trajectory] | None = None,
    *,
    by_time: bool = False,
    align: Alignment | str = Alignment.none,
    align_per_agent: bool = False,
    rpe_delta_m: float = 1.0,
    rpe_delta_nodes: int = 1,
    tum_max_diff_s: float = DEFAULT_TUM_MAX_DIFF_S,
    dataset: str = "",
    estimate_label: str = "",
    estimate_layout: str = "",
) -> Evaluation:
    """Score ``estimate`` (one :class:`~studio.core.trajectory.Trajectory` per agent, or None for the
    graph's initial estimate) against the graph's ground truth. No I/O.

    With ``by_time`` the estimate's poses are matched to the ground truth by timestamp (within
    ``tum_max_diff_s``); otherwise pose k of an agent is the estimate of its vertex k."""
    align = _check_score_arguments(
        graph, estimate, check_alignment(align, align_per_agent), rpe_delta_m, rpe_delta_nodes
    )
    warnings: list[str] = []
    matched = _matched(graph, estimate, by_time, tum_max_diff_s, warnings)
    names = [a.name for a in graph.agents]
    matched, transforms = _aligned(matched, align, align_per_agent, names)
    errors = _errors(matched, rpe_delta_m, rpe_delta_nodes)
    _refuse_non_finite(errors, names, estimate_label)
    ape_t, ape_r, rpe_m, rpe_n = errors.ape_t, errors.ape_r, errors.rpe_m, errors.rpe_n
    rows = tuple(
        _agent_score(names[k], len(matched[k][0]), ape_t[k], ape_r[k], rpe_m[k], rpe_n[k]) for k in range(len(names))
    )

    def pool(series):
        return tuple(np.concatenate([s[c] for s in series]) for c in (0, 1))

    n_all = sum(len(m[0]) for m in matched)
    overall = _agent_score("all", n_all, errors.ape_t_all, np.concatenate(ape_r), pool(rpe_m), pool(rpe_n))
    return Evaluation(
        dataset=dataset or str(graph.metadata.get("source", "")),
        estimate=estimate_label or ("initial estimate" if estimate is None else "estimate"),
        estimate_layout=estimate_layout or ("initial" if estimate is None else "arrays"),
        alignment=align,
        align_per_agent=align is Alignment.first_pose or (align_per_agent and align is not Alignment.none),
        rpe_delta_m=float(rpe_delta_m),
        rpe_delta_nodes=int(rpe_delta_nodes),
        agents=rows,
        overall=overall,
        node_indices=tuple(np.asarray(m[3], dtype=np.int64) for m in matched),
        stamps_ns=tuple(m[2] for m in matched),
        ape_translation_series_m=tuple(ape_t),
        ape_rotation_series_deg=tuple(ape_r),
        ground_truth_xyz=tuple(np.ascontiguousarray(m[0][:, 0:3]) for m in matched),
        estimate_xyz=tuple(np.ascontiguousarray(m[1][:, 0:3]) for m in matched),
        alignment_transforms=tuple(transforms),
        warnings=tuple(warnings),
    )


@_quiet_numpy
def ape_translation(
    graph: PoseGraph, ground_truth_se3: Sequence[np.ndarray], poses_se3: Sequence[np.ndarray], *, align: Alignment | str
) -> ErrorStats:
    """The translation APE [m] of :func:`score` (its row ``all``) and nothing else, for scoring many
    iterates of one estimate cheaply: ``poses_se3`` one ``(n_a, 7)`` array per agent, vertex k of an
    agent its pose k; ``ground_truth_se3`` the graph's ground truth in 3D (``graph.to_se3()``'s,
    passed in so a caller converts it once). ``first-pose`` aligns each agent, ``se3``/``sim3`` all
    agents together, as :func:`score` does."""
    align = Alignment(align)
    if len(poses_se3) != len(graph.agents) or len(ground_truth_se3) != len(graph.agents):
        raise EvaluationError(f"the estimate has {len(poses_se3)} agents, the dataset {len(graph.agents)}")
    ests = [np.asarray(p, dtype=np.float64) for p in poses_se3]
    for agent, gt, est in zip(graph.agents, ground_truth_se3, ests):
        if est.shape != gt.shape:
            raise EvaluationError(f"estimate of {agent.name}: {len(est)} poses for the dataset's {len(gt)}")
        _check_finite(est, f"estimate of {agent.name}")
    # positions only: the same arithmetic as _apply's translation part, without the rotations
    if align is Alignment.first_pose:
        moved = [_first_pose_transform(gt[0], est[0]) for gt, est in zip(ground_truth_se3, ests)]
        ests = [(1.0 * est[:, 0:3]) @ r.T + t for (r, t), est in zip(moved, ests)]
    elif align is not Alignment.none:
        r, t, s = _umeyama(
            np.concatenate([e[:, 0:3] for e in ests]),
            np.concatenate([g[:, 0:3] for g in ground_truth_se3]),
            align is Alignment.sim3,
            "all agents",
        )
        ests = [(s * est[:, 0:3]) @ r.T + t for est in ests]
    errors = np.linalg.norm(
        np.concatenate([g[:, 0:3] for g in ground_truth_se3]) - np.concatenate([e[:, 0:3] for e in ests]), axis=1
    )
    stats = ErrorStats.of(errors)
    if stats is None or not np.all(np.isfinite(errors)):
        raise EvaluationError("estimate: no finite translation error to score")
    return stats


def _check_score_arguments(
    graph: PoseGraph,
    estimate: Sequence[Trajectory] | None,
    align: Alignment | str,
    rpe_delta_m: float,
    rpe_delta_nodes: int,
) -> Alignment:
    """The alignment asked for; :class:`EvaluationError` for an unknown one, a bad RPE delta or an
    estimate with another number of agents."""
    try:
        align = Alignment(align)
    except ValueError:
        raise EvaluationError(f"unknown alignment {align!r} (known: {', '.join(a.value for a in Alignment)})") from None
    if not (math.isfinite(rpe_delta_m) and rpe_delta_m > 0):
        raise EvaluationError(f"the RPE distance must be a positive number of metres, got {rpe_delta_m!r}")
    if rpe_delta_nodes < 1:
        raise EvaluationError(f"the RPE node delta must be at least 1, got {rpe_delta_nodes}")
    if estimate is not None and len(estimate) != len(graph.agents):
        raise EvaluationError(f"the estimate has {len(estimate)} agents, the dataset {len(graph.agents)}")
    return align


def _aligned(matched: list, align: Alignment, align_per_agent: bool, names: list[str]) -> tuple[list, list]:
    """``matched`` with each estimate aligned to its ground truth, and the transforms ``(r, t, s)``
    used: one per agent (first pose, or per-agent Umeyama), one for all agents, or none."""
    transforms = []
    if align is Alignment.first_pose:
        aligned = []
        for gt, est, st, idx in matched:
            r, t = _first_pose_transform(gt[0], est[0])
            transforms.append((r, t, 1.0))
            aligned.append((gt, _apply(est, r, t, 1.0), st, idx))
        return aligned, transforms
    if align is Alignment.none:
        return matched, transforms
    sim3 = align is Alignment.sim3
    if align_per_agent:
        aligned = []
        for name, (gt, est, st, idx) in zip(names, matched):
            r, t, s = _umeyama(est[:, 0:3], gt[:, 0:3], sim3, name)
            transforms.append((r, t, s))
            aligned.append((gt, _apply(est, r, t, s), st, idx))
        return aligned, transforms
    r, t, s = _umeyama(
        np.concatenate([m[1][:, 0:3] for m in matched]),
        np.concatenate([m[0][:, 0:3] for m in matched]),
        sim3,
        "all agents",
    )
    transforms.append((r, t, s))
    return [(gt, _apply(est, r, t, s), st, idx) for gt, est, st, idx in matched], transforms


@dataclass(frozen=True, eq=False)
class _Errors:
    """Per-agent error series of the aligned estimate."""

    ape_t_all: np.ndarray
    """APE translation [m] of all agents' poses pooled, in agent order."""
    ape_t: list[np.ndarray]
    ape_r: list[np.ndarray]
    rpe_m: list[tuple[np.ndarray, np.ndarray]]
    """RPE (translation, rotation) over ``rpe_delta_m`` metres."""
    rpe_n: list[tuple[np.ndarray, np.ndarray]]
    """RPE (translation, rotation) over ``rpe_delta_nodes`` nodes."""


def _errors(matched: list, rpe_delta_m: float, rpe_delta_nodes: int) -> _Errors:
    """APE translation by evo's own metric, on all agents' poses pooled (kollagen's single TUM
    files); APE rotation and both RPEs per agent."""
    from evo.core import metrics

    gt_all = np.concatenate([m[0] for m in matched])
    est_all = np.concatenate([m[1] for m in matched])
    stamps_all = np.arange(len(gt_all), dtype=np.int64) * NS_PER_S
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((_trajectory(gt_all, stamps_all), _trajectory(est_all, stamps_all)))
    bounds = np.cumsum([0] + [len(m[0]) for m in matched])
    return _Errors(
        ape.error,
        [ape.error[a:b] for a, b in zip(bounds[:-1], bounds[1:])],
        [_ape_rotation_deg(gt, est) for gt, est, *_ in matched],
        [_rpe(gt, est, rpe_delta_m, metrics.Unit.meters) for gt, est, *_ in matched],
        [_rpe(gt, est, rpe_delta_nodes, metrics.Unit.frames) for gt, est, *_ in matched],
    )


def _refuse_non_finite(errors: _Errors, names: list[str], estimate_label: str) -> None:
    """One line naming the agent and pose of the first error that is not finite."""
    series_all = [*errors.ape_t, *errors.ape_r, *(r[0] for r in errors.rpe_m), *(r[0] for r in errors.rpe_n)]
    for k, series in enumerate(series_all):
        bad = np.flatnonzero(~np.isfinite(np.asarray(series, dtype=float)))
        if len(bad):  # an estimate far beyond any map (e.g. a vertex at 1e200) overflows the errors
            k %= len(names)
            raise EvaluationError(
                f"{estimate_label or 'estimate'}: agent {names[k]}: the error at pose {int(bad[0])} "
                "is not finite (a pose beyond the finite range?)"
            )


def _agent_score(name: str, n: int, at, ar, rm, rn) -> AgentScore:
    ape_t, ape_r = ErrorStats.of(at), ErrorStats.of(ar)
    assert ape_t is not None and ape_r is not None  # every scored agent has at least one pose
    return AgentScore(
        name,
        n,
        ape_t,
        ape_r,
        ErrorStats.of(rm[0]),
        ErrorStats.of(rm[1]),
        ErrorStats.of(rn[0]),
        ErrorStats.of(rn[1]),
    )


def evaluate(
    dataset: PathLike,
    *,
    estimate: PathLike | None = None,
    align: Alignment | str = Alignment.none,
    align_per_agent: bool = False,
    rpe_delta_m: float = 1.0,
    rpe_delta_nodes: int = 1,
    tum_max_diff_s: float = DEFAULT_TUM_MAX_DIFF_S,
    progress: Progress | None = None,
) -> Evaluation:
    """Read ``dataset`` and score ``estimate`` (or, if None, the dataset's initial estimate) against
    its ground truth. See the module docstring for the conventions.

    ``dataset`` is a multi-g2o folder, or a single g2o file with ``<stem>_GT.tum`` beside it
    (kollagen's single view, scored as one agent named ``<stem>``). ``estimate`` is a single g2o
    file (ids as in the dataset's single g2o), a multi-g2o folder, a folder of
    ``<agent>.tum``/``<agent>_*.tum`` files (matched by time within ``tum_max_diff_s``), or the
    folder ``studio solve`` wrote (its ``solve.json`` names the estimate inside).
    """
    from studio.io.estimate import read_estimate
    from studio.io.multig2o import read_multi_g2o

    check_alignment(align, align_per_agent)  # before any reading
    step = "evaluate"
    report(progress, step, 0, 3, "stages")
    vertex_ids = None
    if Path(dataset).is_file():
        graph, vertex_ids = _single_dataset(Path(dataset))
    else:
        graph = read_multi_g2o(dataset, edges=False)
    report(progress, step, 1, 3, "stages")
    est = None if estimate is None else read_estimate(estimate, graph, vertex_ids=vertex_ids)
    report(progress, step, 2, 3, "stages")
    ev = score(
        graph,
        None if est is None else est.agents,
        by_time=est is not None and est.by_time,
        align=align,
        align_per_agent=align_per_agent,
        rpe_delta_m=rpe_delta_m,
        rpe_delta_nodes=rpe_delta_nodes,
        tum_max_diff_s=tum_max_diff_s,
        dataset=str(dataset),
        estimate_label="initial estimate" if est is None else est.source,
        estimate_layout="initial" if est is None else est.layout,
    )
    report(progress, step, 3, 3, "stages")
    return ev


def _single_dataset(path: Path) -> tuple[PoseGraph, np.ndarray | None]:
    """A single g2o file as every command reads it (:func:`studio.converters.g2o.read_single_g2o`:
    its ids renumbered ``0..n-1`` in increasing order), one agent named ``<stem>`` scored against
    ``<stem>_GT.tum`` beside it (one pose per vertex in id order; its stamps where they increase,
    else the id in seconds). Returns the graph and the file's ids where they are not ``0..n-1``
    (a g2o estimate of it is read by the same ids)."""
    from studio.converters.g2o import read_single_g2o, truth_file
    from studio.core.errors import FormatError
    from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseKind
    from studio.io.tum import read_tum

    gt_path = truth_file(path)
    if gt_path is None:
        raise FormatError(f"{path}: no ground truth beside it ({path.stem}_GT.tum); a dataset is scored against it")
    single = read_single_g2o(path)
    n = len(single.initial)
    ids = np.arange(n) if single.vertex_ids is None else single.vertex_ids
    stamps = single.stamps_ns
    if n > 1 and np.any(np.diff(stamps) <= 0):
        stamps = np.arange(n, dtype=np.int64) * NS_PER_S
    planar = single.kind is PoseKind.SE2
    agent = AgentGraph(
        path.stem,
        single.kind,
        stamps,
        single.initial,
        single.ground_truth,
        Edges.empty(single.kind),
        Edges.empty(single.kind),
        ground_truth_se3=read_tum(gt_path).poses_xyz_quat_xyzw if planar else None,
    )
    graph = PoseGraph(single.kind, (agent,), InterAgentEdges.empty(single.kind), metadata={"source": str(path)})
    return graph, None if np.array_equal(ids, np.arange(n)) else ids


# ---------------------------------------------------------------------------------------------- output

_COLUMNS = (  # header, metric, statistic
    ("poses", None, None),
    ("APE t mean", "ape_translation_m", "mean"),
    ("APE t median", "ape_translation_m", "median"),
    ("APE t RMSE", "ape_translation_m", "rmse"),
    ("APE t max", "ape_translation_m", "max"),
    ("APE r mean", "ape_rotation_deg", "mean"),
    ("APE r RMSE", "ape_rotation_deg", "rmse"),
    ("RPE/m t RMSE", "rpe_m_translation_m", "rmse"),
    ("RPE/m r RMSE", "rpe_m_rotation_deg", "rmse"),
    ("RPE/node t RMSE", "rpe_node_translation_m", "rmse"),
    ("RPE/node r RMSE", "rpe_node_rotation_deg", "rmse"),
)


def _cells(a: AgentScore) -> list[str]:
    out = [a.name]
    for _, metric, stat in _COLUMNS:
        if metric is None:
            out.append(str(a.poses))
            continue
        st = getattr(a, metric)
        out.append("-" if st is None else f"{getattr(st, str(stat)):.6f}")
    return out


def _header_lines(ev: Evaluation) -> list[str]:
    return [
        f"dataset:   {ev.dataset}",
        f"estimate:  {ev.estimate} ({ev.estimate_layout})",
        f"alignment: {ev.alignment_text}",
        f"units:     t in metres, r in degrees; RPE/m over {ev.rpe_delta_m:g} m of ground-truth path, "
        f"RPE/node over {ev.rpe_delta_nodes} node{'s' if ev.rpe_delta_nodes != 1 else ''}",
    ]


def _text_rows(rows: list[list[str]]) -> list[str]:
    """Rows of cells as lines: the first column left-aligned, the others right-aligned."""
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    return ["  ".join(r[0].ljust(widths[0]) if c == 0 else r[c].rjust(widths[c]) for c in range(len(r))) for r in rows]


def format_table(ev: Evaluation, *, width: int | None = None) -> str:
    """A plain-text table, agents as rows and ``all`` (every agent pooled) last. Where that is wider
    than ``width`` characters (a terminal's columns), the table is turned: metrics as rows, agents
    as columns, in as many blocks of agents as it takes to fit."""
    head = ["agent"] + [c[0] for c in _COLUMNS]
    body = [_cells(a) for a in ev.agents] + [_cells(ev.overall)]
    lines = _text_rows([head] + body)
    if width is None or len(lines[0]) <= width:
        rule = "-" * len(lines[0])
        return "\n".join(_header_lines(ev) + ["", lines[0], rule, *lines[1:-1], rule, lines[-1]]) + "\n"
    return "\n".join(_header_lines(ev) + _turned(head, body, width)) + "\n"


def _turned(head: list[str], body: list[list[str]], width: int) -> list[str]:
    """Metrics as rows and agents as columns, in blocks of agents that fit ``width``."""
    label = max(map(len, head))
    out: list[str] = []
    start = 0
    while start < len(body):
        stop = start + 1
        while (
            stop < len(body)
            and len(_text_rows([[h] + [r[i] for r in body[start : stop + 1]] for i, h in enumerate(head)])[0]) <= width
        ):
            stop += 1
        block = _text_rows([[h.ljust(label)] + [r[i] for r in body[start:stop]] for i, h in enumerate(head)])
        out += ["", block[0], "-" * len(block[0]), *block[1:]]
        start = stop
    return out


def format_markdown(ev: Evaluation) -> str:
    """A GitHub-flavoured Markdown table with the same columns, conventions stated above it."""
    head = ["agent"] + [c[0] for c in _COLUMNS]
    lines = [f"{ln.split(':', 1)[0].capitalize()}:{ln.split(':', 1)[1].rstrip()}  " for ln in _header_lines(ev)]
    lines[-1] = lines[-1].rstrip()
    lines += ["", "| " + " | ".join(head) + " |", "|" + "|".join([":---"] + ["---:"] * len(_COLUMNS)) + "|"]
    for a in ev.agents:
        lines.append("| " + " | ".join(_cells(a)) + " |")
    cells = _cells(ev.overall)
    lines.append("| " + " | ".join(f"**{c}**" for c in cells) + " |")
    return "\n".join(lines) + "\n"


#: The statistics panel's columns (header, metric, statistic): the few a reader compares first,
#: narrow enough that a row per agent and ``all`` fit the recording's panel for eight agents.
_PANEL_COLUMNS = (
    ("poses", None, None),
    ("APE t mean", "ape_translation_m", "mean"),
    ("APE t RMSE", "ape_translation_m", "rmse"),
    ("APE t max", "ape_translation_m", "max"),
    ("APE r mean", "ape_rotation_deg", "mean"),
    ("RPE t RMSE", "rpe_m_translation_m", "rmse"),
    ("RPE r RMSE", "rpe_m_rotation_deg", "rmse"),
)


def _panel_cells(a: AgentScore) -> list[str]:
    out = [a.name]
    for _, metric, stat in _PANEL_COLUMNS:
        st = None if metric is None else getattr(a, metric)
        out.append(str(a.poses) if metric is None else "-" if st is None else f"{getattr(st, str(stat)):.4f}")
    return out


def format_panel(ev: Evaluation) -> str:
    """The recording's statistics panel (Markdown): one row per agent and ``all`` (every agent
    pooled, in bold) with APE and RPE (over ``rpe_delta_m`` of ground-truth path), four decimals, the
    conventions in one line above and the inputs below (the full table is ``format_markdown``)."""
    head = ["agent"] + [c[0] for c in _PANEL_COLUMNS]
    lines = [
        f"t [m], r [deg]; {ev.alignment_text}; RPE over {ev.rpe_delta_m:g} m of ground-truth path",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "|".join([":---"] + ["---:"] * len(_PANEL_COLUMNS)) + "|",
    ]
    lines += ["| " + " | ".join(_panel_cells(a)) + " |" for a in ev.agents]
    lines.append("| " + " | ".join(f"**{c}**" for c in _panel_cells(ev.overall)) + " |")
    lines += ["", f"Dataset: {ev.dataset}  ", f"Estimate: {ev.estimate} ({ev.estimate_layout})"]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------- recording


def write_evaluation_recording(
    ev: Evaluation,
    path: PathLike,
    *,
    force: bool = False,
    recording_id: str | None = None,
    progress: Progress | None = None,
) -> Path:
    """Write ``ev`` as a new ``.rrd``, atomically: the estimate against the ground truth in 3D (the
    estimate coloured by its APE translation), one plot per metric with every agent, and the table
    of statistics, laid out by :func:`studio.recording.evaluation.evaluation_blueprint`.

    Pass the dataset recording's id as ``recording_id`` to have the viewer merge both files.
    """
    from studio.io.atomic import staged_outputs
    from studio.recording.evaluation import ErrorSeries, save_evaluation_recording

    path = Path(path)
    series = [
        ErrorSeries(
            a.name,
            ev.node_indices[k],
            ev.stamps_ns[k],
            {"ape_translation_m": ev.ape_translation_series_m[k], "ape_rotation_deg": ev.ape_rotation_series_deg[k]},
            ground_truth_xyz=ev.ground_truth_xyz[k] if ev.ground_truth_xyz else None,
            estimate_xyz=ev.estimate_xyz[k] if ev.estimate_xyz else None,
        )
        for k, a in enumerate(ev.agents)
    ]
    report(progress, "evaluation recording", 0, 1, "files")
    if path.suffix != ".rrd":
        raise OutputError(f"{path}: a recording must end in .rrd")
    inputs = [ev.dataset] + ([ev.estimate] if ev.estimate_layout != "initial" else [])
    with staged_outputs(path.parent, [path.name], force=force, inputs=inputs) as staging:
        save_evaluation_recording(staging / path.name, format_panel(ev), series, recording_id=recording_id)
    report(progress, "evaluation recording", 1, 1, "files")
    return path
