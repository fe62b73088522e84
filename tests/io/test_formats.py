"""Readers and writers: round trips bit for bit, and parse errors that name file and line."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import FormatError
from studio.core.model import PoseKind, graphs_equal
from studio.core.trajectory import Trajectory
from studio.generator.kollagen import generate
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from studio.io.inter_lc_dat import read_inter_lc_dat
from studio.io.multig2o import read_multi_g2o, write_multi_g2o
from studio.io.synth_config import read_synth_config
from studio.io.tum import read_tum, write_tum

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def graph():
    return generate(read_synth_config(DATA / "configs" / "tiny_three.json"), jobs=1).graph


def test_multi_g2o_round_trip_is_exact_in_3d(graph, tmp_path):
    write_multi_g2o(graph, tmp_path, precision="full")
    back = read_multi_g2o(tmp_path)
    assert back.kind is PoseKind.SE3
    assert graphs_equal(back, graph.to_se3())


def test_multi_g2o_round_trip_2d_records(graph, tmp_path):
    write_multi_g2o(graph, tmp_path, records="2d", precision="full")
    back = read_multi_g2o(tmp_path)
    assert back.kind is PoseKind.SE2
    for a, b in zip(back.agents, graph.agents):
        assert np.array_equal(a.initial, b.initial)
        assert np.array_equal(a.odometry.measurements, b.odometry.measurements)
        assert np.array_equal(a.loop_closures.information_upper, b.loop_closures.information_upper)
        # ground truth goes through a TUM quaternion: yaw comes back within an ulp or two
        np.testing.assert_allclose(a.ground_truth, b.ground_truth, rtol=0, atol=1e-15)
    assert np.array_equal(back.inter.measurements, graph.inter.measurements)


def test_planar_dataset_keeps_the_ground_truth_quaternions_it_read(graph, tmp_path):
    """A planar dataset read from disk lifts to 3D with the ground-truth file's own quaternions,
    not with quaternions re-derived from the yaw (no yaw-and-back round trip)."""
    write_multi_g2o(graph, tmp_path, records="2d", precision="full")
    path = tmp_path / "agent1" / "agent1_GT.tum"
    text = path.read_text().splitlines()
    parts = text[3].split()
    parts[6], parts[7] = "0.4", "0.9"  # a quaternion that no yaw_to_quat gives (read normalised)
    text[3] = " ".join(parts)
    path.write_text("\n".join(text) + "\n")
    back = read_multi_g2o(tmp_path)
    assert back.kind is PoseKind.SE2
    lifted = back.to_se3().agents[0].ground_truth
    assert lifted.tobytes() == read_tum(path).poses_xyz_quat_xyzw.tobytes()
    np.testing.assert_allclose(lifted[3, 5:7], np.array([0.4, 0.9]) / np.hypot(0.4, 0.9), rtol=0, atol=1e-15)


def test_kollagen_precision_dat_reads_back_to_six_decimals(graph, tmp_path):
    write_multi_g2o(graph, tmp_path)  # kollagen's %f
    back = read_multi_g2o(tmp_path)
    ref = graph.to_se3().inter
    assert np.array_equal(back.inter.from_agent, ref.from_agent)
    assert np.array_equal(back.inter.to_index, ref.to_index)
    np.testing.assert_allclose(back.inter.measurements[:, :2], ref.measurements[:, :2], atol=5e-7)
    # and re-writing it gives the same bytes
    again = tmp_path / "again"
    again.mkdir()
    write_multi_g2o(back, again)
    for rel in ("inter_agent_lc.dat", "agent2/posegraph.g2o", "agent2/agent2_GT.tum"):
        assert (tmp_path / rel).read_bytes() == (again / rel).read_bytes(), rel


def test_reads_committed_kollagen_layout():
    g = read_multi_g2o(DATA / "golden" / "tiny_single")
    assert [a.name for a in g.agents] == ["agent1"]
    assert g.agents[0].num_poses == 141
    assert len(g.agents[0].odometry) == 140
    assert len(g.agents[0].loop_closures) > 0
    assert g.agents[0].stamps_ns[-1] == 140 * 10**9


def test_g2o_2d_round_trip_stream():
    doc = G2oDocument(
        PoseKind.SE2,
        np.array([0, 1]),
        np.array([[0.0, 0.0, 0.0], [1.0, -0.0, 0.1]]),
        np.array([0]),
        np.array([1]),
        np.array([[1.0, 1e-300, 0.1]]),
        np.array([[1.0, 0.5, 0.0, 2.0, 0.0, 3.0]]),
    )
    buf = io.StringIO()
    write_g2o(buf, doc)
    assert buf.getvalue().splitlines()[1] == "VERTEX_SE2 1 1 -0 0.10000000000000001"
    back = read_g2o(io.StringIO(buf.getvalue()))
    for f in ("vertex_ids", "vertex_poses", "edge_from", "edge_to", "edge_measurements", "edge_information_upper"):
        assert np.array_equal(getattr(back, f), getattr(doc, f)), f
    assert np.signbit(back.vertex_poses[1, 1])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 x 0\n", "g.g2o:2: 'x' is not a number"),
        ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 0 0\n", "g.g2o:2: EDGE_SE2 needs 11 fields, found 4"),
        ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 1 0\n", "g.g2o:2: vertex 0 is defined twice"),
        ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 7 1 0 0 1 0 0 1 0 1\n", "g.g2o:2: edge refers to unknown vertex 7"),
        ("VERTEX_SE2 0 0 0 0\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n", "g.g2o:2: VERTEX_SE3:QUAT mixed with SE2 records"),
        ("VERTEX_SE2 0 0 nan 0\n", "g.g2o:1: value is not finite"),
        ("VERTEX_XYZ 0 0 0 0\n", "g.g2o:1: unknown record 'VERTEX_XYZ'"),
        ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 2\n", "g.g2o:1: quaternion is not unit length"),
        ("VERTEX_SE2 1.5 0 0 0\n", "g.g2o:1: vertex id '1.5' is not an integer"),
        ("# nothing\n", "g.g2o: no vertices or edges"),
    ],
)
def test_g2o_parse_errors_name_file_and_line(tmp_path, text, message):
    path = tmp_path / "g.g2o"
    path.write_text(text)
    with pytest.raises(FormatError) as err:
        read_g2o(path)
    assert str(err.value).startswith(str(tmp_path / message.split(":")[0]) + message[len(message.split(":")[0]) :])


def test_tum_round_trip_exact_and_fractional_stamps(tmp_path):
    stamps = np.array([1634567890_123456789, 1634567890_223456789, 1634567891_000000000])
    poses = np.array(
        [
            [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0],
            [0.1, -0.2, 0.0, 0.5, 0.5, 0.5, 0.5],
            [1e-9, 2.0, -3.0, 0.0, 0.0, -1.0, 0.0],
        ]
    )
    write_tum(tmp_path / "t.tum", Trajectory.from_poses("t", stamps, poses))
    assert (tmp_path / "t.tum").read_text().splitlines()[0] == "1634567890.123456789 1 2 3 0.0 0.0 0 1"
    back = read_tum(tmp_path / "t.tum")
    assert back.stamps_ns.tolist() == stamps.tolist()
    assert np.array_equal(back.poses_xyz_quat_xyzw, poses)


@pytest.mark.parametrize("n", [5, 5000])  # one % per line / numpy columns
def test_tum_whole_second_stamps_are_written_as_printf_g17_writes_them(tmp_path, n):
    seconds = np.concatenate([np.arange(n - 2), [1634567891, 9_000_000_000]])
    poses = np.tile([0.5, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0], (n, 1))
    write_tum(tmp_path / "t.tum", Trajectory.from_poses("t", seconds * 1_000_000_000, poses))
    lines = (tmp_path / "t.tum").read_text().splitlines()
    printf = "%.17g"  # as kollagen writes a node index
    assert [ln.split()[0] for ln in lines] == [printf % float(s) for s in seconds.tolist()]
    assert lines[-1] == "9000000000 0.5 -1 0.0 0.0 0.0 0 1"


def test_tum_reader_accepts_commas_comments_header_and_normalises():
    text = "timestamp,tx,ty,tz,qx,qy,qz,qw\n# comment\n1.5,0,0,0,0,0,0,2\n2.5,1,0,0,0,0,0,1\n"
    t = read_tum(io.StringIO(text))
    assert t.stamps_ns.tolist() == [1_500_000_000, 2_500_000_000]
    assert t.quat_xyzw[0, 3] == 1.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 0 0 0 0 0 0 1\n2 0 0\n", ":2: expected 8 columns"),
        ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", ":2: timestamps must increase"),
        ("1 0 0 0 0 0 0 0\n", ":1: quaternion is zero"),
        ("1 0 inf 0 0 0 0 1\n", ":1: value is not finite"),
    ],
)
def test_tum_errors(tmp_path, text, message):
    p = tmp_path / "t.tum"
    p.write_text(text)
    with pytest.raises(FormatError, match=f"^{p}{message}"):
        read_tum(p)


def test_dat_errors(tmp_path):
    p = tmp_path / "inter_agent_lc.dat"
    p.write_text("1 0 2 0 0.1 0.2 0.3\n")
    with pytest.raises(FormatError, match=r"inter_agent_lc.dat:1: expected 32 \(SE3\) or 13 \(SE2\) columns, found 7"):
        read_inter_lc_dat(p)


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(FormatError, match="no such file"):
        read_g2o(tmp_path / "none.g2o")
    (tmp_path / "bin.g2o").write_bytes(b"VERTEX_SE2 0 0 0 0\n\xff\xfe")
    with pytest.raises(FormatError, match=r"bin.g2o:2: not UTF-8 text"):
        read_g2o(tmp_path / "bin.g2o")
    with pytest.raises(FormatError, match="no agent folder with a posegraph.g2o"):
        read_multi_g2o(tmp_path)
