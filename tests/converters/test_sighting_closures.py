"""Robot sightings used downstream: ``--sightings-as-closures`` (an inter-agent loop closure per
sighting), ``studio check``'s range-bearing part and ``studio export --format jrl``'s
``BearingRangeFactorPose2``, on MR.CLAM-layout files the tests write (tests/converters/mrclam_files.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from studio.check import check, format_check
from studio.convert import ConvertConfig
from studio.converters.sightings import sighting_closures
from studio.core.errors import ConfigError
from studio.core.model import RangeBearing
from studio.core.residuals import chi2_terms, edge_errors
from studio.io.multig2o import read_multi_g2o
from studio.io.range_bearing import read_range_bearing
from tests.converters.mrclam_files import BEARING_SIGMA_RAD, RANGE_SIGMA_M, write_mrclam_dataset
from tests.converters.test_mrclam import run

_FAST = ("--lc-prob-intra", "0", "--lc-prob-inter", "0", "--no-rrd")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return write_mrclam_dataset(tmp_path_factory.mktemp("sc") / "MRCLAM_Dataset1", seconds=40.0, seed=5)


@pytest.fixture(scope="module")
def with_closures(dataset) -> Path:
    out = dataset.parent / "closures"
    # dense keyframes: each sighting is within 0.1 s of both robots' keyframes
    res = run("mrclam", dataset, "-o", out, "--planar", "--sightings-as-closures", "--keyframe-time", "0.1", *_FAST)
    assert res.exit_code == 0, res.output
    return out


def test_one_closure_per_sighting_from_observer_to_observed(with_closures):
    g = read_multi_g2o(with_closures)
    rb = read_range_bearing(with_closures / "range_bearing.txt", g)
    report = json.loads((with_closures / "report.json").read_text())
    assert len(g.inter) == len(rb) == report["counts"]["sighting_closures"] > 50
    assert np.array_equal(g.inter.from_agent, rb.observer_agent) and np.array_equal(g.inter.to_index, rb.observed_index)
    # the measured position: the range and bearing (the keyframes are within 0.1 s of the sighting)
    z = g.inter.measurements
    assert np.allclose(np.hypot(z[:, 0], z[:, 1]), rb.range_m, atol=0.05)
    assert np.allclose(np.arctan2(z[:, 1], z[:, 0]), rb.bearing_rad, atol=0.05)
    assert json.loads((with_closures / "convert.json").read_text())["sightings_as_closures"] is True


def test_closures_are_consistent_at_the_ground_truth(with_closures):
    """The simulated sightings have N(0, 0.05 m) range and N(0, 0.02 rad) bearing noise and the
    closures' information is propagated from the estimated sigmas: chi2/dof near 1 for the class,
    the translation block alone too (range and bearing keep their own weights)."""
    rep = check(with_closures)
    inter = rep.summary("inter")
    assert 0.7 < inter.total.factor < 1.4 and 0.7 < inter.translation.factor < 1.4, inter
    assert inter.rotation.factor < 1.5  # the drawn relative heading, lc_sigma_rad


def test_the_information_follows_range_and_bearing(with_closures):
    """A closure along the observer's x axis: range error along x, bearing error across (r sigma_b);
    the information of the error (g2o: in the frame of the measured pose) has those variances."""
    g = read_multi_g2o(with_closures)
    from studio.core.geometry import upper_to_matrix

    info = upper_to_matrix(g.inter.information_upper, 3)
    z = g.inter.measurements
    rb = read_range_bearing(with_closures / "range_bearing.txt", g)
    k = int(np.argmin(np.abs(rb.bearing_rad) + np.abs(z[:, 2])))  # nearly straight ahead, same heading
    cov = np.linalg.inv(info[k])
    assert cov[0, 0] == pytest.approx(rb.sigma_range_m[k] ** 2, rel=0.2)
    assert cov[1, 1] == pytest.approx((rb.range_m[k] * rb.sigma_bearing_rad[k]) ** 2, rel=0.2)


def test_closures_are_refused_for_a_source_without_sightings(tmp_path):
    with pytest.raises(ConfigError, match="sightings_as_closures: tum has no robot-to-robot sightings"):
        ConvertConfig("tum", ("a.txt",), sightings_as_closures=True)
    res = run("tum", tmp_path / "a.txt", "-o", tmp_path / "o", "--sightings-as-closures")
    assert res.exit_code == 2
    assert res.output == (
        "error: --sightings-as-closures: studio convert tum does not take it "
        "(only mrclam takes --sightings-as-closures)\n"
    )


def test_sighting_closures_draw_the_heading_from_its_own_seed_stream(with_closures):
    """Same seed, same closures; the odometry and loop-closure streams are untouched by them."""
    g = read_multi_g2o(with_closures)
    rb = read_range_bearing(with_closures / "range_bearing.txt", g)
    a = sighting_closures(g, rb, _truths(g), sigma_heading_rad=0.01, seed=0)
    b = sighting_closures(g, rb, _truths(g), sigma_heading_rad=0.01, seed=0)
    c = sighting_closures(g, rb, _truths(g), sigma_heading_rad=0.01, seed=1)
    assert np.array_equal(a.measurements, b.measurements) and not np.array_equal(a.measurements, c.measurements)
    assert np.array_equal(a.measurements[:, 0:2], c.measurements[:, 0:2])  # only the heading is drawn


def _truths(g):
    from studio.core.geometry import yaw_to_quat_xyzw
    from studio.core.trajectory import Trajectory

    out = []
    for a in g.agents:
        gt = a.ground_truth
        out.append(
            Trajectory(
                a.name, a.stamps_ns, np.column_stack([gt[:, 0:2], np.zeros(len(gt))]), yaw_to_quat_xyzw(gt[:, 2])
            )
        )
    return out


def test_check_reports_the_sightings_at_the_ground_truth(with_closures):
    rep = check(with_closures)
    c = rep.range_bearing
    assert c is not None and c.sightings > 50
    assert 0.6 < c.range_chi2_per_dof < 1.6 and 0.6 < c.bearing_chi2_per_dof < 1.6, c
    assert c.verdict_within_3_sigma in ("consistent",) or 0.6 < c.chi2_per_dof_within_3_sigma < 1.4
    text = format_check(rep)
    assert f"range-bearing sightings: {c.sightings} at their keyframes' ground truth" in text
    assert json.loads(rep.to_json())["range_bearing"]["sightings"] == c.sightings


def test_check_sees_the_keyframe_offsets_with_sparse_keyframes(dataset, tmp_path):
    """With the default keyframes (one per metre or 15 degrees) a sighting's keyframes are up to
    seconds away: the robots turn meanwhile, and the check says the bearings are inconsistent."""
    out = tmp_path / "sparse"
    res = run("mrclam", dataset, "-o", out, "--planar", *_FAST)
    assert res.exit_code == 0, res.output
    c = check(out).range_bearing
    assert c is not None and c.bearing_chi2_per_dof > 3.0
    assert c.median_keyframe_offset_s > 0.2


def test_a_dataset_without_sightings_has_no_range_bearing_part(tmp_path):
    from tests.converters.synthetic import loop_trajectory, write_tum_file

    files = []
    for k in range(2):
        stamps, pos, quat = loop_trajectory(300, phase=k)
        files.append(write_tum_file(tmp_path / f"r{k}.tum", stamps, pos, quat))
    res = run("tum", *files, "-o", tmp_path / "t", "--no-rrd")
    assert res.exit_code == 0, res.output
    rep = check(tmp_path / "t")
    assert rep.range_bearing is None and "range_bearing" not in json.loads(rep.to_json())
    assert "range-bearing" not in format_check(rep)


def test_jrl_carries_the_sightings_as_bearing_range_factors(with_closures, tmp_path):
    """Each sighting becomes a ``BearingRangeFactorPose2`` in the observer's measurements at its
    stamp; GTSAM's own factor built from the entry has, at the ground truth, the chi2 the check
    computes."""
    gtsam = pytest.importorskip("gtsam")
    from studio.export import export_dataset

    res = export_dataset(with_closures, tmp_path / "d.jrl", format="jrl")
    doc = json.loads((tmp_path / "d.jrl").read_text())
    entries = [
        (e["stamp"], f)
        for r in doc["measurements"].values()
        for e in r
        for f in e["measurements"]
        if f["type"] == "BearingRangeFactorPose2"
    ]
    g = read_multi_g2o(with_closures)
    rb = read_range_bearing(with_closures / "range_bearing.txt", g)
    assert len(entries) == len(rb) and not res.warnings
    truth = {}
    for values in doc["groundtruth"].values():
        for v in values:
            truth[v["key"]] = gtsam.Pose2(v["x"], v["y"], v["theta"])
    chi2 = 0.0
    for _, f in entries:
        m = f["measurement"]
        cov = np.array(f["covariance"]).reshape(2, 2)
        factor = gtsam.BearingRangeFactorPose2(
            f["key1"],
            f["key2"],
            gtsam.Rot2(m["bearing"]["theta"]),
            m["range"]["value"],
            gtsam.noiseModel.Gaussian.Covariance(cov),
        )
        values = gtsam.Values()
        values.insert(f["key1"], truth[f["key1"]])
        values.insert(f["key2"], truth[f["key2"]])
        chi2 += 2 * factor.error(values)
    assert chi2 / (2 * len(rb)) == pytest.approx(check(with_closures).range_bearing.chi2_per_dof, rel=1e-6)


def test_formats_without_range_bearing_say_they_leave_them_out(with_closures, tmp_path):
    from studio.export import export_dataset

    res = export_dataset(with_closures, tmp_path / "s", format="symbols")
    assert [w for w in res.warnings if "range-bearing sightings (range_bearing.txt) are left out" in w]


def test_jrl_of_3d_records_says_it_leaves_the_sightings_out(dataset, tmp_path):
    from studio.export import export_dataset

    out = tmp_path / "three_d"
    res = run("mrclam", dataset, "-o", out, *_FAST)
    assert res.exit_code == 0, res.output
    exp = export_dataset(out, tmp_path / "d.jrl", format="jrl")
    assert any("JRL's 3D bearing is a Unit3" in w for w in exp.warnings)
    assert "BearingRange" not in (tmp_path / "d.jrl").read_text()


def test_range_bearing_rows_naming_missing_vertices_are_refused_by_check(with_closures, tmp_path):
    import shutil

    from studio.core.errors import FormatError

    ds = tmp_path / "ds"
    shutil.copytree(with_closures, ds)
    lines = (ds / "range_bearing.txt").read_text().splitlines(keepends=True)
    data = [i for i, x in enumerate(lines) if not x.startswith("#")]
    parts = lines[data[0]].split()
    parts[2] = "99999"
    lines[data[0]] = " ".join(parts) + "\n"
    (ds / "range_bearing.txt").write_text("".join(lines))
    with pytest.raises(FormatError, match="sighting 1: agent .* vertex 99999 is not in the dataset"):
        check(ds)


def test_sighting_noise_is_estimated_near_the_simulated_one(with_closures):
    rb: RangeBearing = read_range_bearing(with_closures / "range_bearing.txt")
    assert abs(rb.sigma_range_m[0] - RANGE_SIGMA_M) < 0.3 * RANGE_SIGMA_M
    assert abs(rb.sigma_bearing_rad[0] - BEARING_SIGMA_RAD) < 0.3 * BEARING_SIGMA_RAD
    # the residuals behind the closures' chi2 (the studio's own g2o convention)
    g = read_multi_g2o(with_closures)
    gt = [a.ground_truth for a in g.agents]
    i = g.inter
    e = edge_errors(
        np.array([gt[a][k] for a, k in zip(i.from_agent, i.from_index)]),
        np.array([gt[a][k] for a, k in zip(i.to_agent, i.to_index)]),
        i.measurements,
    )
    assert 0.6 < float(np.median(chi2_terms(e, i.information_upper))) / 3 < 1.4


def test_keyframes_at_sightings_tie_each_side_to_its_own_time(dataset, tmp_path):
    """``--keyframes-at-sightings``: the pose nearest to every sighting is a keyframe of both robots,
    so the offsets are at most half a ground-truth step (10 ms here) and the check's bearings, free
    of the robots' motion in between, are consistent."""
    out = tmp_path / "at"
    res = run("mrclam", dataset, "-o", out, "--planar", "--keyframes-at-sightings", *_FAST)
    assert res.exit_code == 0, res.output
    g = read_multi_g2o(out)
    rb = read_range_bearing(out / "range_bearing.txt", g)
    assert np.abs(rb.observer_offset_ns).max() <= 5_000_000 and np.abs(rb.observed_offset_ns).max() <= 5_000_000
    c = check(out).range_bearing
    assert c is not None and 0.6 < c.bearing_chi2_per_dof < 1.6 and 0.6 < c.range_chi2_per_dof < 1.6, c
    assert json.loads((out / "convert.json").read_text())["keyframes_at_sightings"] is True
    sparse = tmp_path / "sparse"
    assert run("mrclam", dataset, "-o", sparse, "--planar", *_FAST).exit_code == 0
    assert sum(a.num_poses for a in g.agents) > sum(a.num_poses for a in read_multi_g2o(sparse).agents)
    assert "keyframes_at_sightings" not in json.loads((sparse / "convert.json").read_text())


def test_closures_need_planar_records(dataset, tmp_path):
    """A 3D graph's z, roll and pitch would have no measurement: one line, exit 2, nothing written."""
    res = run("mrclam", dataset, "-o", tmp_path / "o", "--sightings-as-closures", "--no-rrd")
    assert res.exit_code == 2 and not (tmp_path / "o").exists()
    assert res.output.strip().splitlines() == [
        "error: --sightings-as-closures: a range and a bearing are planar: the closures need planar records "
        "(add --planar)"
    ]
