"""The studio block: noise models' statistics, outliers as configured, 3D walks, information frames,
deterministic bytes, and the block's validation."""

from __future__ import annotations

import copy
import hashlib
import math

import numpy as np
import pytest

from studio.core.errors import ConfigError
from studio.core.geometry import normalize_angle, relative_planar_pose
from studio.core.residuals import chi2_terms, edge_errors
from studio.generator.extended import generate_studio
from studio.generator.extensions import NoiseModel, sample_noise
from studio.generator.grid3d import relative_se3
from studio.generator.kollagen import generate
from studio.generator.presets import preset
from studio.io.synth_config import parse_synth_config, synth_config_to_json

MODELS = {
    "gaussian": ({"model": "gaussian"}, 3.0),
    "student_t": ({"model": "student_t", "dof": 6}, 3.0 + 6.0 / (6 - 4)),
    "laplace": ({"model": "laplace"}, 6.0),
    "mixture": ({"model": "mixture", "weights": [0.9, 0.1], "scales": [1, 5]}, None),
}


def _mixture_kurtosis(w, s):
    w, s = np.asarray(w, float), np.asarray(s, float)
    w = w / w.sum()
    m2 = np.sum(w * s**2)
    return float(3 * np.sum(w * s**4) / m2**2)


MODELS["mixture"] = (MODELS["mixture"][0], _mixture_kurtosis([0.9, 0.1], [1, 5]))


def _small(steps=250, agents=3, studio=None, **top):
    doc = synth_config_to_json(preset("multi3500x8"))
    doc["number_of_steps"] = steps
    doc["number_of_agents"] = agents
    doc["agent_parameters"]["agent_specific"] = doc["agent_parameters"]["agent_specific"][:agents]
    doc.update(top)
    if studio is not None:
        doc["studio"] = {"version": 1, **studio}
    return doc


def _cfg(doc, name="t"):
    return parse_synth_config(copy.deepcopy(doc), name=name)


def _variance_ok(samples: np.ndarray, variance: float, kurtosis: float) -> tuple[float, float]:
    """(relative error of the sample variance, 5 standard errors of it)."""
    n = samples.size
    s2 = float(np.mean(samples**2))  # zero mean known
    return abs(s2 / variance - 1.0), 5.0 * math.sqrt((kurtosis - 1.0) / n)


def _model(spec) -> NoiseModel:
    doc = _small(studio={"noise": {"odometry": spec}})
    return _cfg(doc).studio.noise_of("odometry")


@pytest.mark.parametrize("name", sorted(MODELS))
def test_noise_model_draws_have_unit_variance_and_their_kurtosis(name):
    spec, kurt = MODELS[name]
    x = sample_noise(_model(spec), np.random.default_rng(3), (400_000,))
    err, bound = _variance_ok(x, 1.0, kurt)
    assert err < bound
    k = float(np.mean(x**4) / np.mean(x**2) ** 2)
    assert abs(k - kurt) < 0.25 * kurt  # the shape is the model's, not a Gaussian's (3)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_grid3d_residuals_at_ground_truth_match_the_model(name):
    spec, kurt = MODELS[name]
    doc = _small(steps=400, studio={"walk": "grid3d", "noise": {c: spec for c in ("odometry", "intra", "inter")}})
    cfg = _cfg(doc)
    g = generate_studio(cfg).output.graph
    a0 = cfg.agents[0]
    checks = []
    for a, ac in zip(g.agents, cfg.agents):
        gt = a.ground_truth
        for edges, sp, sa in (
            (a.odometry, ac.std_dev_position, ac.std_dev_angle),
            (a.loop_closures, ac.std_dev_intra_loop_closure_position, ac.std_dev_intra_loop_closure_angle),
        ):
            true = relative_se3(gt[edges.from_index], gt[edges.to_index])
            n = relative_se3(true, edges.measurements)  # = (dt, Exp(dr))
            checks.append((n[:, 0:3], sp))
            v = np.linalg.norm(n[:, 3:6], axis=1)
            angle = 2 * np.arctan2(v, n[:, 6])
            checks.append((n[:, 3:6] * (angle / np.where(v > 0, v, 1))[:, None], sa))
    trans = np.concatenate([c[0].ravel() / c[1] for c in checks[0::2]])
    rot = np.concatenate([c[0].ravel() / c[1] for c in checks[1::2]])
    for x in (trans, rot):
        err, bound = _variance_ok(x, 1.0, kurt)
        assert err < bound, (name, err, bound)
    assert a0.std_dev_position > 0


