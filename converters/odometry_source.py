"""Real odometry: edges from a second source of motion instead of noise drawn from the ground truth.

A converted dataset's odometry is synthetic by default (``converters/build.py``). With a real source
of motion per agent (MR.CLAM's integrated wheel odometry, ``--odometry real``; or any trajectory
given with ``--odometry-from NAME=FILE.tum`` / ``NAME=BAG:SPEC``: a VIO estimate, a ``/odom`` topic),
the keyframes stay those chosen on the ground truth and

* each odometry edge is the source's relative motion between the two keyframes' stamps (the source
  is interpolated there: positions linearly, orientations by slerp);
* the initial estimate is the source's motion composed from the true first keyframe
  (``T_gt0 T_src0^-1 T_src(t)``: dead reckoning);
* the information is estimated from the source's own errors against the ground truth: per edge the
  error ``e = (gt_rel^-1 src_rel)`` (translation in the first keyframe's frame, rotation vector), and
  a variance model fitted to the squared errors by non-negative least squares, pooled over the axes:
  ``var_t(d) = s_t0^2 + k_t^2 d^2`` and ``var_r(d, a) = s_r0^2 + k_rm^2 d^2 + k_ra^2 a^2`` with ``d`` the
  true distance [m] and ``a`` the true rotation angle [rad] of the edge. ``k_t`` is the source's drift
  per metre [m/m]; ``s_*0`` are floors of at least :data:`MIN_SIGMA`. The fit is reported per agent
  (report.json ``odometry``) and makes ``studio check`` read the odometry's consistency: a mean chi2
  per degree of freedom near 1 on the fitted data by construction (the fit is in-sample), departures
  where the errors are biased or heavy-tailed.

Pure numpy plus scipy's ``nnls``; no I/O except :func:`read_odometry_sources`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import (
    normalize_angle,
    quat_canonical,
    quat_conj,
    quat_from_rotvec,
    quat_mul,
    quat_rotate,
    relative_planar_pose,
    yaw_from_quat_xyzw,
)
from studio.core.model import AgentGraph, Edges, PoseGraph, PoseKind
from studio.core.trajectory import Trajectory, Warn
from studio.core.units import NS_PER_S

__all__ = [
    "MIN_SIGMA",
    "OdometryFit",
    "parse_odometry_spec",
    "read_odometry_sources",
    "poses_at",
    "quat_to_rotvec",
    "apply_odometry_sources",
]

#: Floor of every fitted standard deviation (m or rad): an edge of zero length keeps a finite weight.
MIN_SIGMA = 1e-4
#: g2o's EDGE_SE3:QUAT rotation error is the quaternion's vector part, about half the rotation vector.
_SE3_QUAT_INFORMATION_SCALE = 4.0
_DIAG21 = np.array([0, 6, 11, 15, 18, 20])
_DIAG6 = np.array([0, 3, 5])


@dataclass(frozen=True)
class OdometryFit:
    """The noise model fitted to one agent's real odometry (see the module docstring)."""

    agent: str
    source: str
    edges: int
    sigma_min_m: float
    sigma_m_per_m: float
    sigma_min_rad: float
    sigma_rad_per_m: float
    sigma_rad_per_rad: float
    rms_translation_m: float
    rms_rotation_rad: float
    drift_m_per_m: float
    """Sum of the edges' translation error norms over the distance travelled."""

    def to_dict(self) -> dict[str, Any]:
        """The fit as report.json holds it; a value there is none of (NaN: no travel) is null."""
        return {
            k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in dataclasses.asdict(self).items()
        }


_BAG_SPEC = re.compile(r"^(?P<path>.+?\.(?:bag|mcap)|.+?)(?::(?P<spec>/.*))$")


