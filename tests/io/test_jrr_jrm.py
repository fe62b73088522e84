"""JRL results (.jrr) and metrics (.jrm): the layouts jrl's Writer writes, read back; round trips;
bad files refused in one line naming the JSON path."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import FormatError
from studio.core.jrl_metrics import RobotValues
from studio.core.model import PoseKind
from studio.io.jrm import MetricSummary, read_jrm, write_jrm
from studio.io.jrr import JrlResults, read_jrr, write_jrr

A, B = ord("a") << 56, ord("b") << 56

# What jrl's Writer::writeResults writes (nlohmann: std::map objects with sorted keys, a char as a
# number, compact): robot a's solution holds a copy of b's pose b0 it shares.
JRL_WRITER_JRR = (
    (
        '{"dataset_name":"tiny","method_name":"mesa","outliers":{"a":[[1,0]],"b":[]},"robots":[97,98],'
        '"solutions":{"a":[{"key":KEY_A0,"rotation":[1.0,0.0,0.0,0.0],"translation":[0.0,0.0,0.0],"type":"Pose3"},'
        '{"key":KEY_B0,"rotation":[0.0,0.0,0.0,1.0],"translation":[1.5,-2.0,3.0],"type":"Pose3"}],'
        '"b":[{"key":KEY_B0,"rotation":[0.9800665778412416,0.0,0.0,0.19866933079506122],"translation":[1.0,-2.0,3.0],'
        '"type":"Pose3"}]}}'
    )
    .replace("KEY_A0", str(A))
    .replace("KEY_B0", str(B))
)


def test_a_jrr_as_jrls_writer_writes_it_is_read(tmp_path: Path):
    path = tmp_path / "r.jrr"
    path.write_text(JRL_WRITER_JRR)
    r = read_jrr(path)
    assert (r.dataset_name, r.method_name, r.robots, r.kind) == ("tiny", "mesa", ("a", "b"), PoseKind.SE3)
    assert r.solutions[0].keys.tolist() == [A, B] and r.solutions[1].keys.tolist() == [B]
    # [w, x, y, z] in the file, x y z qx qy qz qw inside
    assert r.solutions[0].poses[1].tolist() == [1.5, -2.0, 3.0, 0.0, 0.0, 1.0, 0.0]
    assert r.solutions[1].poses[0, 6] == pytest.approx(0.9800665778412416)
    assert r.outliers is not None and r.outliers[0].tolist() == [[1, 0]] and r.outliers[1].shape == (0, 2)


def test_writing_gives_jrls_bytes_and_reading_gives_the_results_back(tmp_path: Path):
    path = tmp_path / "r.jrr"
    path.write_text(JRL_WRITER_JRR)
    again = tmp_path / "again.jrr"
    write_jrr(again, read_jrr(path))
    assert again.read_text() == JRL_WRITER_JRR


def test_planar_results_and_one_character_robot_ids(tmp_path: Path):
    res = JrlResults(
        "d",
        "m",
        ("a", "b"),
        PoseKind.SE2,
        (
            RobotValues(np.array([A, A + 1]), np.array([[0.0, 1.0, 0.5], [2.0, 3.0, -1.0]])),
            RobotValues(np.zeros(0, np.int64), np.zeros((0, 3))),
        ),
    )
    path = tmp_path / "p.jrr"
    write_jrr(path, res)
    doc = json.loads(path.read_text())
    assert doc["robots"] == [97, 98] and doc["solutions"]["a"][1] == {
        "key": A + 1,
        "theta": -1.0,
        "type": "Pose2",
        "x": 2.0,
        "y": 3.0,
    }
    back = read_jrr(path)
    assert back.kind is PoseKind.SE2 and back.solutions[0].poses.tolist() == res.solutions[0].poses.tolist()
    assert back.solutions[1].poses.shape == (0, 3) and back.outliers is None
    doc["robots"] = ["a", "b"]  # hand-written files
    path.write_text(json.dumps(doc))
    assert read_jrr(path).robots == ("a", "b")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["solutions"].update(c=[]), r"solutions\.c: robot 'c' is not in robots"),
        (lambda d: d["outliers"].update(z=[]), r"outliers\.z: robot 'z' is not in robots"),
        (
            lambda d: d["solutions"]["a"][1]["translation"].__setitem__(0, float("nan")),
            r"solutions\.a\[1\]: not a finite",
        ),
        (
            lambda d: d["solutions"]["a"][1]["rotation"].__setitem__(0, 0.5),
            r"solutions\.a\[1\]\.rotation: quaternion is not unit",
        ),
        (lambda d: d["solutions"]["a"][1].update(type="Point3"), r"solutions\.a\[1\]\.type: expected Pose2 or Pose3"),
        (lambda d: d["solutions"]["a"][1].update(key=A), r"solutions\.a: key \d+ is listed twice"),
        (lambda d: d.update(robots=[97, 300]), r"robots\[1\]: expected a robot id"),
        (lambda d: d["solutions"]["a"][0].pop("rotation"), r"solutions\.a\[0\]: a Pose3 value needs"),
        (lambda d: d["solutions"]["a"][0]["translation"].pop(), r"solutions\.a\[0\]: a Pose3 value needs"),
        (lambda d: d["solutions"]["b"][0]["translation"].__setitem__(2, "3"), r"solutions\.b\[0\]: not a finite"),
    ],
)
def test_a_bad_jrr_is_refused_naming_the_json_path(tmp_path: Path, edit, message):
    doc = json.loads(JRL_WRITER_JRR)
    edit(doc)
    path = tmp_path / "bad.jrr"
    path.write_text(json.dumps(doc))
    with pytest.raises(FormatError, match=message) as err:
        read_jrr(path)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def test_a_jrm_is_written_as_jrls_writer_writes_it_and_read_back(tmp_path: Path):
    summary = MetricSummary(
        "tiny",
        "mesa",
        ("a", "b"),
        robot_ate={"b": (0.5, 0.25), "a": (1.0, 0.125)},
        total_ate=(1.5, 0.375),
        joint_aligned_ate=(0.75, 0.2),
        sve=(math.nan, math.nan),
        mean_residual=12.5,
        robot_precision_recall={"a": (1.0, 0.5)},
        precision_recall=(1.0, 0.5),
    )
    path = tmp_path / "m.jrm"
    write_jrm(path, summary)
    # nlohmann writes a std::map<char, pair> (its key not a string) as [key, value] pairs, NaN as null
    assert path.read_text() == (
        '{"dataset_name":"tiny","joint_aligned_ate":[0.75,0.2],"mean_residual":12.5,"method_name":"mesa",'
        '"precision_recall":[1.0,0.5],"robot_ate":[[97,[1.0,0.125]],[98,[0.5,0.25]]],'
        '"robot_precision_recall":[[97,[1.0,0.5]]],"robots":[97,98],"sve":[null,null],"total_ate":[1.5,0.375]}'
    )
    back = read_jrm(path)
    assert back.robot_ate == {"a": (1.0, 0.125), "b": (0.5, 0.25)} and back.total_ate == (1.5, 0.375)
    assert back.sve is not None and all(math.isnan(x) for x in back.sve)
    assert back.mean_residual == 12.5 and back.precision_recall == (1.0, 0.5)


def test_a_jrm_with_only_the_header_and_a_bad_one(tmp_path: Path):
    path = tmp_path / "m.jrm"
    write_jrm(path, MetricSummary("d", "m", ("a",), mean_residual=0.0))
    assert read_jrm(path).robot_ate is None
    path.write_text('{"dataset_name":"d","method_name":"m","robots":[97],"robot_ate":{"a":[1,2]}}')
    with pytest.raises(FormatError, match=r"robot_ate: expected a list of \[robot, \[a, b\]\] pairs"):
        read_jrm(path)