@pytest.mark.parametrize("name", ["student_t", "laplace", "mixture"])
def test_planar_residuals_at_ground_truth_match_the_model_and_kollagens_walk_stays(name):
    spec, kurt = MODELS[name]
    doc = _small(steps=600, studio={"noise": {c: spec for c in ("odometry", "intra", "inter")}})
    cfg = _cfg(doc)
    g = generate_studio(cfg).output.graph
    ref = generate(_cfg(_small(steps=600))).graph
    frag_len = cfg.stepsize / cfg.step_fragment
    odo_l, odo_t, lc = [], [], []
    for a, r, ac in zip(g.agents, ref.agents, cfg.agents):
        assert np.array_equal(a.ground_truth, r.ground_truth)  # kollagen's walk and closures are kept
        assert np.array_equal(a.loop_closures.to_index, r.loop_closures.to_index)
        gt, z = a.ground_truth, a.odometry.measurements
        ell = z[:, 0] * np.cos(z[:, 2]) + z[:, 1] * np.sin(z[:, 2])
        odo_l.append((ell - frag_len) / ac.std_dev_position)
        true_turn = normalize_angle(gt[1:, 2] - gt[:-1, 2])
        odo_t.append(normalize_angle(z[:, 2] - true_turn) / ac.std_dev_angle)
        e = a.loop_closures
        dx, dy, dt = relative_planar_pose(*gt[e.from_index].T, *gt[e.to_index].T)
        res = e.measurements - np.column_stack([dx, dy, dt])
        sigma = np.array([ac.std_dev_intra_loop_closure_position] * 2 + [ac.std_dev_intra_loop_closure_angle])
        lc.append((res / sigma).ravel())
    for x in (np.concatenate(odo_l), np.concatenate(odo_t), np.concatenate(lc)):
        err, bound = _variance_ok(x, 1.0, kurt)
        assert err < bound, (name, err, bound)


def test_gaussian_block_keeps_kollagens_bytes_and_outliers_keep_the_inliers():
    plain = generate(_cfg(_small())).graph
    same = generate_studio(_cfg(_small(studio={"noise": {"odometry": {"model": "gaussian"}}}))).output.graph
    for a, b in zip(plain.agents, same.agents):
        assert np.array_equal(a.odometry.measurements, b.odometry.measurements)
    out = generate_studio(_cfg(_small(studio={"outliers": {"intra_fraction": 0.1, "inter_fraction": 0.1}})))
    g = out.output.graph
    for a, b in zip(plain.agents, g.agents):
        assert np.array_equal(a.loop_closures.measurements, b.loop_closures.measurements)
        assert np.array_equal(a.initial, b.initial)
    assert np.array_equal(plain.inter.measurements, g.inter.measurements)


