"""Real datasets as they ship: S3E without orientation, AirMuseum scenario folders and body frames,
EuRoC, KITTI and Kimera-Multi files, --split, source guessing, and kollagen's own multi-g2o reader."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from studio.cli import app
from studio.convert import ConvertConfig, convert, read_convert_config
from studio.converters.build import GraphOptions
from studio.converters.kitti import CAMERA_TO_Z_UP
from studio.converters.transforms import body_frame_rotation
from studio.core.geometry import normalize_angle, se3_poses_to_planar
from studio.io.multig2o import read_multi_g2o
from studio.samples import euroc_sequence as _euroc_sequence
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory, write_tum_file

runner = CliRunner()


def run(*args):
    return runner.invoke(app, ["convert", *map(str, args)])


def curved_path(n: int, seed: int, rate_hz: float = 2.0, speed: float = 1.5):
    """A real-looking drive: speed ~1.5 m/s, heading wandering smoothly, UTM-sized, 2 Hz."""
    rng = np.random.default_rng(seed)
    turn = np.convolve(rng.normal(0, 0.25, n), np.ones(6) / 6, mode="same")
    yaw = np.cumsum(turn) + seed
    xy = np.cumsum(np.column_stack([np.cos(yaw), np.sin(yaw)]) * speed / rate_hz, axis=0)
    pos = np.column_stack([UTM_EAST + xy[:, 0] + 30 * seed, UTM_NORTH + xy[:, 1], np.full(n, 20.0)])
    stamps = 1_660_988_157_745_130_000 + (np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    return stamps, pos, yaw


# ------------------------------------------------------------------------------------------- S3E


def test_s3e_as_shipped_derives_headings_that_follow_the_real_turns(tmp_path):
    seq = tmp_path / "S3E_Square_1"
    seq.mkdir()
    truth = {}
    for k, name in enumerate(["Alpha", "Bob"]):
        stamps, pos, yaw = curved_path(900, seed=k)
        truth[name.lower()] = (stamps, yaw)
        identity = np.tile([0.0, 0.0, 0.0, 1.0], (len(stamps), 1))  # RTK: positions only
        write_tum_file(seq / f"{name}_gt.txt", stamps, pos, identity, header=None)
    out = tmp_path / "ds"
    r = run("s3e", seq, "-o", out, "--planar", "--keyframe-distance", "2")
    assert r.exit_code == 0, r.output
    assert "headings derived from motion (the orientation carried no information): alpha, bob" in r.output
    report = json.loads((out / "report.json").read_text())
    assert [a["orientation"] for a in report["agents"]] == ["derived from motion"] * 2
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["alpha", "bob"]  # lower case
    for a in g.agents:
        stamps, yaw = truth[a.name]
        true_yaw = np.interp(a.stamps_ns.astype(float), stamps.astype(float), np.unwrap(yaw))
        true_inc = normalize_angle(np.diff(true_yaw))
        odo_inc = a.odometry.measurements[:, 2]
        assert np.corrcoef(odo_inc, true_inc)[0, 1] >= 0.8
        # and the written ground truth carries the derived heading
        assert np.corrcoef(normalize_angle(np.diff(a.ground_truth[:, 2])), true_inc)[0, 1] >= 0.8
    # keeping the identity quaternions instead, the odometry says the robot never turned
    kept = convert(
        ConvertConfig("s3e", (str(seq),), orientation="keep", options=GraphOptions(planar=True)),
        tmp_path / "kept",
        rrd=False,
    )
    a = kept.build.graph.agents[0]
    stamps, yaw = truth["alpha"]
    true_inc = normalize_angle(np.diff(np.interp(a.stamps_ns.astype(float), stamps.astype(float), np.unwrap(yaw))))
    assert abs(np.corrcoef(a.odometry.measurements[:, 2], true_inc)[0, 1]) < 0.3


def test_s3e_laboratory_ground_truth_of_two_poses_is_left_out_or_refused(tmp_path):
    seq = tmp_path / "S3E_Laboratory_1"
    seq.mkdir()
    stamps, pos, _ = curved_path(300, seed=3)
    ident = np.tile([0.0, 0.0, 0.0, 1.0], (300, 1))
    write_tum_file(seq / "Alpha_gt.txt", stamps, pos, ident, header=None)
    write_tum_file(seq / "Bob_gt.txt", stamps[[0, -1]], pos[[0, -1]], ident[:2], header=None)
    r = run("s3e", seq, "-o", tmp_path / "ds")
    assert r.exit_code == 0, r.output
    assert (
        f"warning: {seq / 'Bob_gt.txt'}: only 2 poses (an indoor S3E sequence has just its start and end); "
        "agent bob left out" in r.output
    )
    (seq / "Alpha_gt.txt").write_text((seq / "Bob_gt.txt").read_text())
    r = run("s3e", seq, "-o", tmp_path / "ds2")
    assert r.exit_code == 2
    assert r.output.strip().splitlines()[-1].startswith(f"error: {seq / 'Alpha_gt.txt'}: only start and end poses")
    assert not (tmp_path / "ds2").exists()


# ------------------------------------------------------------------------------------------- AirMuseum


def test_airmuseum_scenario_folder_and_body_frames(tmp_path):
    scenario = tmp_path / "AirMuseum_scenario_1"
    frames = {"drone": "flu", "robotA": "ufl", "robotB": "ufl", "robotC": "fur"}
    headings = {}
    for k, (robot, code) in enumerate(frames.items()):
        folder = scenario / "data" / robot
        folder.mkdir(parents=True)
        s, p, q_flu = loop_trajectory(600, radius=6.0, phase=0.4 * k, centre=(0.5 * k, 0.0, 0.0))
        headings[robot] = Rotation.from_quat(q_flu).as_euler("ZYX")[:, 0]
        # the file holds the orientation of the robot's own body axes: R_world_body = R_world_flu R_flu_body
        q_body = (Rotation.from_quat(q_flu) * Rotation.from_matrix(body_frame_rotation(code))).as_quat()
        write_tum_file(folder / "body_stamped_groundtruth.txt", s, p, q_body, header="# timestamp tx ty tz qx qy qz qw")
    out = tmp_path / "ds"
    r = run("airmuseum", scenario, "-o", out, "--planar", "--lc-prob-inter", "1.0")
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["drone", "robotA", "robotB", "robotC"]
    assert len(g.inter) > 0
    for a in g.agents:
        s, _, _ = loop_trajectory(600)
        true = np.interp(a.stamps_ns.astype(float), s.astype(float), np.unwrap(headings[a.name]))
        err = normalize_angle(a.ground_truth[:, 2] - true)
        assert np.abs(err).max() < 1e-6, a.name  # yaw about the true up axis, for every body frame
    # --body-frame overrides a default: robotA read as FLU gets a wrong heading (robot C's FUR only
    # differs from FLU by a roll, which leaves the yaw alone)
    r = run("airmuseum", scenario, "-o", tmp_path / "wrong", "--planar", "--body-frame", "robotA=flu")
    assert r.exit_code == 0, r.output
    bad = read_multi_g2o(tmp_path / "wrong").agents[1]
    s, _, _ = loop_trajectory(600)
    true = np.interp(bad.stamps_ns.astype(float), s.astype(float), np.unwrap(headings["robotA"]))
    assert np.abs(normalize_angle(bad.ground_truth[:, 2] - true)).max() > 0.5
    r = run("airmuseum", scenario, "-o", tmp_path / "x", "--body-frame", "robotC=xyz")
    assert r.exit_code == 2 and "body frame 'xyz': expected three letters" in r.output


# ------------------------------------------------------------------------------------------- EuRoC, KITTI, Kimera


def test_euroc_sequences_are_agents_with_their_quaternions_in_w_x_y_z_order(tmp_path):
    truth = {n.lower(): _euroc_sequence(tmp_path, n, k) for k, n in enumerate(["MH_01_easy", "MH_02_easy"])}
    out = tmp_path / "ds"
    r = run(tmp_path / "MH_01_easy", tmp_path / "MH_02_easy", "-o", out, "--keyframe-distance", "0.5")  # guessed
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["mh_01_easy", "mh_02_easy"]
    cfg = read_convert_config(out / "convert.json")
    assert cfg.source == "euroc"
    a = g.agents[0]
    s, p, q = truth["mh_01_easy"]
    k = np.searchsorted(s, a.stamps_ns)
    rel = Rotation.from_quat(q[k]).inv() * Rotation.from_quat(a.ground_truth[:, 3:7])
    assert rel.magnitude().max() < 1e-9  # read as x y z w it would be off by radians
    assert read_multi_g2o(out).agents[1].stamps_ns[0] == truth["mh_02_easy"][0][0]  # nanoseconds kept


def test_kitti_poses_become_z_up_and_take_times_txt(tmp_path):
    n = 120
    t = np.arange(n) * 0.1036
    # the camera drives forward (+z in the camera frame) and turns right (about -y... camera y is down)
    yaw = np.linspace(0, 1.0, n)
    R = Rotation.from_euler("y", yaw.reshape(-1, 1)).as_matrix()  # turning about the camera's vertical axis
    pos = np.column_stack([np.cumsum(np.sin(yaw)), np.zeros(n), np.cumsum(np.cos(yaw))])
    lines = [" ".join(f"{v:.12e}" for v in np.column_stack([R[i], pos[i]]).ravel()) for i in range(n)]
    (tmp_path / "poses").mkdir()
    (tmp_path / "poses" / "00.txt").write_text("\n".join(lines) + "\n")
    (tmp_path / "sequences" / "00").mkdir(parents=True)
    (tmp_path / "sequences" / "00" / "times.txt").write_text("\n".join(f"{v:.6e}" for v in t) + "\n")
    r = run(
        tmp_path / "poses" / "00.txt",
        "-o",
        tmp_path / "ds",
        "--split",
        "3",
        "--overlap",
        "2",
        "--keyframe-distance",
        "0.5",
    )
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(tmp_path / "ds")
    assert [a.name for a in g.agents] == ["00_1", "00_2", "00_3"]
    allp = np.concatenate([a.ground_truth for a in g.agents])
    # z up: the drive stays at height 0 and moves forward along +x
    assert np.abs(allp[:, 2]).max() < 1e-9 and allp[:, 0].max() > 50
    assert g.agents[0].stamps_ns[0] == 0 and g.agents[2].stamps_ns[-1] == round(t[-1] * 1e9)
    # the windows overlap by 2 s
    assert g.agents[0].stamps_ns[-1] - g.agents[1].stamps_ns[0] > 1.5e9
    cfg = read_convert_config(tmp_path / "ds" / "convert.json")
    assert cfg.source == "kitti" and cfg.split == 3 and cfg.overlap_s == 2.0
    again = run("--config", tmp_path / "ds" / "convert.json", "-o", tmp_path / "ds2")
    assert again.exit_code == 0, again.output
    for f in ("agent2/posegraph.g2o", "inter_agent_lc.dat", "agents.json"):
        assert (tmp_path / "ds" / f).read_bytes() == (tmp_path / "ds2" / f).read_bytes()
    assert CAMERA_TO_Z_UP @ np.array([0, 0, 1.0]) @ np.array([1.0, 0, 0]) == 1.0


def test_kimera_multi_folder_with_w_x_y_z_quaternions(tmp_path):
    gt = tmp_path / "ground_truth" / "1014"
    gt.mkdir(parents=True)
    truth = {}
    for k, robot in enumerate(["acl_jackal", "acl_jackal2", "sparkal1"]):
        s, p, q = loop_trajectory(500, radius=5.0, phase=k)
        q = (Rotation.from_quat(q) * Rotation.from_euler("y", 0.2)).as_quat()
        truth[robot] = q
        rows = ["#timestamp_kf,x,y,z,qw,qx,qy,qz"] + [
            ",".join([str(t), *map(repr, pp), repr(qq[3]), repr(qq[0]), repr(qq[1]), repr(qq[2])])
            for t, pp, qq in zip(s.tolist(), p.tolist(), q.tolist())
        ]
        (gt / f"{robot}_gt_odom.csv").write_text("\n".join(rows) + "\n")
    r = run(gt, "-o", tmp_path / "ds")  # guessed: kimera-multi
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(tmp_path / "ds")
    assert [a.name for a in g.agents] == ["acl_jackal", "acl_jackal2", "sparkal1"]
    q0 = g.agents[0].ground_truth[0, 3:7]
    assert (Rotation.from_quat(truth["acl_jackal"][0]).inv() * Rotation.from_quat(q0)).magnitude() < 1e-9


@pytest.mark.parametrize(
    "source, name, text, message",
    [
        (
            "euroc",
            "MH_01_easy/mav0/state_groundtruth_estimate0/data.csv",
            "#t\n1,2,3\n",
            "data.csv:2: expected 17 columns",
        ),
        (
            "euroc",
            "MH_01_easy/mav0/state_groundtruth_estimate0/data.csv",
            "#t\n1.5" + ",0" * 16 + "\n",
            "data.csv:2: timestamp '1.5' is not an integer of nanoseconds",
        ),
        ("kitti", "00.txt", "1 0 0 0 0 1 0 0 0 0 1 x\n", "00.txt:1: 'x' is not a number"),
        ("kitti", "00.txt", "2 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1\n", "pose 0 is not a rotation"),
        (
            "kimera-multi",
            "r_gt_odom.csv",
            "#timestamp_kf,x,y,z,qw,qx,qy,qz\n1,0,0,0,1,0,0\n",
            "r_gt_odom.csv:2: expected 8 columns",
        ),
        # a file whose header names the quaternion x y z w (a TUM-ordered export under the dataset's name)
        # is refused: read by position, its rotations would be scrambled
        (
            "kimera-multi",
            "r_gt_odom.csv",
            "#timestamp_kf,x,y,z,qx,qy,qz,qw\n1,0,0,0,0,0,0,1\n2,1,0,0,0,0,0,1\n",
            "r_gt_odom.csv:1: the header orders the quaternion x y z w",
        ),
        (
            "euroc",
            "MH_01_easy/mav0/state_groundtruth_estimate0/data.csv",
            "#timestamp,p_x,p_y,p_z,q_x,q_y,q_z,q_w" + ",v" * 9 + "\n1" + ",0" * 6 + ",1" + ",0" * 9 + "\n",
            "data.csv:1: the header orders the quaternion x y z w",
        ),
    ],
)
def test_bad_files_are_one_line(tmp_path, source, name, text, message):
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    arg = tmp_path / "MH_01_easy" if source == "euroc" else path
    r = run(source, arg, "-o", tmp_path / "ds")
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], r.output
    assert not (tmp_path / "ds").exists()


def test_an_ambiguous_path_asks_for_the_source(tmp_path):
    (tmp_path / "notes.md").write_text("hello\n")
    r = run(tmp_path / "notes.md", "-o", tmp_path / "ds")
    assert r.exit_code == 2
    assert f"cannot tell the source of {tmp_path / 'notes.md'}: name it" in r.output


# ------------------------------------------------------------------------------------------- kollagen's reader


def kollagen_open(folder: Path, three_d: bool = True) -> dict:
    """What ``kollagen::multig2o::open(folder, _3D)`` (its MultiG2oParse.h) reads, re-told in Python:
    agent folders are those whose name starts with "agent" and that hold posegraph.g2o and
    <folder>_GT.tum, sorted as strings (agent10 before agent2); in each g2o file the first token must be
    the vertex tag, the vertices come first, then at least one edge (vertices only is an error):
    odometry until the first edge with to - from != 1, every edge after it a loop closure; the GT file
    is read as whitespace-separated numbers (8 per pose) until the first non-number;
    inter_agent_lc.dat as rows of 4 integers and 28 numbers (3D) or 4 integers and 9 numbers (2D),
    until the first row that does not read. (kollagen's ``helper::parse`` at commit 3571aac then
    returns ``{}`` instead of what it parsed; the files are still read whole, and every error
    thrown, which is what this checks.)"""
    vtag, etag = ("VERTEX_SE3:QUAT", "EDGE_SE3:QUAT") if three_d else ("VERTEX_SE2", "EDGE_SE2")
    vlen, elen = (1 + 7, 2 + 7 + 21) if three_d else (1 + 3, 2 + 3 + 6)
    if not (folder / "inter_agent_lc.dat").exists():
        raise ValueError("multig2o is missing an inter_agent_lc.dat")
    dirs = sorted(
        (
            p
            for p in folder.iterdir()
            if p.name.startswith("agent") and (p / "posegraph.g2o").exists() and (p / f"{p.name}_GT.tum").exists()
        ),
        key=lambda p: str(p),
    )
    if not dirs:
        raise ValueError("Unable to find agent folders in provided multig2o")
    agents = []
    for d in dirs:
        tokens = (d / "posegraph.g2o").read_text().split()
        if not tokens or tokens[0] != vtag:
            raise ValueError(f"First line of g2o should read {vtag}")
        k, vertices, odometry, loops, seen_lc = 0, 0, 0, 0, False
        while k < len(tokens) and tokens[k] != etag:
            if tokens[k] != vtag:  # kollagen would read this tag's numbers as a vertex; we refuse it
                raise ValueError(f"unexpected {tokens[k]} among the vertices of {d.name}")
            int(tokens[k + 1]), [float(t) for t in tokens[k + 2 : k + 1 + vlen]]
            vertices += 1
            k += 1 + vlen
        if k >= len(tokens):
            raise ValueError(f"First line after {vtag} in g2o should read {etag}")
        while k < len(tokens):
            if tokens[k] != etag:
                raise ValueError(f"unexpected {tokens[k]}")
            fr, to = int(tokens[k + 1]), int(tokens[k + 2])
            [float(t) for t in tokens[k + 3 : k + 1 + elen]]
            if seen_lc or to - fr != 1:
                seen_lc = True
                loops += 1
            else:
                odometry += 1
            k += 1 + elen
        gt = []
        for tok in (d / f"{d.name}_GT.tum").read_text().split():
            try:
                gt.append(float(tok))
            except ValueError:
                break
        agents.append(
            {
                "folder": d.name,
                "vertices": vertices,
                "odometry": odometry,
                "loop_closures": loops,
                "gt": len(gt) // 8,
                "t0": gt[0] if gt else None,
            }
        )
    row = 4 + (28 if three_d else 9)
    dat = (folder / "inter_agent_lc.dat").read_text().split()
    rows = 0
    for r in range(len(dat) // row):
        cells = dat[r * row : (r + 1) * row]
        try:
            [int(c) for c in cells[:4]], [float(c) for c in cells[4:]]
        except ValueError:
            break
        rows += 1
    return {"agents": agents, "inter": rows}


def test_a_converted_dataset_is_read_whole_by_kollagens_reader(tmp_path):
    files = []
    for k in range(3):
        s, p, q = loop_trajectory(500, centre=(UTM_EAST + k, UTM_NORTH, 20.0), phase=k)
        files.append(write_tum_file(tmp_path / f"robot{k}.txt", s, p, q))
    res = convert(ConvertConfig("tum", tuple(map(str, files))), tmp_path / "ds", rrd=False)
    seen = kollagen_open(tmp_path / "ds")
    g = res.build.graph
    assert [a["vertices"] for a in seen["agents"]] == [a.num_poses for a in g.agents]
    assert [a["gt"] for a in seen["agents"]] == [a.num_poses for a in g.agents]
    assert [a["odometry"] for a in seen["agents"]] == [len(a.odometry) for a in g.agents]
    assert [a["loop_closures"] for a in seen["agents"]] == [len(a.loop_closures) for a in g.agents]
    assert seen["inter"] == len(g.inter) > 0
    # with folders named after the robots, kollagen's reader finds nothing
    convert(ConvertConfig("tum", tuple(map(str, files)), folder_names="robots"), tmp_path / "robots", rrd=False)
    with pytest.raises(ValueError, match="Unable to find agent folders"):
        kollagen_open(tmp_path / "robots")
    assert [a.name for a in read_multi_g2o(tmp_path / "robots").agents] == ["robot0", "robot1", "robot2"]
    assert np.allclose(
        se3_poses_to_planar(g.agents[0].ground_truth)[:, 0:2],
        se3_poses_to_planar(read_multi_g2o(tmp_path / "ds").agents[0].ground_truth)[:, 0:2],
    )


def _assert_kollagen_reads_all(seen: dict, g) -> None:
    assert [a["vertices"] for a in seen["agents"]] == [a.num_poses for a in g.agents]
    assert [a["gt"] for a in seen["agents"]] == [a.num_poses for a in g.agents]
    assert [a["odometry"] for a in seen["agents"]] == [len(a.odometry) for a in g.agents]
    assert [a["loop_closures"] for a in seen["agents"]] == [len(a.loop_closures) for a in g.agents]
    assert seen["inter"] == len(g.inter) > 0


def test_a_planar_s3e_conversion_is_read_whole_by_kollagens_2d_reader(tmp_path):
    """Planar output (2D records) as kollagen reads it with ``open(dir, false)``; 3D reading refuses it."""
    gt = tmp_path / "GT"
    gt.mkdir()
    for k, name in enumerate(("Alpha", "Bob")):
        s, p, _ = curved_path(600, seed=k)
        p[:, 0] -= 30 * k  # both robots in the same streets
        lines = [f"{t / 1e9:.5f} {x:.9f} {y:.8f} {z:.4f} 0 0 0 1" for t, (x, y, z) in zip(s, p)]
        (gt / f"{name}_gt.txt").write_text("\n".join(lines) + "\n")
    res = convert(ConvertConfig("s3e", (str(gt),), options=GraphOptions(planar=True)), tmp_path / "ds", rrd=False)
    g = res.build.graph
    assert (tmp_path / "ds" / "agent1" / "posegraph.g2o").read_text().startswith("VERTEX_SE2 ")
    _assert_kollagen_reads_all(kollagen_open(tmp_path / "ds", three_d=False), g)
    with pytest.raises(ValueError, match="should read VERTEX_SE3:QUAT"):
        kollagen_open(tmp_path / "ds", three_d=True)


def test_kollagens_reader_takes_ten_split_agents_in_string_order(tmp_path):
    """--split 10: every agent is read whole, but kollagen lists agent10 second (string order), so its
    agent index k is not inter_agent_lc.dat's k for 10 or more agents (docs/formats.md says so)."""
    s, p, q = loop_trajectory(2000, radius=15.0, laps=6.0, centre=(UTM_EAST, UTM_NORTH, 20.0))
    f = write_tum_file(tmp_path / "run.txt", s, p, q)
    res = convert(ConvertConfig("tum", (str(f),), split=10, overlap_s=5.0), tmp_path / "ds", rrd=False)
    g = res.build.graph
    seen = kollagen_open(tmp_path / "ds")
    folders = [a["folder"] for a in seen["agents"]]
    assert folders == sorted(f"agent{k}" for k in range(1, 11)) and folders[1] == "agent10"
    natural = sorted(range(10), key=lambda i: int(folders[i][len("agent") :]))
    reordered = {
        key: [seen["agents"][i][key] for i in natural] for key in ("vertices", "odometry", "loop_closures", "gt")
    }
    assert reordered["vertices"] == [a.num_poses for a in g.agents]
    assert reordered["gt"] == [a.num_poses for a in g.agents]
    assert reordered["odometry"] == [len(a.odometry) for a in g.agents]
    assert reordered["loop_closures"] == [len(a.loop_closures) for a in g.agents]
    assert seen["inter"] == len(g.inter) > 0
    # the split windows follow each other in time: in kollagen's order the 2nd agent is the last window
    t0 = [a["t0"] for a in seen["agents"]]
    assert t0[1] == max(t0) and sorted(t0) == [t0[i] for i in natural]


