"""The hostile-input corpus, one named test per file, through the CLI.

Small text files are committed in ``tests/data/hostile/``; what would be large or binary is made here:
deeply nested and oversized JSON, 2 GB sparse files (no disk used), and ROS bags written with
rosbags' own writers and then damaged. Each hostile file must give exit code 2, exactly one line on
stderr (``error: <file>[:<line>]: <rule>``), no traceback, and no output.

A hostile g2o, ground truth or ``inter_agent_lc.dat`` is placed into an otherwise valid two-agent
multi-g2o folder (see :func:`dataset`), then given to ``studio record`` or ``studio evaluate``.
"""

from __future__ import annotations

import json
import shutil
import struct
import time
from pathlib import Path

from typer.testing import CliRunner

from studio.cli import app
from tests.conftest import DATA
from tests.machine import bound_s

HOSTILE = DATA / "hostile"
runner = CliRunner()

_INFO = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400"
VALID_G2O = "".join(f"VERTEX_SE3:QUAT {i} {float(i)} 0 0 0 0 0 1\n" for i in range(3)) + "".join(
    f"EDGE_SE3:QUAT {i} {i + 1} 1 0 0 0 0 0 1 {_INFO}\n" for i in range(2)
)
VALID_GT = "".join(f"{i} {float(i)} 0 0 0 0 0 1\n" for i in range(3))
VALID_DAT = f"1 0 2 1 1 0 0 0 0 0 1 {_INFO}\n"


def dataset(root: Path, *, g2o: str | None = None, gt: str | None = None, dat: str | None = None) -> Path:
    """A valid two-agent multi-g2o folder ``root/ds`` with hostile files (names in tests/data/hostile)
    put in place of agent1's posegraph.g2o, agent1's ground truth or the inter-agent closures."""
    ds = root / "ds"
    for agent in ("agent1", "agent2"):
        (ds / agent).mkdir(parents=True)
        (ds / agent / "posegraph.g2o").write_text(VALID_G2O)
        (ds / agent / f"{agent}_GT.tum").write_text(VALID_GT)
    (ds / "inter_agent_lc.dat").write_text(VALID_DAT)
    for name, rel in ((g2o, "agent1/posegraph.g2o"), (gt, "agent1/agent1_GT.tum"), (dat, "inter_agent_lc.dat")):
        if name is not None:
            shutil.copyfile(HOSTILE / name, ds / rel)
    return ds


def snapshot(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def refused(args: list[str], message: str, *, outputs: list[Path], watch: Path) -> None:
    """Run ``studio ARGS``: exit code 2, stderr exactly ``message`` on one line, no traceback, nothing
    on stdout, none of ``outputs`` written and nothing new (no staging folder) under ``watch``."""
    before = snapshot(watch)
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr, result.exception)
    assert isinstance(result.exception, SystemExit)  # not an exception that escaped
    assert result.stderr == message + "\n"
    assert "Traceback" not in result.stderr and result.stdout == ""
    for out in outputs:
        assert not out.exists(), out
    assert snapshot(watch) == before


def record(tmp_path: Path, ds: Path, message: str) -> None:
    out = tmp_path / "rec" / "X.rrd"
    refused(["record", ds, "-o", out], message, outputs=[out, out.parent], watch=tmp_path)


def evaluate(tmp_path: Path, ds: Path, message: str) -> None:
    refused(["evaluate", ds], message, outputs=[], watch=tmp_path)


def convert_tum(tmp_path: Path, src: Path, message: str) -> None:
    out = tmp_path / "out" / "ds"
    refused(["convert", "tum", src, "-o", out], message, outputs=[out.parent], watch=tmp_path)


def synth(tmp_path: Path, cfg: Path, message: str) -> None:
    out = tmp_path / "out"
    refused(["synth", cfg, "-o", out], message, outputs=[out], watch=tmp_path)


def copy(tmp_path: Path, name: str) -> Path:
    return Path(shutil.copyfile(HOSTILE / name, tmp_path / name))


# ------------------------------------------------------------------------------------------ g2o files


