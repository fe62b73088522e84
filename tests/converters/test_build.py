"""converters.build: keyframes, origin, gaps, odometry noise model, loop closures, outliers, seeds."""

from __future__ import annotations

import numpy as np
import pytest

from studio.converters.build import GraphOptions, build_graph, pairs_within, select_keyframes, step_turns_rad
from studio.core.errors import ConfigError
from studio.core.geometry import quat_conj, quat_mul, quat_rotate, se3_poses_to_planar
from studio.core.model import PoseKind
from studio.core.trajectory import Trajectory
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory

NOISELESS = dict(
    odo_sigma_m_per_m=0.0,
    odo_sigma_rad_per_rad=0.0,
    odo_sigma_rad_per_m=0.0,
    odo_sigma_min_m=0.0,
    odo_sigma_min_rad=0.0,
    lc_sigma_m=0.0,
    lc_sigma_rad=0.0,
)


def traj(name, n=600, **kw):
    s, p, q = loop_trajectory(n, **kw)
    return Trajectory(name, s, p, q, name)


def test_pairs_within_matches_brute_force():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-20, 20, size=(700, 3)) * [1, 1, 0.2]
    i, j, d = pairs_within(pts, 2.5)
    full = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    bi, bj = np.nonzero(np.triu(full < 2.5, k=1))
    assert len(bi) > 100
    assert list(zip(i.tolist(), j.tolist())) == list(zip(bi.tolist(), bj.tolist()))
    np.testing.assert_allclose(d, full[bi, bj])


def test_keyframes_every_distance_and_angle():
    s, p, q = loop_trajectory(1001, radius=10.0, laps=1.0)  # 62.8 m of path and 360 degrees of turn
    kf, gaps = select_keyframes(s, p, step_turns_rad(q), GraphOptions(keyframe_distance=2.0, keyframe_angle=0.0))
    assert not gaps.any()
    assert kf[0] == 0 and kf[-1] == 1000
    assert len(kf) == 32 + 1  # floor(62.8 / 2) = 31 crossings + first + last
    kf2, _ = select_keyframes(s, p, step_turns_rad(q), GraphOptions(keyframe_distance=0.0, keyframe_angle=30.0))
    assert len(kf2) == 12 + 1  # 11 crossings of 30 degrees before 360 (reached at the last pose) + first + last
    kf3, _ = select_keyframes(
        s, p, step_turns_rad(q), GraphOptions(keyframe_distance=0.0, keyframe_angle=0.0, keyframe_time=10.0)
    )
    assert np.all(np.diff(s[kf3][:-1]) == 10_000_000_000)


def test_shared_origin_keeps_relative_placement_of_utm_agents():
    a = traj("a", centre=(UTM_EAST, UTM_NORTH, 120.0))
    b = traj("b", centre=(UTM_EAST + 3.0, UTM_NORTH - 4.0, 121.0), phase=1.0)
    res = build_graph([a, b], GraphOptions())
    np.testing.assert_array_equal(res.origin_xyz, a.positions_xyz[0])
    ga, gb = (x.ground_truth for x in res.graph.agents)
    np.testing.assert_allclose(ga[0, :3], 0.0, atol=0)
    np.testing.assert_allclose(gb[0, :3], b.positions_xyz[0] - a.positions_xyz[0], atol=1e-9)
    assert np.abs(ga[:, :3]).max() < 25  # local, not UTM-sized
    # the initial estimate starts at the true first pose of each agent
    np.testing.assert_allclose(res.graph.agents[1].initial[0], gb[0], atol=1e-12)


def test_noiseless_odometry_is_the_true_relative_pose_and_dead_reckoning_the_truth():
    res = build_graph([traj("a", climb=3.0)], GraphOptions(**NOISELESS))
    ag = res.graph.agents[0]
    gt = ag.ground_truth
    np.testing.assert_allclose(ag.initial[:, :3], gt[:, :3], atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(ag.initial[:, 3:] * gt[:, 3:], axis=1)), 1.0, atol=1e-12)
    rel_t = quat_rotate(quat_conj(gt[:-1, 3:]), gt[1:, :3] - gt[:-1, :3])
    np.testing.assert_allclose(ag.odometry.measurements[:, :3], rel_t, atol=1e-12)


