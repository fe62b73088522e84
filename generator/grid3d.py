"""The 3D grid walk (``"studio": {"walk": "grid3d"}``): kollagen's walk that also climbs and descends.

Each step either moves horizontally as kollagen's (a turn of -1, 0, +1 or, with retrocession, 2
quarter turns, then ``stepsize`` metres ahead) or, with probability ``vertical_probability``, climbs or
descends ``vertical_step`` metres (half each) keeping its heading; a step has ``step_fragment`` poses.
The ground truth may tilt: pitch and roll drawn per pose from N(0, ``tilt_std_dev``^2).

Measurements are SE(3): ``Z = T_true (+) N`` with ``N = (dt, Exp(dr))``, ``dt`` the class's position
standard deviation times unit-variance draws of its noise model on each axis, ``dr`` the same with the
angle standard deviation. g2o's ``EDGE_SE3:QUAT`` error at the ground truth is then
``e = (-R_N^T dt, vec(q_N^-1)) ~ (-dt, -dr / 2)``: the information written is
``diag(I_p, I_p, I_p, 4 I_a, 4 I_a, 4 I_a)`` with kollagen's ``estimated_information_*`` keys
``I_p`` and ``I_a`` (4x on the quaternion slots since that error is half the angle).

Loop closures: as kollagen's (a revisited cell with ``same_position_*_probability``, else
``scale * exp(-5 d^2 / r^2)``), but in 3D and with ``d`` in metres (kollagen mixes grid cells and
metres); intra-agent candidates are the first visits of the cells within the sphere, at least one
step (``step_fragment`` poses) back; inter-agent ones the last visits of the lower-numbered agent's
cells. Every draw comes from numpy ``default_rng([seed, stream])`` streams, so the bytes depend only on
the config. Pure maths, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from studio.core.geometry import quat_conj, quat_from_rotvec, quat_mul, quat_rotate
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.units import NS_PER_S
from studio.generator.config import SynthConfig
from studio.generator.extensions import NoiseModel, StudioExtensions, sample_noise

__all__ = ["Walk3d", "generate_grid3d", "se3_information", "relative_se3", "compose_se3"]

_STREAM_WALK, _STREAM_ODOMETRY, _STREAM_LOOPS, _STREAM_INTER = 11, 12, 13, 14
_CHUNK = 4096


@dataclass(frozen=True, eq=False)
class Walk3d:
    cells: np.ndarray  # (n, 3) int64 grid cells
    heading: np.ndarray  # (n,) int64 quarter turns in 0..3
    poses: np.ndarray  # (n, 7) ground truth [x y z qx qy qz qw]


def se3_information(n: int, position: float, angle: float) -> np.ndarray:
    """``(n, 21)`` upper triangles of ``diag(p, p, p, 4a, 4a, 4a)`` (see the module doc)."""
    full = np.diag([position] * 3 + [4.0 * angle] * 3)
    rows, cols = np.triu_indices(6)
    return np.tile(full[rows, cols], (n, 1))


def relative_se3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Poses ``b`` in the frames of ``a`` (rows ``[x y z qx qy qz qw]``)."""
    qa_inv = quat_conj(a[:, 3:7])
    t = quat_rotate(qa_inv, b[:, 0:3] - a[:, 0:3])
    q = quat_mul(qa_inv, b[:, 3:7])
    return np.column_stack([t, q / np.linalg.norm(q, axis=1, keepdims=True)])


def compose_se3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    t = a[:, 0:3] + quat_rotate(a[:, 3:7], b[:, 0:3])
    q = quat_mul(a[:, 3:7], b[:, 3:7])
    return np.column_stack([t, q / np.linalg.norm(q, axis=1, keepdims=True)])


def noisy(
    true_rel: np.ndarray, model: NoiseModel, sigma_pos: float, sigma_ang: float, rng: np.random.Generator
) -> np.ndarray:
    """``true_rel (+) (dt, Exp(dr))`` with the model's draws (translation first, then rotation)."""
    n = len(true_rel)
    dt = sample_noise(model, rng, (n, 3)) * sigma_pos
    dr = sample_noise(model, rng, (n, 3)) * sigma_ang
    return compose_se3(true_rel, np.column_stack([dt, quat_from_rotvec(dr)]))