def parse_odometry_spec(spec: str) -> tuple[str, str, str | None]:
    """``NAME=FILE`` (a TUM file) or ``NAME=BAG:SPEC`` (a bag and a topic spec as ``--agent`` takes,
    e.g. ``run.bag:/alpha/odom``) as ``(name, path, bag_spec_or_None)``."""
    name, sep, rest = spec.partition("=")
    if not sep or not name or not rest:
        raise ConfigError(f"odometry_from: {spec!r}: expected NAME=FILE.tum or NAME=BAG:/topic")
    m = _BAG_SPEC.match(rest)
    if m:
        return name, m.group("path"), m.group("spec")
    return name, rest, None


def read_odometry_sources(specs: Sequence[str], *, warn: Warn | None = None) -> dict[str, Trajectory]:
    """One trajectory per ``--odometry-from`` spec, keyed by the agent it is for."""
    out: dict[str, Trajectory] = {}
    for spec in specs:
        name, path, bag_spec = parse_odometry_spec(spec)
        if name in out:
            raise ConfigError(f"odometry_from: two sources for agent {name!r}")
        if not Path(path).exists():
            raise FormatError(f"{path}: no such file or folder (odometry source of {name})")
        if bag_spec is None:
            from studio.converters.tum import read_tum_trajectory

            traj = read_tum_trajectory(path, name=name, warn=warn)
        else:
            from studio.converters.rosbag import read_bag

            traj = read_bag(path, {name: bag_spec}, warn=warn)[0]
        out[name] = traj
    return out


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vectors of unit quaternions ``(n, 4)`` (x y z w), angles in [0, pi]."""
    q = quat_canonical(np.asarray(q, dtype=np.float64))
    v, w = q[:, 0:3], q[:, 3]
    s = np.linalg.norm(v, axis=1)
    angle = 2.0 * np.arctan2(s, w)
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 2.0)
    return v * scale[:, None]


def poses_at(traj: Trajectory, stamps_ns: np.ndarray, *, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``traj`` at ``stamps_ns``: positions linearly interpolated, orientations by slerp. A stamp
    outside the trajectory's time span raises FormatError naming ``what``."""
    st = traj.stamps_ns
    t = np.asarray(stamps_ns, dtype=np.int64)
    outside = np.flatnonzero((t < st[0]) | (t > st[-1]))
    if outside.size:
        k = int(outside[0])
        raise FormatError(
            f"{traj.source or traj.name}: {what} covers {st[0] / NS_PER_S:.9f}..{st[-1] / NS_PER_S:.9f} s, "
            f"but keyframe {k} is at {t[k] / NS_PER_S:.9f} s ({outside.size} keyframes outside)"
        )
    hi = np.clip(np.searchsorted(st, t, side="left"), 1, len(st) - 1) if len(st) > 1 else np.zeros(len(t), int)
    if len(st) == 1:
        return np.repeat(traj.positions_xyz, len(t), axis=0), np.repeat(traj.quat_xyzw, len(t), axis=0)
    lo = hi - 1
    span = (st[hi] - st[lo]).astype(np.float64)
    alpha = ((t - st[lo]).astype(np.float64) / span)[:, None]
    pos = traj.positions_xyz[lo] + alpha * (traj.positions_xyz[hi] - traj.positions_xyz[lo])
    q0, q1 = traj.quat_xyzw[lo], traj.quat_xyzw[hi]
    step = quat_to_rotvec(quat_mul(quat_conj(q0), q1))
    quat = quat_mul(q0, quat_from_rotvec(alpha * step))
    return pos, quat / np.linalg.norm(quat, axis=1, keepdims=True)


def _source_for(name: str, sources: Mapping[str, Trajectory]) -> Trajectory | None:
    """The source of agent ``name``, or of the trajectory it was split from (``alpha_2``: ``alpha``)."""
    if name in sources:
        return sources[name]
    base, sep, part = name.rpartition("_")
    return sources.get(base) if sep and part.isdigit() else None


def _fit_variances(sq: np.ndarray, regressors: np.ndarray) -> np.ndarray:
    """Non-negative coefficients ``c`` of ``sq ~ regressors @ c`` (columns scaled for conditioning)."""
    from scipy.optimize import nnls

    scale = np.maximum(np.abs(regressors).max(axis=0), 1e-300)
    coef, _ = nnls(regressors / scale, sq)
    return coef / scale


