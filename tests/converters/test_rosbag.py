"""converters.rosbag on bags written by the tests: ROS 1, ROS 2 sqlite3 and mcap, every message type."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.rosbag import parse_agent_spec, read_bag, read_bag_sources
from studio.core.errors import ConfigError, FormatError
from studio.io.multig2o import read_multi_g2o
from tests.converters.bags import STORAGES, Msgs, typestore, utm31_to_latlon, write_bag
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory

runner = CliRunner()
N = 120


def every_type_topics(storage: str):
    """One topic per supported message type, each carrying its own loop."""
    m = Msgs(typestore(storage))
    out, truth = {}, {}
    for k, (topic, kind) in enumerate(
        [
            ("/a/pose", "PoseStamped"),
            ("/b/pose_cov", "PoseWithCovarianceStamped"),
            ("/c/odom", "Odometry"),
            ("/tf", "TFMessage"),
        ]
    ):
        s, p, q = loop_trajectory(N, centre=(3.0 * k, 0.0, 1.0), phase=k, t0_s=1_700_000_000.25)
        out[topic] = [(int(t), getattr(m, kind)(int(t), pp, qq)) for t, pp, qq in zip(s, p, q)]
        truth[topic] = (s, p, q)
    # GNSS: a loop in UTM zone 31, with heading from QuaternionStamped, from Imu, and without heading
    for k, (fix, heading, kind) in enumerate(
        [("/e/fix", "/e/heading", "QuaternionStamped"), ("/f/fix", "/f/imu", "Imu"), ("/g/fix", None, None)]
    ):
        s, p, q = loop_trajectory(N, centre=(UTM_EAST + 5.0 * k, UTM_NORTH, 80.0), phase=k, t0_s=1_700_000_000.0)
        lat, lon = utm31_to_latlon(p[:, 0], p[:, 1])
        status = np.zeros(N, dtype=int)
        status[[5, 6, 7]] = -1  # no fix: dropped
        out[fix] = [
            (int(t), m.NavSatFix(int(t), la, lo, pp[2], st)) for t, la, lo, pp, st in zip(s, lat, lon, p, status)
        ]
        if heading:
            hs = s + 3_000_000  # heading stamps 3 ms after the fixes
            out[heading] = [(int(t), getattr(m, kind)(int(t), qq)) for t, qq in zip(hs, q)]
        truth[fix] = (s, p, q)
    out["/chatter"] = [(int(truth["/a/pose"][0][0]), m.String(0))]
    return out, truth


SPECS = {
    "a": "/a/pose",
    "b": "/b/pose_cov",
    "c": "/c/odom",
    "d": "/tf:odom:base_link",
    "e": "/e/fix+/e/heading",
    "f": "/f/fix+/f/imu",
    "g": "/g/fix",
}


@pytest.fixture(scope="module", params=STORAGES)
def bag(request, tmp_path_factory):
    topics, truth = every_type_topics(request.param)
    path = write_bag(tmp_path_factory.mktemp(request.param) / "run", request.param, topics)
    return path, truth


def test_every_message_type_in_every_storage(bag):
    path, truth = bag
    warnings = []
    trajs = read_bag(path, SPECS, warn=warnings.append)
    assert [t.name for t in trajs] == list(SPECS)
    for t, topic in zip(trajs[:4], ["/a/pose", "/b/pose_cov", "/c/odom", "/tf"]):
        s, p, q = truth[topic]
        np.testing.assert_array_equal(t.stamps_ns, s)
        np.testing.assert_array_equal(t.positions_xyz, p)
        np.testing.assert_allclose(t.quat_xyzw, q, atol=1e-15)
    keep = np.ones(N, bool)
    keep[[5, 6, 7]] = False
    for t, topic in zip(trajs[4:], ["/e/fix", "/f/fix", "/g/fix"]):
        s, p, q = truth[topic]
        np.testing.assert_array_equal(t.stamps_ns, s[keep])
        np.testing.assert_allclose(t.positions_xyz, p[keep], atol=1e-6)  # UTM round trip to the micrometre
    np.testing.assert_allclose(trajs[4].quat_xyzw, truth["/e/fix"][2][keep], atol=1e-15)
    np.testing.assert_allclose(trajs[5].quat_xyzw, truth["/f/fix"][2][keep], atol=1e-15)
    # without heading: yaw of the direction of travel, close to the true heading on a smooth loop
    s, p, q = truth["/g/fix"]
    yaw_true = 2 * np.arctan2(q[keep][:, 2], q[keep][:, 3])
    yaw_cog = 2 * np.arctan2(trajs[6].quat_xyzw[:, 2], trajs[6].quat_xyzw[:, 3])
    err = np.angle(np.exp(1j * (yaw_cog - yaw_true)))[1:-1]
    assert np.abs(err).max() < np.radians(10)  # worst beside the dropped fixes (uneven chord)
    assert np.median(np.abs(err)) < np.radians(0.5)
    assert sum("3 fixes without a position dropped" in w for w in warnings) == 3


def test_bag_end_to_end_through_the_cli(bag, tmp_path):
    path, _ = bag
    args = ["convert", "bag", str(path), "-o", str(tmp_path / "ds")]
    for name, spec in SPECS.items():
        args += ["--agent", f"{name}={spec}"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(tmp_path / "ds")
    assert [a.name for a in g.agents] == list(SPECS)
    cfg = json.loads((tmp_path / "ds" / "convert.json").read_text())
    assert cfg["agents"] == [f"{k}={v}" for k, v in SPECS.items()]


def test_unknown_topic_lists_the_bags_topics_and_types(bag):
    path, _ = bag
    with pytest.raises(
        FormatError,
        match=r"no topic '/nope' for agent x \(topics: /a/pose \[geometry_msgs/PoseStamped\], "
        r".*/chatter \[std_msgs/String\]",
    ):
        read_bag(path, {"x": "/nope"})


def test_unsupported_type_lists_the_supported_ones(bag):
    path, _ = bag
    with pytest.raises(
        FormatError,
        match=r"/chatter has type std_msgs/msg/String, which is not supported "
        r"\(supported: geometry_msgs/PoseStamped, .*sensor_msgs/NavSatFix\)",
    ):
        read_bag(path, {"x": "/chatter"})
    with pytest.raises(FormatError, match=r"heading topic /a/pose has type .*PoseStamped, which is not supported"):
        read_bag(path, {"x": "/e/fix+/a/pose"})
    with pytest.raises(FormatError, match=r"no transform map->robot \(transforms seen: base_link->camera"):
        read_bag(path, {"x": "/tf:map:robot"})


def test_corrupt_and_truncated_bags(tmp_path):
    topics, _ = every_type_topics("ros1")
    full = write_bag(tmp_path / "ok", "ros1", {"/a/pose": topics["/a/pose"]})
    data = full.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match=r"cut\.bag: cannot read the bag, corrupt or truncated"):
        read_bag(cut, {"a": "/a/pose"})
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 4)
    with pytest.raises(FormatError, match=r"junk\.bag: cannot read the bag"):
        read_bag(junk, {"a": "/a/pose"})
    topics2, _ = every_type_topics("sqlite3")
    folder = write_bag(tmp_path / "r2", "sqlite3", {"/a/pose": topics2["/a/pose"]})
    db = next(folder.glob("*.db3"))
    db.write_bytes(db.read_bytes()[:1000])
    with pytest.raises(FormatError, match=r"r2: cannot read the bag"):
        read_bag(folder, {"a": "/a/pose"})


def test_no_fix_only_and_two_utm_zones(tmp_path):
    m = Msgs(typestore("sqlite3"))
    s = 1_700_000_000 * 10**9 + np.arange(20) * 10**8
    no_fix = [(int(t), m.NavSatFix(int(t), 42.0, 3.0, 0.0, -1)) for t in s]
    zones = [(int(t), m.NavSatFix(int(t), 42.0, 5.99995 + 0.00001 * k, 0.0, 0)) for k, t in enumerate(s)]
    path = write_bag(tmp_path / "gps", "sqlite3", {"/nofix": no_fix, "/zones": zones})
    with pytest.raises(FormatError, match=r"no usable messages \(20 with no fix dropped\)"):
        read_bag(path, {"a": "/nofix"})
    with pytest.raises(FormatError, match=r"span UTM zones 31N and 32N"):
        read_bag(path, {"a": "/zones"})


def test_skip_missing_reads_nothing_when_no_agent_is_in_the_bag(bag):
    path, _ = bag
    assert read_bag(path, {"alpha": "/alpha/fix+/alpha/heading"}, skip_missing=True) == []


@pytest.mark.parametrize(
    "spec, match",
    [
        ("../evil=/a/pose", "not a safe folder name"),
        ("a/b=/a/pose", "not a safe folder name"),
        ("..=/a/pose", "not a safe folder name"),
        ("noequals", "expected NAME=SPEC"),
        ("a=/tf:odom", "a TF spec is /tf:PARENT:CHILD"),
        ("a=/fix+", "a GNSS spec is /fix\\+/heading"),
    ],
)
def test_bad_agent_specs(spec, match):
    with pytest.raises(ConfigError, match=match):
        parse_agent_spec(spec)


def test_bad_agent_names_exit_2_and_write_nothing(bag, tmp_path):
    path, _ = bag
    r = runner.invoke(app, ["convert", "bag", str(path), "--agent", "../../etc=/a/pose", "-o", str(tmp_path / "ds")])
    assert r.exit_code == 2 and "not a safe folder name" in r.output
    assert not (tmp_path / "ds").exists() and not (tmp_path.parent / "etc").exists()


def test_bag_sources_need_agents_and_reject_plain_mcap(tmp_path):
    with pytest.raises(ConfigError, match="at least one --agent"):
        read_bag_sources([tmp_path])
    with pytest.raises(ConfigError, match="given twice"):
        read_bag_sources([tmp_path], agents=["a=/x", "a=/y"])
    f = tmp_path / "x.mcap"
    f.write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(FormatError, match=r"x\.mcap: cannot read the bag, corrupt or truncated"):
        read_bag(f, {"a": "/x"})
    with pytest.raises(FormatError, match="without metadata.yaml"):
        read_bag(tmp_path, {"a": "/x"})


def test_s3e_reads_agents_without_ground_truth_from_the_bag(tmp_path):
    from studio.converters.s3e import read_s3e
    from tests.converters.synthetic import write_tum_file

    seq = tmp_path / "S3E_seq"
    seq.mkdir()
    m = Msgs(typestore("sqlite3"))
    s, p, q = loop_trajectory(N, centre=(UTM_EAST, UTM_NORTH, 80.0), t0_s=1_700_000_000.0)
    lat, lon = utm31_to_latlon(p[:, 0], p[:, 1])
    write_bag(
        seq / "bag",
        "sqlite3",
        {
            "/alpha/fix": [(int(t), m.NavSatFix(int(t), la, lo, pp[2])) for t, la, lo, pp in zip(s, lat, lon, p)],
            "/alpha/heading": [(int(t), m.QuaternionStamped(int(t), qq)) for t, qq in zip(s, q)],
        },
    )
    write_tum_file(seq / "Bob_gt.txt", s, p + [2.0, 0.0, 0.0], q)
    trajs = read_s3e([seq])
    assert [t.name for t in trajs] == ["alpha", "bob"]
    np.testing.assert_allclose(trajs[0].positions_xyz, p, atol=1e-6)


def test_plain_mcap_file_every_type(tmp_path):
    import shutil

    topics, truth = every_type_topics("mcap")
    folder = write_bag(tmp_path / "run", "mcap", topics)
    plain = tmp_path / "plain.mcap"
    shutil.copy(next(folder.glob("*.mcap")), plain)
    trajs = read_bag(plain, SPECS)
    assert [t.name for t in trajs] == list(SPECS)
    s, p, q = truth["/tf"]
    np.testing.assert_array_equal(trajs[3].positions_xyz, p)
    np.testing.assert_array_equal(trajs[3].stamps_ns, s)
    np.testing.assert_allclose(trajs[4].quat_xyzw[0], truth["/e/fix"][2][0], atol=1e-15)
    with pytest.raises(
        FormatError, match=r"no topic '/nope' for agent x \(topics: /a/pose \[geometry_msgs/PoseStamped\]"
    ):
        read_bag(plain, {"x": "/nope"})
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(plain.read_bytes()[:-100])
    with pytest.raises(FormatError, match=r"cut\.mcap: cannot read the bag"):
        read_bag(cut, {"a": "/a/pose"})
