"""converters.tum: TUM-style text in every accepted shape, and every bad input named file:line."""

from __future__ import annotations

import numpy as np
import pytest

from studio.converters.tum import read_tum_sources, read_tum_trajectory
from studio.core.errors import ConfigError, FormatError
from tests.converters.synthetic import loop_trajectory, write_tum_file


def test_space_and_comma_separated_with_header_give_the_same_trajectory(tmp_path):
    s, p, q = loop_trajectory(50)
    a = write_tum_file(tmp_path / "a.txt", s, p, q)
    b = write_tum_file(tmp_path / "b.csv", s, p, q, sep=",", header="timestamp,tx,ty,tz,qx,qy,qz,qw")
    ta, tb = read_tum_trajectory(a), read_tum_trajectory(b)
    assert ta.name == "a" and tb.name == "b"
    np.testing.assert_array_equal(ta.stamps_ns, s)
    np.testing.assert_array_equal(ta.stamps_ns, tb.stamps_ns)
    np.testing.assert_array_equal(ta.positions_xyz, p)
    np.testing.assert_array_equal(tb.positions_xyz, p)
    np.testing.assert_allclose(ta.quat_xyzw, q, atol=1e-15)


def test_quaternions_are_normalised_and_nanoseconds_exact(tmp_path):
    f = tmp_path / "r.txt"
    f.write_text("# comment\n1634567890.123456789 1 2 3 0 0 0 2\n1634567890.2 1 2 3 0 0 3 4\n")
    t = read_tum_trajectory(f)
    assert t.stamps_ns.tolist() == [1634567890123456789, 1634567890200000000]
    np.testing.assert_allclose(t.quat_xyzw, [[0, 0, 0, 1], [0, 0, 0.6, 0.8]], atol=1e-15)


def test_unsorted_and_duplicate_stamps_are_fixed_with_a_counting_warning(tmp_path):
    f = tmp_path / "r.txt"
    f.write_text("3 3 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n2 9 0 0 0 0 0 1\n4 4 0 0 0 0 0 1\n")
    warnings = []
    t = read_tum_trajectory(f, warn=warnings.append)
    assert t.stamps_ns.tolist() == [1e9, 2e9, 3e9, 4e9]
    assert t.positions_xyz[:, 0].tolist() == [1, 2, 3, 4]  # the first of the duplicates is kept
    assert warnings == [f"{f}: 1 out-of-order timestamp sorted, 1 duplicate timestamp dropped"]