def _se2_errors(gt: np.ndarray, src: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar relative motions of ``gt`` and ``src`` rows ``x y yaw``: (source's measurement,
    error ``gt_rel^-1 src_rel`` rows, gt_rel rows)."""
    g = np.column_stack(relative_planar_pose(gt[:-1, 0], gt[:-1, 1], gt[:-1, 2], gt[1:, 0], gt[1:, 1], gt[1:, 2]))
    s = np.column_stack(relative_planar_pose(src[:-1, 0], src[:-1, 1], src[:-1, 2], src[1:, 0], src[1:, 1], src[1:, 2]))
    e = np.column_stack(relative_planar_pose(g[:, 0], g[:, 1], g[:, 2], s[:, 0], s[:, 1], s[:, 2]))
    return s, e, g


def apply_odometry_sources(
    graph: PoseGraph, sources: Mapping[str, Trajectory], *, what: str = "the odometry source"
) -> tuple[PoseGraph, list[OdometryFit]]:
    """``graph`` with each agent's odometry edges, information and initial estimate taken from its
    source (agents without one keep theirs), and the fit per agent with a source.

    Per agent: the source at the keyframes' stamps, its relative motions and their errors against
    the ground truth (:func:`_planar_motion`, :func:`_spatial_motion`), the variance model fitted to
    them (:func:`_fit_information`), then the agent's new odometry and initial estimate."""
    agents: list[AgentGraph] = []
    fits: list[OdometryFit] = []
    for agent in graph.agents:
        src = _source_for(agent.name, sources)
        if src is None or agent.num_poses < 2 or agent.ground_truth is None:
            agents.append(agent)
            continue
        pos, quat = poses_at(src, agent.stamps_ns, what=what)
        m = agent.num_poses - 1
        motion = (_planar_motion if graph.kind is PoseKind.SE2 else _spatial_motion)(agent.ground_truth, pos, quat)
        ct, cr, info = _fit_information(graph.kind, motion)
        odometry = Edges(graph.kind, np.arange(m), np.arange(1, m + 1), motion.measurements, info)
        agents.append(dataclasses.replace(agent, initial=motion.initial, odometry=odometry))
        et, er, dist = motion.translation_errors, motion.rotation_errors, motion.distance_m
        travelled = float(dist.sum())
        fits.append(
            OdometryFit(
                agent.name,
                src.source or src.name,
                m,
                math.sqrt(ct[0]),
                math.sqrt(ct[1]),
                math.sqrt(cr[0]),
                math.sqrt(cr[1]),
                math.sqrt(cr[2]),
                float(np.sqrt(np.mean(np.sum(et**2, axis=1)))),
                float(np.sqrt(np.mean(np.sum(er**2, axis=1)))),
                float(np.linalg.norm(et, axis=1).sum() / travelled) if travelled > 0 else math.nan,
            )
        )
    return dataclasses.replace(graph, agents=tuple(agents)), fits


@dataclass(frozen=True, eq=False)
class _Motion:
    """A source's motion between an agent's keyframes, against the ground truth's."""

    measurements: np.ndarray
    """The source's relative motion per odometry edge (the agent's pose rows)."""
    translation_errors: np.ndarray
    """``(m, 2)`` or ``(m, 3)``: the error's translation, in the first keyframe's frame [m]."""
    rotation_errors: np.ndarray
    """``(m, 1)`` or ``(m, 3)``: the error's rotation (angle or rotation vector) [rad]."""
    distance_m: np.ndarray
    """The true distance of each edge [m]."""
    turn_rad: np.ndarray
    """The true rotation angle of each edge [rad]."""
    initial: np.ndarray
    """Dead reckoning: the source's motion composed from the true first keyframe."""


def _planar_motion(gt: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> _Motion:
    """:class:`_Motion` of SE(2) keyframes ``gt`` (rows ``x y yaw``), the source's yaw from ``quat``."""
    src_planar = np.column_stack([pos[:, 0:2], yaw_from_quat_xyzw(quat)])
    meas, e, g = _se2_errors(gt, src_planar)
    rel0 = np.column_stack(
        relative_planar_pose(
            src_planar[0, 0],
            src_planar[0, 1],
            src_planar[0, 2],
            src_planar[:, 0],
            src_planar[:, 1],
            src_planar[:, 2],
        )
    )
    c, s = math.cos(gt[0, 2]), math.sin(gt[0, 2])
    initial = np.column_stack(
        [
            gt[0, 0] + c * rel0[:, 0] - s * rel0[:, 1],
            gt[0, 1] + s * rel0[:, 0] + c * rel0[:, 1],
            normalize_angle(gt[0, 2] + rel0[:, 2]),
        ]
    )
    return _Motion(meas, e[:, 0:2], e[:, 2:3], np.linalg.norm(g[:, 0:2], axis=1), np.abs(g[:, 2]), initial)


def _spatial_motion(gt: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> _Motion:
    """:class:`_Motion` of SE(3) keyframes ``gt`` (rows ``x y z qx qy qz qw``)."""
    gp, gq = gt[:, 0:3], gt[:, 3:7]
    g_t = quat_rotate(quat_conj(gq[:-1]), gp[1:] - gp[:-1])
    g_q = quat_mul(quat_conj(gq[:-1]), gq[1:])
    s_t = quat_rotate(quat_conj(quat[:-1]), pos[1:] - pos[:-1])
    s_q = quat_canonical(quat_mul(quat_conj(quat[:-1]), quat[1:]))
    meas = np.column_stack([s_t, s_q])
    et = quat_rotate(quat_conj(g_q), s_t - g_t)
    er = quat_to_rotvec(quat_mul(quat_conj(g_q), s_q))
    dist, turn = np.linalg.norm(g_t, axis=1), np.linalg.norm(quat_to_rotvec(g_q), axis=1)
    q_align = quat_mul(gq[:1], quat_conj(quat[:1]))
    init_p = gp[0] + quat_rotate(np.repeat(q_align, len(pos), axis=0), pos - pos[0])
    init_q = quat_canonical(quat_mul(np.repeat(q_align, len(pos), axis=0), quat))
    initial = np.column_stack([init_p, init_q / np.linalg.norm(init_q, axis=1, keepdims=True)])
    return _Motion(meas, et, er, dist, turn, initial)


def _fit_information(kind: PoseKind, motion: _Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The variance models' coefficients (translation, rotation; floors at :data:`MIN_SIGMA`) fitted
    to ``motion``'s errors, and the information upper triangles they give each edge."""
    et, er, dist, turn = motion.translation_errors, motion.rotation_errors, motion.distance_m, motion.turn_rad
    m = len(dist)
    kt, kr = et.shape[1], er.shape[1]
    ct = _fit_variances((et**2).ravel(), np.repeat(np.column_stack([np.ones(m), dist**2]), kt, axis=0))
    cr = _fit_variances((er**2).ravel(), np.repeat(np.column_stack([np.ones(m), dist**2, turn**2]), kr, axis=0))
    ct[0], cr[0] = max(ct[0], MIN_SIGMA**2), max(cr[0], MIN_SIGMA**2)
    var_t = ct[0] + ct[1] * dist**2
    var_r = cr[0] + cr[1] * dist**2 + cr[2] * turn**2
    if kind is PoseKind.SE2:
        info = np.zeros((m, 6))
        info[:, _DIAG6] = np.column_stack([1 / var_t, 1 / var_t, 1 / var_r])
    else:
        info = np.zeros((m, 21))
        info[:, _DIAG21] = np.column_stack([1 / var_t] * 3 + [_SE3_QUAT_INFORMATION_SCALE / var_r] * 3)
    return ct, cr, info