def test_outliers_fraction_kinds_and_geometry():
    studio = {
        "outliers": {
            "intra_fraction": 0.1,
            "inter_fraction": 0.2,
            "kinds": {"random": 1, "aliasing": 3},
            "random_radius": 6.0,
            "random_min_radius": 2.0,
            "aliasing_min_distance": 8.0,
            "seed": 4,
        }
    }
    cfg = _cfg(_small(steps=500, studio=studio))
    res = generate_studio(cfg)
    g, planted = res.output.graph, res.outliers
    n_intra = sum(len(a.loop_closures) for a in g.agents)
    n_inter = len(g.inter)
    rows = planted.rows
    intra = rows[:, 0] == rows[:, 2]
    assert intra.sum() == round(0.1 * n_intra) and (~intra).sum() == round(0.2 * n_inter)
    kinds = np.array(planted.kinds)
    # aliasing first while look-alike places exist; random takes the share of those that have none
    for sel, k in ((intra, round(0.1 * n_intra)), (~intra, round(0.2 * n_inter))):
        assert (kinds[sel] == "random").sum() >= round(0.25 * k) and (kinds[sel] == "aliasing").sum() > 0.2 * k
    assert (kinds[intra] == "aliasing").sum() == round(0.75 * round(0.1 * n_intra))  # enough look-alikes here
    ref = generate(_cfg(_small(steps=500))).graph
    true_to = {}
    for ka, a in enumerate(ref.agents):
        for f, t in zip(a.loop_closures.from_index.tolist(), a.loop_closures.to_index.tolist()):
            true_to.setdefault((ka, f, ka), set()).add(t)
    for fa, fi, ta, ti in zip(
        ref.inter.from_agent.tolist(),
        ref.inter.from_index.tolist(),
        ref.inter.to_agent.tolist(),
        ref.inter.to_index.tolist(),
    ):
        true_to.setdefault((fa, fi, ta), set()).add(ti)
    for (fa, fv, ta, tv), kind in zip(rows.tolist(), planted.kinds):
        gt = g.agents[ta].ground_truth
        dists = [np.hypot(*(gt[tv, :2] - gt[t, :2])) for t in true_to[(fa, fv, ta)]]
        if kind == "random":
            assert any(2.0 - 1e-9 <= d <= 6.0 + 1e-9 for d in dists)
        else:
            assert min(dists) >= 8.0 or len(dists) > 1
            assert any(np.isclose(normalize_angle(gt[tv, 2] - gt[t, 2]), 0) for t in true_to[(fa, fv, ta)])
    # every outlier is far off at the ground truth, in chi2
    e = g.inter
    wrong = np.isin(
        np.arange(len(e)),
        [
            k
            for k in range(len(e))
            if (e.from_agent[k], e.from_index[k], e.to_agent[k], e.to_index[k]) in {tuple(r) for r in rows.tolist()}
        ],
    )
    gts = [a.ground_truth for a in g.agents]
    xi = np.array([gts[a][i] for a, i in zip(e.from_agent, e.from_index)])
    xj = np.array([gts[a][i] for a, i in zip(e.to_agent, e.to_index)])
    chi2 = chi2_terms(edge_errors(xi, xj, e.measurements), e.information_upper)
    assert np.median(chi2[wrong]) > 1000 and np.median(chi2[~wrong]) < 5


def test_grid3d_climbs_and_closes_loops_in_z():
    cfg = _cfg(_small(steps=500, studio={"walk": "grid3d", "grid3d": {"vertical_probability": 0.2}}))
    g = generate_studio(cfg).output.graph
    z_levels = set()
    closes = 0
    for a in g.agents:
        z = a.ground_truth[:, 2]
        z_levels |= set(np.round(z, 6).tolist())
        lc = a.loop_closures
        for f, t in zip(lc.from_index.tolist(), lc.to_index.tolist()):
            if np.ptp(z[f : t + 1]) >= 1.0 - 1e-9:  # the loop went up or down a level and came back near
                closes += 1
    assert len(z_levels) > 8 and closes > 20
    assert len(g.inter) > 0 and np.ptp(g.inter.measurements[:, 2]) > 0.5
    assert g.kind.value == "SE3"


def test_grid3d_information_is_consistent_with_g2os_error():
    cfg = _cfg(_small(steps=400, studio={"walk": "grid3d", "grid3d": {"tilt_std_dev": 0.05}}))
    g = generate_studio(cfg).output.graph
    chi2, dof = 0.0, 0
    for a in g.agents:
        for e in (a.odometry, a.loop_closures):
            gt = a.ground_truth
            chi2 += float(
                chi2_terms(edge_errors(gt[e.from_index], gt[e.to_index], e.measurements), e.information_upper).sum()
            )
            dof += 6 * len(e)
    assert abs(chi2 / dof - 1.0) < 0.05