def test_odometry_information_matches_the_noise_model_and_initial_is_dead_reckoning():
    o = GraphOptions(
        odo_sigma_m_per_m=0.1,
        odo_sigma_rad_per_rad=0.05,
        odo_sigma_rad_per_m=0.01,
        odo_sigma_min_m=0.01,
        odo_sigma_min_rad=0.002,
        seed=5,
    )
    ag = build_graph([traj("a", n=2000)], o).graph.agents[0]
    gt = ag.ground_truth
    t_rel = quat_rotate(quat_conj(gt[:-1, 3:]), gt[1:, :3] - gt[:-1, :3])
    q_rel = quat_mul(quat_conj(gt[:-1, 3:]), gt[1:, 3:])
    d = np.linalg.norm(t_rel, axis=1)
    theta = 2 * np.arctan2(np.linalg.norm(q_rel[:, :3], axis=1), np.abs(q_rel[:, 3]))
    sig_t = 0.01 + 0.1 * d
    sig_r = 0.002 + 0.05 * theta + 0.01 * d
    info = ag.odometry.information_upper
    np.testing.assert_allclose(info[:, 0], 1 / sig_t**2, rtol=1e-9)
    # rotation information in g2o's EDGE_SE3:QUAT convention (quaternion vector part ~ angle / 2)
    np.testing.assert_allclose(info[:, 20], 4 / sig_r**2, rtol=1e-9)
    assert np.count_nonzero(info[:, [1, 2, 3, 4, 5]]) == 0
    # the translation errors are distributed as the model says (standardised std dev ~ 1)
    z = (ag.odometry.measurements[:, :3] - t_rel) / sig_t[:, None]
    assert 0.85 < z.std() < 1.15 and abs(z.mean()) < 0.15
    # initial = composition of the measurements, one by one
    p, q = gt[0, :3].copy(), gt[0, 3:].copy()
    for k in range(len(ag.odometry)):
        m = ag.odometry.measurements[k]
        p = p + quat_rotate(q[None], m[None, :3])[0]
        q = quat_mul(q[None], m[None, 3:])[0]
    np.testing.assert_allclose(ag.initial[-1, :3], p, atol=1e-9)


def test_a_gap_is_bridged_reported_and_less_certain():
    s, p, q = loop_trajectory(800, rate_hz=10.0)
    keep = (np.arange(800) < 300) | (np.arange(800) >= 350)  # 5 s without ground truth
    t = Trajectory("carol", s[keep], p[keep], q[keep], "carol")
    res = build_graph([t], GraphOptions(max_gap=1.0, gap_sigma_m_per_s=0.2))
    [gap] = res.gaps
    assert gap.agent == "carol" and gap.seconds == pytest.approx(5.1)
    assert gap.start_ns == s[299] and gap.end_ns == s[350]
    ag = res.graph.agents[0]
    assert ag.stamps_ns[gap.vertex] == s[299] and ag.stamps_ns[gap.vertex + 1] == s[350]
    assert len(ag.odometry) == ag.num_poses - 1  # still one connected chain
    info_xx = ag.odometry.information_upper[:, 0]
    assert info_xx[gap.vertex] < 0.1 * np.delete(info_xx, gap.vertex).min()
    assert gap.metres == pytest.approx(np.linalg.norm(p[350] - p[299]), rel=1e-9)
    assert build_graph([t], GraphOptions(max_gap=6.0)).gaps == ()


def test_intra_loop_closures_respect_radius_and_minimum_separation():
    o = GraphOptions(lc_prob_intra=1.0, lc_radius=1.5, lc_min_time=20.0, lc_min_index=5, **NOISELESS)
    ag = build_graph([traj("a", n=1200, laps=3.0)], o).graph.agents[0]
    lc = ag.loop_closures
    assert len(lc) > 20
    gt = ag.ground_truth
    d = np.linalg.norm(gt[lc.from_index, :3] - gt[lc.to_index, :3], axis=1)
    assert d.max() < 1.5
    assert np.all(ag.stamps_ns[lc.to_index] - ag.stamps_ns[lc.from_index] >= 20e9)
    assert np.all(lc.to_index - lc.from_index >= 5)
    t_rel = quat_rotate(quat_conj(gt[lc.from_index, 3:]), gt[lc.to_index, :3] - gt[lc.from_index, :3])
    np.testing.assert_allclose(lc.measurements[:, :3], t_rel, atol=1e-12)