def test_the_shipped_headers_are_read(tmp_path):
    """The exact header lines of EuRoC and Kimera-Multi pass the quaternion-order check."""
    from studio.converters.text import read_table

    euroc = tmp_path / "data.csv"
    euroc.write_text(
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
        "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
        "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
        "b_a_RS_S_z [m s^-2]\r\n1403636580838555648," + ",".join(["0.5"] * 16) + "\r\n"
    )
    table, stamps = read_table(euroc, 17, what="EuRoC", int_first=True, quaternion="wxyz")
    assert stamps.tolist() == [1403636580838555648] and table.shape == (1, 17)
    kimera = tmp_path / "acl_jackal_gt_odom.csv"
    kimera.write_text("#timestamp_kf,x,y,z,qw,qx,qy,qz\n1665777000123456789,1,2,3,1,0,0,0\n")
    table, stamps = read_table(kimera, 8, what="Kimera", int_first=True, quaternion="wxyz")
    assert stamps.tolist() == [1665777000123456789] and table[0, 4] == 1.0


def _tumvi_sequence(root: Path, name: str, k: int):
    """TUM VI as it ships in the ASL layout: motion capture of the IMU, 8 columns, w x y z."""
    folder = root / name / "mav0" / "mocap0"
    folder.mkdir(parents=True)
    s, p, q = loop_trajectory(400, rate_hz=120.0, radius=2.0, phase=k, climb=0.5)
    q = (Rotation.from_quat(q) * Rotation.from_euler("x", 0.4)).as_quat()
    rows = ["#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []"]
    stamps = 1_520_530_308_199_447_626 + (s - s[0])
    for t, pp, qq in zip(stamps.tolist(), p.tolist(), q.tolist()):
        rows.append(",".join([str(t), *map(repr, pp), repr(qq[3]), repr(qq[0]), repr(qq[1]), repr(qq[2])]))
    (folder / "data.csv").write_text("\n".join(rows) + "\n")
    return stamps, p, q