def _yaw_pitch_roll_quat(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    z = np.zeros_like(yaw)
    qz = np.column_stack([z, z, np.sin(yaw / 2), np.cos(yaw / 2)])
    qy = np.column_stack([z, np.sin(pitch / 2), z, np.cos(pitch / 2)])
    qx = np.column_stack([np.sin(roll / 2), z, z, np.cos(roll / 2)])
    return quat_mul(quat_mul(qz, qy), qx)


_DX = np.array([1, 0, -1, 0], dtype=np.int64)
_DY = np.array([0, 1, 0, -1], dtype=np.int64)


def walk3d(cfg: SynthConfig, ext: StudioExtensions, seed: int) -> Walk3d:
    g = ext.grid3d
    rng = np.random.default_rng([seed % 2**32, _STREAM_WALK, g.seed_offset % 2**32])
    S, F = cfg.number_of_steps, cfg.step_fragment
    vertical = rng.random(S) < g.vertical_probability
    up = np.where(rng.random(S) < 0.5, 1, -1)
    turns = rng.integers(-1, 2 + int(cfg.allow_retrocession), S)
    heading_steps = np.cumsum(np.where(vertical, 0, turns)) % 4
    heading_sub = np.repeat(heading_steps, F)
    vert_sub = np.repeat(vertical, F)
    d = np.column_stack(
        [
            np.where(vert_sub, 0, _DX[heading_sub]),
            np.where(vert_sub, 0, _DY[heading_sub]),
            np.where(vert_sub, np.repeat(up, F), 0),
        ]
    )
    cells = np.vstack([np.zeros((1, 3), dtype=np.int64), np.cumsum(d, axis=0)])
    heading = np.concatenate([[0], heading_sub]).astype(np.int64)
    h = cfg.stepsize / F
    v = g.vertical_step / F
    pos = cells.astype(np.float64) * np.array([h, h, v])
    yaw = (heading * (math.pi / 2) + math.pi) % (2 * math.pi) - math.pi
    tilt = rng.standard_normal((len(cells), 2)) * g.tilt_std_dev
    tilt[0] = 0.0
    q = _yaw_pitch_roll_quat(yaw, tilt[:, 0], tilt[:, 1])
    return Walk3d(cells, heading, np.column_stack([pos, q]))


def _shift(walk: Walk3d, shift: np.ndarray, cell: np.ndarray) -> Walk3d:
    poses = walk.poses.copy()
    poses[:, 0:3] += shift
    cells = walk.cells + np.rint(shift / cell).astype(np.int64)
    return Walk3d(cells, walk.heading, poses)


def _hits(query: np.ndarray, table: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(k, m, d)`` of every query row k and table row m at most ``radius`` apart, sorted by (k, m)."""
    from scipy.spatial import cKDTree

    if len(query) == 0 or len(table) == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z, np.zeros(0)
    tree = cKDTree(table)
    ks, ms, ds = [], [], []
    for lo in range(0, len(query), _CHUNK):
        res = cKDTree(query[lo : lo + _CHUNK]).sparse_distance_matrix(tree, radius, output_type="ndarray")
        ks.append(res["i"].astype(np.int64) + lo)
        ms.append(res["j"].astype(np.int64))
        ds.append(res["v"])
    k, m, d = np.concatenate(ks), np.concatenate(ms), np.concatenate(ds)
    order = np.lexsort((m, k))
    return k[order], m[order], d[order]


def _visits(cells: np.ndarray, which: str) -> np.ndarray:
    _, first = np.unique(cells, axis=0, return_index=True)
    if which == "first":
        return np.sort(first)
    _, rev = np.unique(cells[::-1], axis=0, return_index=True)
    return np.sort(len(cells) - 1 - rev)


def _probabilities(d: np.ndarray, same: float, scale: float, radius: float, eps: float) -> np.ndarray:
    return np.where(d < eps, same, scale * np.exp(-5.0 * d * d / (radius * radius)))


def _metric(cells: np.ndarray, cell: np.ndarray) -> np.ndarray:
    metric: np.ndarray = cells.astype(np.float64) * cell
    return metric


def generate_grid3d(cfg: SynthConfig, seeds: tuple[int, ...]) -> tuple[PoseGraph, list[Walk3d]]:
    """The 3D graph (SE3) of ``cfg`` and the walks (cells, headings) after alignment."""
    ext = cfg.studio
    assert ext is not None
    F = cfg.step_fragment
    cell = np.array([cfg.stepsize / F, cfg.stepsize / F, ext.grid3d.vertical_step / F])
    eps = 0.5 * float(cell.min())
    walks = [walk3d(cfg, ext, s) for s in seeds]
    if cfg.align:
        centre = [np.round(w.poses[:, 0:3].mean(axis=0)) for w in walks]
        walks = [_shift(w, centre[0] - c, cell) for w, c in zip(walks, centre)]
    agents = []
    for k, (w, a, seed) in enumerate(zip(walks, cfg.agents, seeds)):
        n = len(w.poses)
        rng_odo = np.random.default_rng([seed % 2**32, _STREAM_ODOMETRY])
        true_odo = relative_se3(w.poses[:-1], w.poses[1:])
        z_odo = noisy(true_odo, ext.noise_of("odometry"), a.std_dev_position, a.std_dev_angle, rng_odo)
        initial = _dead_reckon(w.poses[0], z_odo)
        odo = Edges(
            PoseKind.SE3,
            np.arange(n - 1),
            np.arange(1, n),
            z_odo,
            se3_information(n - 1, a.estimated_information_position, a.estimated_information_angle),
        )
        # intra-agent loop closures: first visits of cells, at least one step back
        first = _visits(w.cells, "first")
        kq, m, d = _hits(_metric(w.cells, cell), _metric(w.cells[first], cell), a.intra_loop_closure_radius)
        j = first[m]
        keep = j < kq - F
        kq, j, d = kq[keep], j[keep], d[keep]
        p = _probabilities(
            d,
            a.same_position_intra_loop_closure_probability,
            a.intra_loop_closure_probability_scaling,
            a.intra_loop_closure_radius,
            eps,
        )
        rng_lc = np.random.default_rng([seed % 2**32, _STREAM_LOOPS])
        acc = rng_lc.random(len(p)) < p
        fr, to = j[acc], kq[acc]
        z_lc = noisy(
            relative_se3(w.poses[fr], w.poses[to]),
            ext.noise_of("intra"),
            a.std_dev_intra_loop_closure_position,
            a.std_dev_intra_loop_closure_angle,
            rng_lc,
        )
        lcs = Edges(
            PoseKind.SE3,
            fr,
            to,
            z_lc.reshape(-1, 7),
            se3_information(len(fr), a.estimated_information_intra_position, a.estimated_information_intra_angle),
        )
        agents.append(
            AgentGraph(
                f"agent{k + 1}", PoseKind.SE3, np.arange(n, dtype=np.int64) * NS_PER_S, initial, w.poses, odo, lcs
            )
        )
    inter = _inter(cfg, walks, cell, eps) if len(walks) > 1 else InterAgentEdges.empty(PoseKind.SE3)
    graph = PoseGraph(PoseKind.SE3, tuple(agents), inter, {"generator": "studio grid3d", "name": cfg.name})
    return graph, walks


def _inter(cfg: SynthConfig, walks: list[Walk3d], cell: np.ndarray, eps: float) -> InterAgentEdges:
    assert cfg.studio is not None
    p = cfg.inter
    cols: list[list[np.ndarray]] = [[], [], [], [], []]
    for a in range(len(walks)):
        for b in range(a + 1, len(walks)):
            wa, wb = walks[a], walks[b]
            last = _visits(wa.cells, "last")
            kq, m, d = _hits(_metric(wb.cells, cell), _metric(wa.cells[last], cell), p.loop_closure_radius)
            j = last[m]
            prob = _probabilities(
                d,
                p.same_position_loop_closure_probability,
                p.loop_closure_probability_scaling,
                p.loop_closure_radius,
                eps,
            )
            rng = np.random.default_rng([p.random_number_generator_seed % 2**32, _STREAM_INTER, a, b])
            acc = rng.random(len(prob)) < prob
            fi, tj = kq[acc], j[acc]
            z = noisy(
                relative_se3(wb.poses[fi], wa.poses[tj]),
                cfg.studio.noise_of("inter"),
                p.std_dev_loop_closure_position,
                p.std_dev_loop_closure_angle,
                rng,
            )
            for c, val in zip(cols, (np.full(len(fi), b), fi, np.full(len(fi), a), tj, z.reshape(-1, 7))):
                c.append(val)
    meas = np.concatenate(cols[4])
    fa, fi, ta, ti = (np.concatenate(c) for c in cols[:4])
    return InterAgentEdges(
        PoseKind.SE3,
        fa,
        fi,
        ta,
        ti,
        meas,
        se3_information(len(meas), p.estimated_information_position, p.estimated_information_angle),
    )


def _dead_reckon(start: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """Poses ``start, start (+) rel[0], ...`` composed one by one (plain floats: short rows)."""
    out = np.empty((len(rel) + 1, 7))
    out[0] = start
    x, y, z, qx, qy, qz, qw = start.tolist()
    for k, (tx, ty, tz, bx, by, bz, bw) in enumerate(rel.tolist(), start=1):
        # t += R(q) t_rel
        ux, uy, uz = qy * tz - qz * ty, qz * tx - qx * tz, qx * ty - qy * tx
        ux, uy, uz = 2 * ux, 2 * uy, 2 * uz
        x += tx + qw * ux + (qy * uz - qz * uy)
        y += ty + qw * uy + (qz * ux - qx * uz)
        z += tz + qw * uz + (qx * uy - qy * ux)
        qx, qy, qz, qw = (
            qw * bx + qx * bw + qy * bz - qz * by,
            qw * by - qx * bz + qy * bw + qz * bx,
            qw * bz + qx * by - qy * bx + qz * bw,
            qw * bw - qx * bx - qy * by - qz * bz,
        )
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
        out[k] = (x, y, z, qx, qy, qz, qw)
    return out