def test_loop_closure_probability_falls_off_as_kollagen():
    two = [traj("a", n=3000, laps=6.0), traj("b", n=3000, laps=6.0, phase=0.3)]
    o = dict(lc_radius=3.0, lc_prob_intra=0.0)
    n_full = len(build_graph(two, GraphOptions(lc_prob_inter=1.0, **o)).graph.inter)
    n_half = len(build_graph(two, GraphOptions(lc_prob_inter=0.5, **o)).graph.inter)
    res = build_graph(two, GraphOptions(lc_prob_inter=1.0, **o))
    assert len(build_graph(two, GraphOptions(lc_prob_inter=0.0, **o)).graph.inter) == 0
    assert 0.4 < n_half / n_full < 0.6
    # accepted pairs are biased to short distances: mean exp(-5(d/R)^2) over candidates < 1
    g = res.graph
    ga, gb = g.agents[0].ground_truth, g.agents[1].ground_truth
    d = np.linalg.norm(ga[g.inter.from_index, :3] - gb[g.inter.to_index, :3], axis=1)
    assert d.max() < 3.0 and np.mean(d) < 1.5


def test_rendezvous_links_only_poses_close_in_time():
    a = traj("a", n=1000, laps=2.0, t0_s=1000.0)
    b = traj("b", n=1000, laps=2.0, t0_s=1030.0)  # same path, 30 s later
    o = dict(lc_prob_inter=1.0, lc_prob_intra=0.0, lc_radius=2.0)
    anytime = build_graph([a, b], GraphOptions(**o)).graph
    assert len(anytime.inter) > 0
    rdv = build_graph([a, b], GraphOptions(rendezvous=5.0, **o)).graph
    sa, sb = rdv.agents[0].stamps_ns, rdv.agents[1].stamps_ns
    dt = np.abs(sa[rdv.inter.from_index] - sb[rdv.inter.to_index])
    assert len(rdv.inter) < len(anytime.inter)
    assert len(dt) == 0 or dt.max() <= 5e9


def test_heading_compatibility_drops_opposite_directions():
    a = traj("a", n=800)
    s, p, q = loop_trajectory(800)
    # b drives the same circle the other way round: headings opposite where the paths meet
    b = Trajectory("b", s, p[::-1].copy(), quat_mul(q[::-1], np.array([[0, 0, 1.0, 0]] * 800)), "b")
    o = dict(lc_prob_inter=1.0, lc_prob_intra=0.0)
    assert len(build_graph([a, b], GraphOptions(**o)).graph.inter) > 10
    assert len(build_graph([a, b], GraphOptions(lc_max_heading=90.0, **o)).graph.inter) == 0


def test_outliers_point_at_wrong_far_vertices():
    two = [traj("a", n=2000, laps=4.0), traj("b", n=2000, laps=4.0, phase=0.5)]
    res = build_graph(two, GraphOptions(outlier_fraction=0.2, lc_prob_inter=1.0, lc_prob_intra=1.0))
    total = res.candidates["intra_loop_closures"] + res.candidates["inter_loop_closures"]
    assert len(res.outliers) == round(0.2 * total) and len(res.outliers) > 5
    g = res.graph
    for fa, fv, ta, tv in res.outliers.tolist():
        pa, pb = g.agents[fa].ground_truth[fv, :3], g.agents[ta].ground_truth[tv, :3]
        assert np.linalg.norm(pa - pb) >= 2 * 2.0