def test_truncated_g2o(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_truncated.g2o")
    record(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:6: EDGE_SE3:QUAT needs 30 fields, found 12")


def test_g2o_wrong_column_count(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_wrong_columns.g2o")
    evaluate(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:2: VERTEX_SE3:QUAT needs 8 fields, found 7")


def test_g2o_non_numeric_field(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_non_numeric.g2o")
    evaluate(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:3: '0,5' is not a number")


def test_g2o_nan(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_nan.g2o")
    record(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:2: value is not finite")


def test_g2o_inf_information(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_inf.g2o")
    record(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:5: value is not finite")


def test_g2o_duplicate_vertex_id(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_duplicate_vertex.g2o")
    evaluate(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:4: vertex 1 is defined twice")


def test_g2o_edge_to_unknown_vertex(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_edge_unknown_vertex.g2o")
    record(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:6: edge refers to unknown vertex 7")


def test_g2o_latin1_bytes(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_latin1.g2o")
    record(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:1: not UTF-8 text (byte 0xe9 at column 8)")


def test_g2o_utf16(tmp_path):
    ds = dataset(tmp_path, g2o="g2o_utf16.g2o")
    evaluate(tmp_path, ds, f"error: {ds}/agent1/posegraph.g2o:1: UTF-16 text, not UTF-8 (save it as UTF-8 or ASCII)")


def test_g2o_2gb_sparse_file_is_refused_before_reading(tmp_path):
    ds = dataset(tmp_path)
    size = 2 * 1024**3 + 1  # a sparse file: no disk used, but a naive read would take 2 GB of memory
    with open(ds / "agent1" / "posegraph.g2o", "r+b") as f:
        f.truncate(size)
    t0 = time.perf_counter()
    record(
        tmp_path,
        ds,
        f"error: {ds}/agent1/posegraph.g2o: {size} bytes is over the 1073741824 byte (1 GiB) limit of text inputs",
    )
    assert time.perf_counter() - t0 < bound_s(5.0)


# -------------------------------------------------------------- ground truth and inter-agent closures


def test_ground_truth_unsorted_timestamps(tmp_path):
    ds = dataset(tmp_path, gt="gt_unsorted.tum")
    evaluate(tmp_path, ds, f"error: {ds}/agent1/agent1_GT.tum:4: timestamps must increase")


def test_inter_agent_lc_wrong_column_count(tmp_path):
    ds = dataset(tmp_path, dat="dat_wrong_columns.dat")
    record(tmp_path, ds, f"error: {ds}/inter_agent_lc.dat:2: expected 32 (SE3) or 13 (SE2) columns, found 14")


def test_inter_agent_lc_unknown_vertex(tmp_path):
    ds = dataset(tmp_path, dat="dat_unknown_vertex.dat")
    record(
        tmp_path,
        ds,
        f"error: {ds}/inter_agent_lc.dat: inter-agent edge 0 refers to vertex 9 of agent agent2, which has 3 poses",
    )


# ---------------------------------------------------------------------------- studio convert tum


def test_tum_wrong_column_count(tmp_path):
    src = copy(tmp_path, "tum_wrong_columns.tum")
    convert_tum(tmp_path, src, f"error: {src}:2: expected 8 columns (t x y z qx qy qz qw), found 7")


def test_tum_non_numeric_field(tmp_path):
    src = copy(tmp_path, "tum_non_numeric.tum")
    convert_tum(tmp_path, src, f"error: {src}:3: 'O' is not a number")


def test_tum_line_of_separators_only(tmp_path):
    src = copy(tmp_path, "tum_commas_only_line.tum")  # found by the fuzzer: an IndexError before the fix
    convert_tum(tmp_path, src, f"error: {src}:2: expected 8 columns (t x y z qx qy qz qw), found 0")


def test_tum_nan(tmp_path):
    src = copy(tmp_path, "tum_nan.tum")
    convert_tum(tmp_path, src, f"error: {src}:3: value is not finite")


def test_tum_inf_timestamp(tmp_path):
    src = copy(tmp_path, "tum_inf_stamp.tum")
    convert_tum(tmp_path, src, f"error: {src}:2: timestamp 'inf' is not a number")


def test_tum_huge_coordinate(tmp_path):
    src = copy(tmp_path, "tum_huge_coordinate.tum")
    convert_tum(
        tmp_path, src, f"error: {src}: pose 1 has a coordinate of 1e+308 m, beyond the 1e+09 m a trajectory may reach"
    )


def test_tum_latin1_bytes(tmp_path):
    src = copy(tmp_path, "tum_latin1.tum")
    convert_tum(tmp_path, src, f"error: {src}:1: not UTF-8 text (byte 0xe9 at column 15)")


def test_tum_utf16(tmp_path):
    src = copy(tmp_path, "tum_utf16.tum")
    convert_tum(tmp_path, src, f"error: {src}:1: UTF-16 text, not UTF-8 (save it as UTF-8 or ASCII)")


def test_tum_2gb_sparse_file_is_refused_before_reading(tmp_path):
    src = tmp_path / "huge.tum"
    with open(src, "wb") as f:
        f.write(b"1600000000.0 0 0 0 0 0 0 1\n")
        f.truncate(2 * 10**9)  # "2 GB", sparse
    t0 = time.perf_counter()
    convert_tum(
        tmp_path, src, f"error: {src}: 2000000000 bytes is over the 1073741824 byte (1 GiB) limit of text inputs"
    )
    assert time.perf_counter() - t0 < bound_s(5.0)


# ---------------------------------------------------------------------------------- studio synth


def test_synth_deeply_nested_json(tmp_path):
    cfg = tmp_path / "nested.json"
    cfg.write_text("[" * 100_000 + "]" * 100_000)
    synth(tmp_path, cfg, f"error: {cfg}: invalid JSON: nested too deeply")


def test_synth_deeply_nested_value_inside_a_valid_config(tmp_path):
    doc = json.loads((DATA / "configs" / "tiny_single.json").read_text())
    text = json.dumps(doc).replace('"align": true', '"align": ' + '{"a": ' * 20_000 + "1" + "}" * 20_000)
    cfg = tmp_path / "nested_align.json"
    cfg.write_text(text)
    synth(tmp_path, cfg, f"error: {cfg}: invalid JSON: nested too deeply")


def test_synth_huge_json(tmp_path):
    cfg = tmp_path / "huge.json"
    with open(cfg, "wb") as f:
        f.write(b'{"number_of_steps": 70, "pad": "')
        f.truncate(2 * 10**9)  # sparse: refused from its size, never read
    t0 = time.perf_counter()
    synth(tmp_path, cfg, f"error: {cfg}: 2000000000 bytes is too large for a config (limit 16777216)")
    assert time.perf_counter() - t0 < bound_s(5.0)


def test_synth_utf16_json(tmp_path):
    cfg = copy(tmp_path, "synth_utf16.json")
    synth(tmp_path, cfg, f"error: {cfg}:1: not UTF-8 text")


def test_synth_latin1_json(tmp_path):
    cfg = copy(tmp_path, "synth_latin1.json")
    synth(tmp_path, cfg, f"error: {cfg}:3: not UTF-8 text")


def test_synth_integer_of_401_digits(tmp_path):
    cfg = copy(tmp_path, "synth_long_integer.json")
    synth(tmp_path, cfg, f"error: {cfg}: invalid JSON: an integer of 401 digits is too long")


def test_synth_stepsize_that_overflows(tmp_path):
    cfg = copy(tmp_path, "synth_huge_stepsize.json")
    synth(tmp_path, cfg, f"error: {cfg}: agent_parameters.stepsize: 1e+300 is outside [1e-09, 1000000000.0] m")


def test_synth_too_many_agents(tmp_path):
    cfg = copy(tmp_path, "synth_too_many_agents.json")
    t0 = time.perf_counter()
    synth(tmp_path, cfg, f"error: {cfg}: number_of_agents: 2147483647 is over the limit of 10000 agents")
    assert time.perf_counter() - t0 < bound_s(5.0)


# ------------------------------------------------------------------------------ studio convert bag


def source_dir(tmp_path: Path) -> Path:
    (tmp_path / "src").mkdir(exist_ok=True)
    return tmp_path / "src"


def _pose_topics(storage: str, n: int = 40):
    from tests.converters.bags import Msgs, typestore
    from tests.converters.synthetic import loop_trajectory

    m = Msgs(typestore(storage))
    s, p, q = loop_trajectory(n)
    return {"/a/pose": [(int(t), m.PoseStamped(int(t), pp, qq)) for t, pp, qq in zip(s, p, q)]}


def _mismatched_bag(path: Path, storage: str, data_type: str) -> Path:
    """A bag whose /a/pose connection says geometry_msgs/PoseStamped while every message is a
    ``data_type`` (std_msgs/String or nav_msgs/Odometry) serialised as such."""
    from tests.converters.bags import Msgs, typestore
    from tests.converters.synthetic import loop_trajectory

    ts = typestore(storage)
    m = Msgs(ts)
    s, p, q = loop_trajectory(20)
    msgs = [m.String(int(t)) if data_type == "String" else m.Odometry(int(t), pp, qq) for t, pp, qq in zip(s, p, q)]
    if storage == "ros1":
        from rosbags.rosbag1 import Writer

        path = path.with_suffix(".bag")
        with Writer(path) as w:
            conn = w.add_connection("/a/pose", "geometry_msgs/msg/PoseStamped", typestore=ts)
            for t, msg in zip(s, msgs):
                w.write(conn, int(t), ts.serialize_ros1(msg, msg.__msgtype__))
        return path
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection("/a/pose", "geometry_msgs/msg/PoseStamped", typestore=ts)
        for t, msg in zip(s, msgs):
            w.write(conn, int(t), ts.serialize_cdr(msg, msg.__msgtype__))
    return path


def convert_bag(tmp_path: Path, bag: Path, message: str) -> None:
    out = tmp_path / "out" / "ds"
    refused(["convert", "bag", bag, "--agent", "a=/a/pose", "-o", out], message, outputs=[out.parent], watch=tmp_path)


def test_ros1_bag_cut_in_the_middle(tmp_path):
    from tests.converters.bags import write_bag

    bag = write_bag(source_dir(tmp_path) / "run", "ros1", _pose_topics("ros1"))
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])
    convert_bag(
        tmp_path,
        bag,
        f"error: {bag}: cannot read the bag, corrupt or truncated? (Bag index looks damaged: "
        "('Header could not be read from file.',))",
    )


def test_mcap_file_cut_in_the_middle(tmp_path):
    from tests.converters.bags import write_bag

    folder = write_bag(source_dir(tmp_path) / "run", "mcap", _pose_topics("mcap"))
    data = next(folder.glob("*.mcap")).read_bytes()
    bag = tmp_path / "run.mcap"
    bag.write_bytes(data[: len(data) // 2])
    shutil.rmtree(folder)
    convert_bag(tmp_path, bag, f"error: {bag}: cannot read the bag, corrupt or truncated? (File end magic is invalid.)")


def test_sqlite3_bag_cut_in_the_middle(tmp_path):
    from tests.converters.bags import write_bag

    bag = write_bag(source_dir(tmp_path) / "run", "sqlite3", _pose_topics("sqlite3"))
    db = next(bag.glob("*.db3"))
    data = db.read_bytes()
    db.write_bytes(data[: len(data) // 2])
    convert_bag(
        tmp_path,
        bag,
        f"error: {bag}: cannot read the bag, corrupt or truncated? (Cannot open database "
        f"{db}: database disk image is malformed)",
    )


def test_ros1_bag_header_claiming_2gb(tmp_path):
    """The bag-header record's header length says 2 GiB: refused at once, nothing allocated for it."""
    from tests.converters.bags import write_bag

    bag = write_bag(source_dir(tmp_path) / "run", "ros1", _pose_topics("ros1"))
    data = bytearray(bag.read_bytes())
    assert data[:13] == b"#ROSBAG V2.0\n"
    struct.pack_into("<I", data, 13, 0x7FFFFFFF)
    bag.write_bytes(bytes(data))
    t0 = time.perf_counter()
    convert_bag(
        tmp_path, bag, f"error: {bag}: cannot read the bag, corrupt or truncated? (Header could not be read from file.)"
    )
    assert time.perf_counter() - t0 < bound_s(5.0)


def test_ros1_bag_connection_type_differs_from_data(tmp_path):
    bag = _mismatched_bag(source_dir(tmp_path) / "run", "ros1", "String")
    convert_bag(
        tmp_path,
        bag,
        f"error: {bag}: cannot read the bag, corrupt or truncated? (Could not deserialize "
        "'geometry_msgs/msg/PoseStamped': unpack_from requires a buffer of at least 12 bytes "
        "for unpacking 4 bytes at offset 8 (actual buffer size is 9))",
    )


def test_mcap_bag_connection_type_differs_from_data(tmp_path):
    bag = _mismatched_bag(source_dir(tmp_path) / "run", "mcap", "Odometry")
    convert_bag(
        tmp_path,
        bag,
        f"error: {bag}: cannot read the bag, corrupt or truncated? (CDR message size mismatch "
        "for 'geometry_msgs/msg/PoseStamped'.)",
    )


def test_sqlite3_bag_connection_type_differs_from_data(tmp_path):
    bag = _mismatched_bag(source_dir(tmp_path) / "run", "sqlite3", "String")
    convert_bag(
        tmp_path,
        bag,
        f"error: {bag}: cannot read the bag, corrupt or truncated? (Could not deserialize "
        "'geometry_msgs/msg/PoseStamped': unpack_from requires a buffer of at least 12 bytes "
        "for unpacking 4 bytes at offset 8 (actual buffer size is 10))",
    )


def test_every_committed_hostile_file_has_a_test():
    names = {p.name for p in HOSTILE.iterdir() if p.name != "README.md"}
    source = Path(__file__).read_text()
    assert names and all(f'"{n}"' in source for n in names), sorted(n for n in names if f'"{n}"' not in source)
