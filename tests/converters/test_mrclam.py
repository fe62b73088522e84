"""UTIAS MR.CLAM as it ships (files the tests write in the dataset's layout, tests/converters/mrclam_files.py):
five planar robots, their real (integrated) odometry with a fitted noise model, robot-to-robot
sightings in range_bearing.txt and the recording; and --odometry-from on a TUM pair and a bag topic."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.check import check
from studio.cli import app
from studio.convert import ConvertConfig, convert
from studio.converters.build import GraphOptions
from studio.converters.mrclam import integrate_unicycle
from studio.converters.odometry_source import parse_odometry_spec, poses_at, quat_to_rotvec
from studio.core.errors import ConfigError, FormatError
from studio.core.geometry import normalize_angle, quat_from_rotvec, relative_planar_pose
from studio.core.trajectory import Trajectory
from studio.io.multig2o import read_multi_g2o
from studio.io.range_bearing import read_range_bearing, write_range_bearing
from tests.converters.mrclam_files import (
    BEARING_SIGMA_RAD,
    RANGE_SIGMA_M,
    ROBOT_BARCODES,
    write_mrclam_dataset,
)
from tests.converters.synthetic import drifting_estimate, loop_trajectory, write_tum_file

runner = CliRunner()


def run(*args):
    return runner.invoke(app, ["convert", *map(str, args)])


def _rows(path: Path, columns: int) -> np.ndarray:
    return np.loadtxt(path, comments="#").reshape(-1, columns)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return write_mrclam_dataset(tmp_path_factory.mktemp("mrclam") / "MRCLAM_Dataset1", seconds=40.0, seed=3)


@pytest.fixture(scope="module")
def converted(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("out") / "m"
    res = run("mrclam", dataset, "-o", out, "--planar", "--odometry", "real")
    assert res.exit_code == 0, res.output
    return out, res.output


def test_five_planar_robots_whose_keyframe_yaw_is_the_files_orientation(dataset, converted):
    out, output = converted
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == [f"Robot{k}" for k in range(1, 6)]
    assert g.kind.value == "SE2"
    for k, a in enumerate(g.agents, start=1):
        rows = _rows(dataset / f"Robot{k}_Groundtruth.dat", 4)
        stamps = np.round(rows[:, 0] * 1e6).astype(np.int64) * 1000
        at = np.searchsorted(stamps, a.stamps_ns)
        assert np.array_equal(stamps[at], a.stamps_ns)  # keyframes are ground-truth rows
        assert np.allclose(a.ground_truth[:, 2], normalize_angle(rows[at, 3]), atol=1e-12)
        assert a.num_poses > 20
    assert "range-bearing sightings:" in output and "real odometry Robot1: drift" in output


def _integrate_fine(rows: np.ndarray, t0: float, t1: float) -> tuple[float, float, float]:
    """Euler integration of the commands at 0.1 ms from t0 to t1 (the robot's frame at t0)."""
    t = np.arange(t0, t1, 1e-4)
    k = np.clip(np.searchsorted(rows[:, 0], t, side="right") - 1, 0, len(rows) - 1)
    v = np.where(t < rows[0, 0], 0.0, rows[k, 1])
    w = np.where(t < rows[0, 0], 0.0, rows[k, 2])
    th = np.concatenate([[0.0], np.cumsum(w * 1e-4)])[:-1]
    return float(np.sum(v * np.cos(th)) * 1e-4), float(np.sum(v * np.sin(th)) * 1e-4), float(np.sum(w) * 1e-4)


def test_real_odometry_edges_integrate_the_odometry_file_between_keyframes(dataset, converted):
    out, _ = converted
    g = read_multi_g2o(out)
    a = g.agents[1]
    rows = _rows(dataset / "Robot2_Odometry.dat", 3)
    t0_file = rows[0, 0]
    rows[:, 0] -= t0_file  # seconds from the first command, for precision
    for e in (0, 7, len(a.odometry) - 1):
        t0 = a.stamps_ns[e] / 1e9 - t0_file
        t1 = a.stamps_ns[e + 1] / 1e9 - t0_file
        dx, dy, dth = _integrate_fine(rows, t0, t1)
        m = a.odometry.measurements[e]
        assert abs(m[0] - dx) < 2e-4 and abs(m[1] - dy) < 2e-4 and abs(normalize_angle(m[2] - dth)) < 2e-4
    # the odometry is not the ground truth: the simulated wheels slip (scale error, noise)
    gt = a.ground_truth
    rel = np.column_stack(relative_planar_pose(*gt[:-1].T, *gt[1:].T))
    assert np.abs(a.odometry.measurements[:, 0] - rel[:, 0]).max() > 0.005
    # the initial estimate is the odometry's dead reckoning from the first true pose
    assert np.allclose(a.initial[0], gt[0])
    assert np.linalg.norm(a.initial[-1, :2] - gt[-1, :2]) > 0.05


def test_the_noise_model_is_fitted_reported_and_checked(converted):
    out, _ = converted
    report = json.loads((out / "report.json").read_text())
    assert report["odometry"]["kind"] == "real"
    fits = report["odometry"]["fits"]
    assert [f["agent"] for f in fits] == [f"Robot{k}" for k in range(1, 6)]
    # the simulated wheels over-run by 3..11 %: the drift per metre grows with it, robot by robot
    drifts = [f["drift_m_per_m"] for f in fits]
    assert all(0.01 < d < 0.2 for d in drifts) and drifts[4] > drifts[0]
    assert all(f["sigma_m_per_m"] > 0.005 for f in fits)
    g = read_multi_g2o(out)
    info = g.agents[0].odometry.information_upper
    gt = g.agents[0].ground_truth
    d = np.hypot(*relative_planar_pose(*gt[:-1].T, *gt[1:].T)[:2])  # the true distance of each edge
    var_t = fits[0]["sigma_min_m"] ** 2 + (fits[0]["sigma_m_per_m"] * d) ** 2
    assert np.allclose(info[:, 0], 1 / var_t, rtol=1e-6, atol=0) and np.all(info[:, [1, 2, 4]] == 0)
    # studio check on the real odometry: fitted in-sample, so near 1 overall; the translation is
    # over-confident because the scale error is a bias the diagonal model does not carry
    rep = check(out)
    odo = rep.summary("odometry")
    assert 0.7 < odo.total.factor < 2.0
    assert odo.verdicts["rotation"] == "consistent"


def test_sightings_are_written_counted_and_their_noise_estimated(dataset, converted):
    out, _ = converted
    g = read_multi_g2o(out)
    rb = read_range_bearing(out / "range_bearing.txt", g)
    report = json.loads((out / "report.json").read_text())
    expected = 0
    robot_codes = set(ROBOT_BARCODES)
    for k in range(1, 6):
        rows = _rows(dataset / f"Robot{k}_Measurement.dat", 4)
        expected += int(np.isin(rows[:, 1], list(robot_codes - {ROBOT_BARCODES[k - 1]})).sum())
    assert len(rb) == expected == report["counts"]["range_bearing"] > 50
    assert report["range_bearing"]["source_counts"]["unknown_barcodes"] == 5
    assert report["range_bearing"]["source_counts"]["landmark_sightings"] > 0
    assert abs(report["range_bearing"]["sigma_range_m"] - RANGE_SIGMA_M) < 0.3 * RANGE_SIGMA_M
    assert abs(report["range_bearing"]["sigma_bearing_rad"] - BEARING_SIGMA_RAD) < 0.3 * BEARING_SIGMA_RAD
    assert not np.any(rb.observer_agent == rb.observed_agent)
    # each side is the keyframe nearest in time, its offset written
    for side in ("observer", "observed"):
        agent, index, offset = (getattr(rb, f"{side}_{c}") for c in ("agent", "index", "offset_ns"))
        kf = np.array([g.agents[a].stamps_ns[i] for a, i in zip(agent, index)])
        assert np.array_equal(rb.stamps_ns - kf, offset)
        for a, i, s in list(zip(agent, index, rb.stamps_ns))[:50]:
            assert np.abs(g.agents[a].stamps_ns - s).min() == abs(g.agents[a].stamps_ns[i] - s)


def test_the_recording_shows_the_sightings_and_record_reads_them_back(converted, tmp_path):
    from studio.recording.rrd_checks import fingerprint_rrd

    out, _ = converted
    fp = fingerprint_rrd(out / f"{out.name}.rrd")
    assert any("/world/Robot1/sightings" in k or "world/Robot1/sightings" in k for k in fp)
    res = runner.invoke(app, ["record", str(out), "-o", str(tmp_path / "again.rrd")])
    assert res.exit_code == 0, res.output
    again = fingerprint_rrd(tmp_path / "again.rrd")
    assert {k: v for k, v in again.items() if "sightings" in k} == {k: v for k, v in fp.items() if "sightings" in k}


def test_synthetic_odometry_stays_the_default_and_the_source_is_guessed(dataset, tmp_path):
    res = run(dataset, "-o", tmp_path / "s", "--planar", "--no-rrd")
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "s" / "report.json").read_text())
    assert report["odometry"] == {"kind": "synthetic", "source": "ground truth", "fits": []}
    assert json.loads((tmp_path / "s" / "convert.json").read_text())["source"] == "mrclam"
    assert (tmp_path / "s" / "range_bearing.txt").is_file()