@pytest.mark.parametrize(
    "body, match",
    [
        ("1 0 0 0 0 0 0 1\n2 nan 0 0 0 0 0 1\n", r"r\.txt:2: value is not finite"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", r"r\.txt:2: expected 8 columns"),
        ("1 0 0 0 0 0 0 1\n2 0 x 0 0 0 0 1\n", r"r\.txt:2: 'x' is not a number"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 0\n", r"r\.txt:2: quaternion is zero"),
        ("# only a comment\n", r"r\.txt: no poses"),
        ("", r"r\.txt: no poses"),
        ("1 0 0 0 0 0 0 1\n", r"has 1 pose; a trajectory needs at least 2"),
        ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", r"has 1 pose; a trajectory needs at least 2"),
    ],
)
def test_bad_input_names_file_and_line(tmp_path, body, match):
    f = tmp_path / "r.txt"
    f.write_text(body)
    with pytest.raises(FormatError, match=match):
        read_tum_trajectory(f)


def test_agent_names_from_file_names_are_safe_folder_names(tmp_path):
    s, p, q = loop_trajectory(20)
    weird = write_tum_file(tmp_path / "..robot 1 (front).txt", s, p, q)
    [t] = read_tum_sources([weird])
    assert t.name == "robot_1_front"
    assert "/" not in t.name and not t.name.startswith(".")


def test_tum_rejects_agent_specs_and_needs_a_file(tmp_path):
    """The source's facts are checked once, by the registry, before its reader runs."""
    from studio.converters.registry import check_inputs

    with pytest.raises(ConfigError, match="--agent is only for `studio convert bag`; tum agents are named after"):
        check_inputs("tum", [tmp_path / "x.txt"], ["a=/odom"])
    with pytest.raises(ConfigError, match="studio convert tum needs trajectory files"):
        check_inputs("tum", [], [])
    check_inputs("bag", ["run.bag"], ["a=/odom"])  # bags take --agent


def test_large_files_take_the_bulk_parser_with_identical_results(tmp_path, monkeypatch):
    from studio.io import tum as tum_io

    s, p, q = loop_trajectory(4000, centre=(500_000.0, 4_649_776.0, 10.0))
    q = q * 1.5  # not normalised in the file
    f = write_tum_file(tmp_path / "big.txt", s, p, q, sep=",", header="t,x,y,z,qx,qy,qz,qw")
    assert f.stat().st_size > tum_io._FAST_MIN_CHARS
    text = f.read_text()
    fast = tum_io._read_tum_fast(text, True)
    assert fast is not None
    monkeypatch.setattr(tum_io, "_FAST_MIN_CHARS", 10**12)
    slow = tum_io.read_tum(f)
    np.testing.assert_array_equal(fast[0], slow.stamps_ns)
    np.testing.assert_array_equal(fast[1], slow.poses_xyz_quat_xyzw)
    np.testing.assert_array_equal(fast[0], s)


@pytest.mark.parametrize(
    "edit, match",
    [
        (
            lambda lines: lines.__setitem__(3000, lines[3000].replace(" ", " nan ", 1)),
            r"big\.txt:3001: expected 8 columns",
        ),
        (
            lambda lines: lines.__setitem__(3000, lines[3000].rsplit(" ", 1)[0] + " nan"),
            r"big\.txt:3001: value is not finite",
        ),
        (lambda lines: lines.__setitem__(3000, lines[2998]), r"big\.txt:3001: timestamps must increase"),
        (lambda lines: lines.__setitem__(3000, lines[3000] + " # note"), r"big\.txt:3001: expected 8 columns"),
    ],
)
def test_irregular_large_files_fall_back_to_the_line_parser(tmp_path, edit, match):
    from studio.io.tum import read_tum

    s, p, q = loop_trajectory(4000)
    lines = write_tum_file(tmp_path / "x.txt", s, p, q, header=None).read_text().splitlines()
    edit(lines)
    f = tmp_path / "big.txt"
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(FormatError, match=match):
        read_tum(f)


def test_bulk_stamp_parser_agrees_with_the_line_parser():
    from studio.io.tum import _stamp_ns, _stamps_from_digits

    rng = np.random.default_rng(1)
    tokens = [
        f"{int(w)}.{int(f):0{d}d}"
        for w, f, d in zip(rng.integers(0, 2_000_000_000, 300), rng.integers(0, 10**9, 300), rng.integers(9, 10, 300))
    ]
    tokens += ["0", "7", "7.", ".5", "1634567890.123456789999", "1.000000001", "8999999999.999999999"]
    got = _stamps_from_digits(np.array(tokens))
    assert got.tolist() == [_stamp_ns(t) for t in tokens]
    for bad in (["1e9"], ["-1.5"], ["1.2.3"], ["."], ["12345678901"], ["a"]):
        assert _stamps_from_digits(np.array(bad)) is None


def test_tum_rgbd_sequences_all_named_groundtruth_become_agents_named_after_their_folders(tmp_path):
    """TUM RGB-D ships every sequence's ground truth as ``<sequence>/groundtruth.txt`` with three
    ``#`` header lines; two of them given together are two agents named after their folders."""
    from typer.testing import CliRunner

    from studio.cli import app
    from studio.io.multig2o import read_multi_g2o

    header = "# ground truth trajectory\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp tx ty tz qx qy qz qw"
    files = []
    for k, seq in enumerate(["rgbd_dataset_freiburg1_xyz", "rgbd_dataset_freiburg1_desk"]):
        s, p, q = loop_trajectory(200, phase=k)
        (tmp_path / seq).mkdir()
        files.append(write_tum_file(tmp_path / seq / "groundtruth.txt", s, p, q, header=header))
    assert [t.name for t in read_tum_sources(files)] == ["rgbd_dataset_freiburg1_xyz", "rgbd_dataset_freiburg1_desk"]
    res = CliRunner().invoke(app, ["convert", "tum", *map(str, files), "-o", str(tmp_path / "ds")])
    assert res.exit_code == 0, res.output
    assert [a.name for a in read_multi_g2o(tmp_path / "ds").agents] == [
        "rgbd_dataset_freiburg1_xyz",
        "rgbd_dataset_freiburg1_desk",
    ]
    # names that still collide are refused without suggesting an option `tum` does not have
    (tmp_path / "x" / "rgbd").mkdir(parents=True)
    (tmp_path / "y" / "rgbd").mkdir(parents=True)
    twins = [write_tum_file(tmp_path / d / "rgbd" / "groundtruth.txt", s, p, q) for d in ("x", "y")]
    res = CliRunner().invoke(app, ["convert", "tum", *map(str, twins), "-o", str(tmp_path / "ds2")])
    assert res.exit_code == 2
    assert "two agents are named 'rgbd'" in res.output and "--agent" not in res.output
    assert not (tmp_path / "ds2").exists()