def test_tum_vi_mocap_folders_are_read_by_euroc_with_w_x_y_z_quaternions(tmp_path):
    truth = {n: _tumvi_sequence(tmp_path, n, k) for k, n in enumerate(["dataset-room1_512_16", "dataset-room2_512_16"])}
    out = tmp_path / "ds"
    r = run(*(tmp_path / n for n in truth), "-o", out, "--keyframe-distance", "0.3")  # the source is guessed
    assert r.exit_code == 0, r.output
    assert read_convert_config(out / "convert.json").source == "euroc"
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["dataset-room1_512_16", "dataset-room2_512_16"]
    s, p, q = truth["dataset-room1_512_16"]
    a = g.agents[0]
    k = np.searchsorted(s, a.stamps_ns)
    assert np.array_equal(s[k], a.stamps_ns)  # nanosecond stamps kept exactly
    moved = a.ground_truth[:, 0:3] - a.ground_truth[0, 0:3]  # the dataset's origin is shifted, not its shape
    assert np.abs(moved - (p[k] - p[k][0])).max() < 1e-9
    rel = Rotation.from_quat(q[k]).inv() * Rotation.from_quat(a.ground_truth[:, 3:7])
    assert rel.magnitude().max() < 1e-9


def test_a_tum_vi_file_given_to_tum_says_it_looks_like_nanoseconds(tmp_path):
    _tumvi_sequence(tmp_path, "dataset-room1_512_16", 0)
    csv = tmp_path / "dataset-room1_512_16" / "mav0" / "mocap0" / "data.csv"
    r = runner.invoke(app, ["convert", "tum", str(csv), "-o", str(tmp_path / "x")])
    assert r.exit_code == 2
    line = r.output.strip()
    assert len(line.splitlines()) == 1
    assert f"{csv}:2: timestamp out of range" in line and "looks like nanoseconds" in line
    assert "studio convert euroc" in line
    assert not (tmp_path / "x").exists()


def test_kitti_without_times_txt_warns_and_report_json_says_it(tmp_path):
    n = 40
    lines = [" ".join(f"{v:.12e}" for v in [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.5 * i]) for i in range(n)]
    (tmp_path / "07.txt").write_text("\n".join(lines) + "\n")
    r = runner.invoke(
        app, ["convert", "kitti", str(tmp_path / "07.txt"), "-o", str(tmp_path / "ds"), "--keyframe-distance", "0.4"]
    )
    assert r.exit_code == 0, r.output
    assert "no times.txt" in r.output and "10 Hz" in r.output
    report = json.loads((tmp_path / "ds" / "report.json").read_text())
    assert any("no times.txt" in w and "10 Hz" in w for w in report["warnings"]), report["warnings"]
    assert read_multi_g2o(tmp_path / "ds").agents[0].stamps_ns[1] == 100_000_000