def test_3d_records_of_mrclam_keep_real_odometry_planar(dataset, tmp_path):
    cfg = ConvertConfig("mrclam", (str(dataset),), options=GraphOptions(), odometry="real")
    res = convert(cfg, tmp_path / "m3", rrd=False)
    a = res.build.graph.agents[0]
    assert a.kind.value == "SE3"
    assert np.abs(a.odometry.measurements[:, [2, 3, 4]]).max() < 1e-12  # z, qx, qy
    assert len(res.odometry_fits) == 5


def test_integrate_unicycle_is_exact_on_arcs():
    w = 0.5
    stamps = np.round(np.linspace(0, 2 * math.pi / w, 7) * 1e9).astype(np.int64)  # six long steps
    x, y, th = integrate_unicycle(stamps, np.full(7, 0.2), np.full(7, w))
    assert abs(x[-1]) < 1e-9 and abs(y[-1]) < 1e-9 and abs(th[-1] - 2 * math.pi) < 1e-9
    assert abs(np.hypot(x[3], y[3]) - 2 * 0.2 / w) < 1e-9  # half a circle: the diameter


# ----------------------------------------------------------------------------------------- bad input


def _copy(dataset: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(dataset, dst)
    return dst


def test_bad_mrclam_input_is_one_line_exit_2_and_nothing_written(dataset, tmp_path):
    broken = _copy(dataset, tmp_path / "MRCLAM_Dataset2")
    (broken / "Robot3_Groundtruth.dat").unlink()
    res = run("mrclam", broken, "-o", tmp_path / "o")
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        f"error: {broken / 'Robot3_Groundtruth.dat'}: missing (an MR.CLAM dataset has RobotK_Groundtruth.dat for K = 1..5)"
    ]
    assert not (tmp_path / "o").exists()
    bad = _copy(dataset, tmp_path / "MRCLAM_Dataset3")
    lines = (bad / "Robot2_Odometry.dat").read_text().splitlines()
    lines[9] = lines[9].replace("\t", "\tx", 1)
    (bad / "Robot2_Odometry.dat").write_text("\n".join(lines) + "\n")
    res = run("mrclam", bad, "-o", tmp_path / "o", "--odometry", "real")
    assert res.exit_code == 2
    assert res.output.strip().startswith(f"error: {bad / 'Robot2_Odometry.dat'}:10: ")
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_rows_of_the_wrong_width_or_not_finite_name_their_line(dataset, tmp_path):
    bad = _copy(dataset, tmp_path / "MRCLAM_Dataset4")
    path = bad / "Robot1_Groundtruth.dat"
    lines = path.read_text().splitlines()
    # one row a column short and the next a column long: as many numbers as the layout expects
    lines[5] = lines[5].rsplit("\t", 1)[0]
    lines[6] = lines[6] + "\t0.5"
    path.write_text("\n".join(lines) + "\n")
    res = run("mrclam", bad, "-o", tmp_path / "o")
    assert res.exit_code == 2
    assert res.output.strip() == (
        f"error: {path}:6: expected 4 columns (MR.CLAM ground truth: time [s], x [m], y [m], "
        "orientation [rad]), found 3"
    )
    lines = path.read_text().splitlines()
    lines[5], lines[6] = lines[7], lines[8].replace(lines[8].split("\t")[1], "nan", 1)
    path.write_text("\n".join(lines) + "\n")
    res = run("mrclam", bad, "-o", tmp_path / "o")
    assert res.exit_code == 2 and res.output.strip() == f"error: {path}:7: value is not finite"
    assert not (tmp_path / "o").exists()


