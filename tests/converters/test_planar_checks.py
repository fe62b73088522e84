"""``--planar`` sanity: a warning line when yaw would come from a near-vertical body axis or when the
dropped axis carries the motion; EuRoC's IMU body frame (x up, y right, z forward) as the default."""

from __future__ import annotations

import json

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.planar_checks import planar_warnings
from studio.converters.transforms import body_frame_rotation
from studio.core.geometry import normalize_angle
from studio.core.trajectory import Trajectory
from studio.io.multig2o import read_multi_g2o
from tests.converters.synthetic import loop_trajectory, write_tum_file

runner = CliRunner()


def run(*args):
    return runner.invoke(app, ["convert", *map(str, args)])


def _euroc_imu_sequence(root, name, phase):
    """An EuRoC sequence whose ground truth is the pose of an IMU mounted x up, y right, z forward."""
    folder = root / name / "mav0" / "state_groundtruth_estimate0"
    folder.mkdir(parents=True)
    s, p, q_flu = loop_trajectory(600, rate_hz=200.0, radius=3.0, phase=phase)
    r_flu_imu = Rotation.from_matrix(body_frame_rotation("urf"))
    q = (Rotation.from_quat(q_flu) * r_flu_imu).as_quat()
    rows = ["#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []"]
    for t, pp, qq in zip(s.tolist(), p.tolist(), q.tolist()):
        rows.append(
            ",".join([str(t), *map(repr, pp), repr(qq[3]), repr(qq[0]), repr(qq[1]), repr(qq[2])] + ["0.0"] * 9)
        )
    (folder / "data.csv").write_text("\n".join(rows) + "\n")
    return s, q_flu


def _yaw_increment_correlation(agent, stamps, q_flu):
    k = np.searchsorted(stamps, agent.stamps_ns)
    true_yaw = Rotation.from_quat(q_flu[k]).as_euler("ZYX")[:, 0]
    got = normalize_angle(np.diff(agent.ground_truth[:, 2]))
    want = normalize_angle(np.diff(true_yaw))
    return float(np.corrcoef(got, want)[0, 1]), got, want


def test_euroc_planar_takes_yaw_about_the_true_up_axis_by_default(tmp_path):
    s, q_flu = _euroc_imu_sequence(tmp_path, "MH_01_easy", 0.0)
    out = tmp_path / "ds"
    res = run("euroc", tmp_path / "MH_01_easy", "-o", out, "--planar", "--no-rrd")
    assert res.exit_code == 0, res.output
    assert "warning" not in res.output
    a = read_multi_g2o(out).agents[0]
    corr, got, want = _yaw_increment_correlation(a, s, q_flu)
    assert corr > 0.99 and np.allclose(got, want, atol=1e-9)
    assert json.loads((out / "report.json").read_text())["warnings"] == []


def test_a_near_vertical_yaw_axis_is_one_warning_line(tmp_path):
    _euroc_imu_sequence(tmp_path, "MH_01_easy", 0.0)
    out = tmp_path / "ds"
    # the IMU taken as FLU: x points up, its yaw is meaningless
    res = run("euroc", tmp_path / "MH_01_easy", "-o", out, "--planar", "--no-rrd", "--body-frame", "mh_01_easy=flu")
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("warning:")]
    assert lines == [
        "warning: mh_01_easy: --planar takes yaw from the body x axis, which points within 0 degrees of vertical "
        "(median): give the body frame, e.g. --body-frame mh_01_easy=urf for x up, y right, z forward"
    ]
    assert json.loads((out / "report.json").read_text())["warnings"] == [lines[0][len("warning: ") :]]
    # 3D conversions keep the IMU frame as the ground truth gives it, and warn of nothing
    res = run("euroc", tmp_path / "MH_01_easy", "-o", tmp_path / "d3", "--no-rrd")
    assert res.exit_code == 0 and "warning" not in res.output


def test_a_camera_world_frame_warns_that_the_dropped_axis_carries_the_motion(tmp_path):
    s, p, q = loop_trajectory(400, radius=5.0)
    cam_from_flu = body_frame_rotation("rdf").T  # world axes of a camera frame: x right, y down, z forward
    p_cam = p @ cam_from_flu.T
    q_cam = (Rotation.from_matrix(cam_from_flu) * Rotation.from_quat(q)).as_quat()
    f = write_tum_file(tmp_path / "cam.tum", s, p_cam, q_cam)
    res = run("tum", f, "-o", tmp_path / "ds", "--planar", "--no-rrd")
    assert res.exit_code == 0, res.output
    warnings = [ln for ln in res.output.splitlines() if ln.startswith("warning:")]
    # the robot's x axis (its heading) lies in the camera frame's x-z plane, 45 degrees from its z
    # axis at the median: only the dropped axis is reported
    assert len(warnings) == 1
    assert warnings[0].startswith("warning: cam: --planar drops z, which carries most of the motion (spread ")


def test_planar_paths_give_no_warning():
    s, p, q = loop_trajectory(400, radius=5.0, climb=0.5)
    assert planar_warnings(Trajectory("alpha", s, p, q)) == []