def test_information_frame_measurement_makes_exact_odometry_consistent():
    doc = _small(steps=1500, agents=1, exact_information_matrix=True)
    spec = doc["agent_parameters"]["agent_specific"][0]
    spec["std_dev_position"], spec["std_dev_angle"] = 0.005, 0.2
    raw = generate_studio(_cfg(doc)).output
    rot = generate_studio(_cfg({**doc, "studio": {"version": 1, "information_frame": "measurement"}})).output
    a = raw.graph.agents[0]
    gt, z = a.ground_truth, a.odometry.measurements
    e = edge_errors(gt[:-1], gt[1:], z)
    turning = np.abs(normalize_angle(gt[1:, 2] - gt[:-1, 2])) > 1.0
    kollagen = chi2_terms(e, raw.exact_odometry_information[0])
    studio = chi2_terms(e, rot.exact_odometry_information[0])
    assert abs(studio[turning].mean() / 3 - 1) < 0.2 and abs(studio[~turning].mean() / 3 - 1) < 0.2
    assert kollagen[turning].mean() / 3 > 5  # kollagen's is only right on straight edges
    assert np.array_equal(raw.graph.agents[0].odometry.measurements, z)


def _digest(folder):
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(p.relative_to(folder).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def test_same_seed_same_bytes_and_outliers_txt(tmp_path):
    from studio.io.outliers_txt import read_outlier_kinds
    from studio.synth import synthesize

    studio = {
        "walk": "grid3d",
        "noise": {"inter": {"model": "student_t", "dof": 4}},
        "outliers": {"intra_fraction": 0.05, "inter_fraction": 0.05, "seed": 2},
    }
    cfg = _cfg(_small(steps=200, studio=studio), name="d")
    r1 = synthesize(cfg, tmp_path / "a", rrd=False, jobs=1)
    synthesize(cfg, tmp_path / "b", rrd=False, jobs=2)
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")
    rows, kinds = read_outlier_kinds(r1.dataset_dir / "outliers.txt")
    assert len(rows) == len(r1.outliers.rows) > 0 and set(kinds) <= {"random", "aliasing"}
    assert not (tmp_path / "a" / "d_singleg2o").exists()
    assert "VERTEX_SE3:QUAT" in (r1.dataset_dir / "agent1" / "posegraph.g2o").read_text()[:200]
    other = _cfg(
        {
            **_small(steps=200, studio=studio),
            "inter_agent_loop_closure_parameters": {
                **_small()["inter_agent_loop_closure_parameters"],
                "random_number_generator_seed": 9,
            },
        },
        name="d",
    )
    synthesize(other, tmp_path / "c", rrd=False, jobs=1)
    assert _digest(tmp_path / "a") != _digest(tmp_path / "c")


@pytest.mark.parametrize(
    ("studio", "match"),
    [
        (
            {"walk": "grid3d", "grid3d": {"vertical_prob": 0.1}},
            r"studio\.grid3d\.vertical_prob: unknown key.*vertical_probability",
        ),
        ({"nosie": {}}, r"studio\.nosie: unknown key.*'noise'"),
        (
            {"noise": {"odometry": {"model": "student_t", "dof": 2}}},
            r"studio\.noise\.odometry\.dof: 2\.0 is outside \(2\.0",
        ),
        ({"noise": {"odometry": {"model": "cauchy"}}}, r"studio\.noise\.odometry\.model: must be one of"),
        ({"outliers": {"intra_fraction": 1.5}}, r"studio\.outliers\.intra_fraction"),
        ({"information_frame": "measurement"}, r"studio\.information_frame: .*exact_information_matrix"),
    ],
)
def test_bad_studio_block_is_refused_with_its_json_path(studio, match):
    with pytest.raises(ConfigError, match=match):
        _cfg(_small(studio=studio))


def test_version_is_required_and_checked():
    doc = _small()
    doc["studio"] = {"walk": "grid3d"}
    with pytest.raises(ConfigError, match=r"studio\.version: missing key"):
        _cfg(doc)
    doc["studio"] = {"version": 2}
    with pytest.raises(ConfigError, match=r"studio\.version: 2 is not a version"):
        _cfg(doc)


def test_effective_config_round_trips():
    for name in ("cube3d", "multi3500x8_outliers"):
        cfg = preset(name)
        assert parse_synth_config(synth_config_to_json(cfg), name=name) == cfg