def test_odometry_real_needs_a_source_with_odometry(tmp_path):
    s, p, q = loop_trajectory(100)
    f = write_tum_file(tmp_path / "a.tum", s, p, q)
    res = run("tum", f, "-o", tmp_path / "o", "--odometry", "real")
    assert res.exit_code == 2
    assert "tum ships no odometry of its own; give a second source with --odometry-from" in res.output
    with pytest.raises(ConfigError, match="expected NAME=FILE.tum or NAME=BAG:/topic"):
        ConvertConfig("tum", (str(f),), odometry_from=("nofile",))


# ------------------------------------------------------------------------------ --odometry-from


def test_odometry_from_a_tum_pair_gives_the_sources_relative_motions(tmp_path):
    gt, vio = {}, {}
    for k, name in enumerate(("alpha", "bob")):
        s, p, q = loop_trajectory(600, rate_hz=20.0, radius=8.0, phase=k)
        gt[name] = write_tum_file(tmp_path / f"{name}.tum", s, p, q)
        vp, vq = drifting_estimate(s, p, q, scale=1.05, yaw_rate=0.002, seed=k)
        vio[name] = (s, vp, vq)
        write_tum_file(tmp_path / f"{name}_vio.txt", s, vp, vq)
    out = tmp_path / "ds"
    res = run(
        "tum", gt["alpha"], gt["bob"], "-o", out, "--planar", "--no-rrd",
        "--odometry-from", f"alpha={tmp_path / 'alpha_vio.txt'}",
        "--odometry-from", f"bob={tmp_path / 'bob_vio.txt'}",
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    g = read_multi_g2o(out)
    for a in g.agents:
        s, vp, vq = vio[a.name]
        src = Trajectory(a.name, s, vp, vq)
        pp, qq = poses_at(src, a.stamps_ns, what="test")
        from studio.core.geometry import yaw_from_quat_xyzw

        yaw = yaw_from_quat_xyzw(qq)
        rel = np.column_stack(relative_planar_pose(pp[:-1, 0], pp[:-1, 1], yaw[:-1], pp[1:, 0], pp[1:, 1], yaw[1:]))
        assert np.allclose(a.odometry.measurements, rel, atol=1e-9)
    report = json.loads((out / "report.json").read_text())
    assert report["odometry"]["source"] == "odometry_from"
    fits = report["odometry"]["fits"]
    assert [f["agent"] for f in fits] == ["alpha", "bob"]
    for f in fits:  # 5 % scale error: about 0.05 m of error per metre
        assert 0.03 < f["drift_m_per_m"] < 0.08
    cfg = json.loads((out / "convert.json").read_text())
    assert cfg["odometry_from"] == [f"alpha={tmp_path / 'alpha_vio.txt'}", f"bob={tmp_path / 'bob_vio.txt'}"]
    # only bob from a second source: alpha keeps synthetic odometry
    res = run("tum", gt["alpha"], gt["bob"], "-o", tmp_path / "one", "--planar", "--no-rrd",
              "--odometry-from", f"bob={tmp_path / 'bob_vio.txt'}")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert [f["agent"] for f in json.loads((tmp_path / "one" / "report.json").read_text())["odometry"]["fits"]] == [
        "bob"
    ]
    # a source that does not cover the keyframes, and an unknown agent: one line, exit 2
    s, vp, vq = vio["bob"]
    write_tum_file(tmp_path / "short.txt", s[100:], vp[100:], vq[100:])
    res = run("tum", gt["bob"], "-o", tmp_path / "x", "--odometry-from", f"bob={tmp_path / 'short.txt'}")
    assert res.exit_code == 2 and "short.txt: the odometry source covers" in res.output
    res = run("tum", gt["bob"], "-o", tmp_path / "x", "--odometry-from", f"carol={tmp_path / 'short.txt'}")
    assert res.exit_code == 2 and "--odometry-from: no agent 'carol' (agents: bob)" in res.output
    assert not (tmp_path / "x").exists()


def test_odometry_from_a_bag_topic(tmp_path):
    from tests.converters.bags import Msgs, typestore, write_bag

    s, p, q = loop_trajectory(400, rate_hz=20.0, radius=6.0)
    gt = write_tum_file(tmp_path / "alpha.tum", s, p, q)
    vp, vq = drifting_estimate(s, p, q, scale=0.98, yaw_rate=-0.003, seed=5)
    m = Msgs(typestore("ros1"))
    write_bag(
        tmp_path / "run",
        "ros1",
        {"/alpha/odom": [(int(t), m.Odometry(int(t), pp, qq)) for t, pp, qq in zip(s, vp, vq)]},
    )
    bag = next(tmp_path.glob("run*"))
    out = tmp_path / "ds"
    res = run("tum", gt, "-o", out, "--no-rrd", "--odometry-from", f"alpha={bag}:/alpha/odom")
    assert res.exit_code == 0, res.output
    g = read_multi_g2o(out)
    a = g.agents[0]
    pp, qq = poses_at(Trajectory("alpha", s, vp, vq), a.stamps_ns, what="test")
    from studio.core.geometry import quat_conj, quat_mul, quat_rotate

    t_rel = quat_rotate(quat_conj(qq[:-1]), pp[1:] - pp[:-1])
    assert np.allclose(a.odometry.measurements[:, :3], t_rel, atol=1e-9)
    q_rel = quat_mul(quat_conj(qq[:-1]), qq[1:])
    assert np.allclose(np.abs(np.sum(a.odometry.measurements[:, 3:] * q_rel, axis=1)), 1.0, atol=1e-9)
    fit = json.loads((out / "report.json").read_text())["odometry"]["fits"][0]
    assert fit["source"].endswith("/alpha/odom") or "/alpha/odom" in fit["source"]
    assert 0.005 < fit["drift_m_per_m"] < 0.06


def test_odometry_spec_parsing():
    assert parse_odometry_spec("a=x.tum") == ("a", "x.tum", None)
    assert parse_odometry_spec("a=run.bag:/a/odom") == ("a", "run.bag", "/a/odom")
    assert parse_odometry_spec("a=bagdir:/tf:odom:base") == ("a", "bagdir", "/tf:odom:base")


def test_quat_to_rotvec_inverts_quat_from_rotvec():
    r = np.random.default_rng(0).normal(0, 1, (50, 3))
    r *= np.minimum(1.0, 3.0 / np.linalg.norm(r, axis=1))[:, None]
    assert np.allclose(quat_to_rotvec(quat_from_rotvec(r)), r, atol=1e-12)


def test_range_bearing_file_round_trip_and_bad_lines(converted, tmp_path):
    out, _ = converted
    g = read_multi_g2o(out)
    rb = read_range_bearing(out / "range_bearing.txt", g)
    write_range_bearing(tmp_path / "rb.txt", rb)
    assert (tmp_path / "rb.txt").read_bytes() == (out / "range_bearing.txt").read_bytes()
    text = (out / "range_bearing.txt").read_text().splitlines()
    for bad, msg in (
        (" ".join(text[3].split()[:10]), ":4: expected 11 columns, found 10"),
        (" ".join([*text[3].split()[:2], "99999", *text[3].split()[3:]]), ":4: agent [0-9] has no vertex 99999"),
        ("1 1 0 1 0 1.0 0.0 0.1 0.1 0 0", ":4: agent 1 sights itself"),
    ):
        (tmp_path / "bad.txt").write_text("\n".join([*text[:3], bad]) + "\n")
        with pytest.raises(FormatError, match=msg):
            read_range_bearing(tmp_path / "bad.txt", g)