def test_same_seed_same_graph_other_seed_other_noise():
    two = [traj("a"), traj("b", phase=1.0)]
    r1, r2 = build_graph(two, GraphOptions(seed=7)), build_graph(two, GraphOptions(seed=7))
    r3 = build_graph(two, GraphOptions(seed=8))
    from studio.core.model import graphs_equal

    assert graphs_equal(r1.graph, r2.graph)
    assert not graphs_equal(r1.graph, r3.graph)
    # a loop-closure option does not change the odometry noise (one stream per purpose)
    r4 = build_graph(two, GraphOptions(seed=7, lc_prob_inter=0.1))
    np.testing.assert_array_equal(r1.graph.agents[0].odometry.measurements, r4.graph.agents[0].odometry.measurements)


def test_planar_projection_gives_se2():
    res = build_graph([traj("a", climb=5.0)], GraphOptions(planar=True))
    ag = res.graph.agents[0]
    assert res.graph.kind.value == "SE2" and ag.initial.shape[1] == 3
    assert ag.odometry.information_upper.shape[1] == 6


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(lc_radius=0.0), "^lc_radius: must be > 0"),
        (dict(lc_prob_inter=1.5), "^lc_prob_inter: a probability"),
        (dict(outlier_fraction=1.0), "^outlier_fraction"),
        (dict(keyframe_distance=-1.0), "^keyframe_distance"),
        (dict(seed=-1), "^seed"),
        (dict(max_gap=float("nan")), "^max_gap"),
    ],
)
def test_bad_options_raise_config_errors_naming_the_option(kw, match):
    """The library names the option; the command line maps it to its flag (test_convert_cli)."""
    with pytest.raises(ConfigError, match=match) as err:
        GraphOptions(**kw)
    assert err.value.option == next(iter(kw))


def test_duplicate_agent_names_are_rejected():
    with pytest.raises(ConfigError, match="two agents are named 'a'"):
        build_graph([traj("a"), traj("a")], GraphOptions())


def test_integer_options_become_floats():
    o = GraphOptions(lc_radius=3, seed=2)
    assert isinstance(o.lc_radius, float) and o.lc_radius == 3.0 and o.seed == 2


def test_planar_build_agrees_with_the_spatial_one_on_a_flat_path():
    """Planar graphs are built in SE(2) directly; on a flat path they match the spatial build: the
    same keyframes, ground truth, loop-closure pairs and translation noise (one random stream)."""
    trajs = [traj("a"), traj("b", phase=1.0)]
    opts = dict(seed=5, lc_radius=3.0)
    flat = build_graph(trajs, GraphOptions(planar=True, **opts)).graph
    full = build_graph(trajs, GraphOptions(**opts)).graph
    assert flat.kind is PoseKind.SE2 and full.kind is PoseKind.SE3
    for a2, a3 in zip(flat.agents, full.agents):
        np.testing.assert_array_equal(a2.stamps_ns, a3.stamps_ns)
        np.testing.assert_allclose(a2.ground_truth, se3_poses_to_planar(a3.ground_truth), atol=1e-9)
        np.testing.assert_allclose(a2.odometry.measurements[:, 0:2], a3.odometry.measurements[:, 0:2], atol=1e-9)
        np.testing.assert_array_equal(a2.loop_closures.from_index, a3.loop_closures.from_index)
        np.testing.assert_array_equal(a2.loop_closures.to_index, a3.loop_closures.to_index)
        # the planar information is the x, y, yaw block of the spatial one, whose rotation
        # information is on the quaternion's vector part (4 times the angle's)
        np.testing.assert_allclose(
            a2.odometry.information_upper[:, [0, 3, 5]],
            a3.odometry.information_upper[:, [0, 6, 20]] / [1, 1, 4],
            rtol=1e-12,
        )
        assert not a2.odometry.information_upper[:, [1, 2, 4]].any()
    assert len(flat.inter) == len(full.inter) > 0
    # dead reckoning composes the noisy planar steps
    a = flat.agents[0]
    step = a.odometry.measurements[0]
    c, s = np.cos(a.ground_truth[0, 2]), np.sin(a.ground_truth[0, 2])
    np.testing.assert_allclose(
        a.initial[1, 0:2], a.ground_truth[0, 0:2] + [c * step[0] - s * step[1], s * step[0] + c * step[1]]
    )
