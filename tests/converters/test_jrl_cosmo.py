"""JRL as jrl's own code reads and writes it, on files in COSMO-Bench's layout that the tests write
(tests/converters/jrl_files.py): robot ids as numbers, a ``PriorFactorPose3`` per robot, dense
covariances, copies of other robots' poses in each robot's values, potential and labelled outliers.

``studio convert jrl`` keeps all of it in the dataset folder (``priors.txt``, ``outliers.txt``,
``potential_outliers.txt``); ``studio export --format jrl`` writes it back, and a reimplementation of
jrl's ``Parser`` (here, in the test: ``src/Parser.cpp``, ``include/jrl/IOMeasurements.h``,
``src/IOValues.cpp``) reads the export as the same graph, priors and labels. Bad files are one line
naming the file and the JSON path, exit 2, nothing written."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.export import read_dataset_outliers
from studio.io.multig2o import read_multi_g2o
from studio.io.priors_txt import read_priors_txt
from tests.converters.jrl_files import PRIOR_SIGMAS, cosmo_team, key, write_cosmo_jrl

runner = CliRunner()


def _run(*args: Any):
    return runner.invoke(app, [*map(str, args)])


# ------------------------------------------------------------------ jrl's Parser, reimplemented


def _rotation(q_wxyz: list[float]) -> np.ndarray:
    """``gtsam::Rot3::Quaternion(w, x, y, z)``: Eigen's ``toRotationMatrix`` of the quaternion."""
    w, x, y, z = q_wxyz
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose3(obj: dict) -> tuple[np.ndarray, np.ndarray]:
    """``parse<gtsam::Pose3>``: ``translation`` [x, y, z], ``rotation`` [w, x, y, z]."""
    return np.array(obj["translation"], dtype=float), _rotation(obj["rotation"])


def jrl_parse(doc: dict) -> dict[str, Any]:
    """``Parser::parseDataset`` for what a 3D pose graph holds. ``robots`` is read with
    ``get<std::vector<char>>()``, which takes numbers (a string is nlohmann's type_error 302); a
    section's robot is its key's first character; a factor is parsed by its type tag
    (``measurement_parsers_.at``, so an unknown tag throws); a covariance is ``Eigen::Map``-ped
    column-major; FactorIds are ``std::set<std::pair<size_t, size_t>>``."""
    robots = doc["robots"]
    if not all(type(c) is int and -128 <= c < 256 for c in robots):
        raise TypeError("[json.exception.type_error.302] type must be number")
    robots = [chr(c) for c in robots]
    factors: dict[tuple[str, int, int], tuple] = {}
    for name, entries in doc["measurements"].items():
        rid = name[0]
        for e, entry in enumerate(entries):
            stamp = entry["stamp"]
            assert type(stamp) is int and stamp >= 0  # get<uint64_t>
            for m, f in enumerate(entry.get("measurements", [])):
                tag = f["type"]
                if tag == "PriorFactorPose3":
                    keys, value = (f["key"],), _pose3(f["prior"])
                elif tag == "BetweenFactorPose3":
                    keys, value = (f["key1"], f["key2"]), _pose3(f["measurement"])
                else:
                    raise KeyError(tag)
                assert all(type(k) is int and 0 <= k < 1 << 64 for k in keys)
                cov = np.array(f["covariance"], dtype=float).reshape(6, 6, order="F")
                factors[(rid, e, m)] = (tag, stamp, keys, value, cov)
    values: dict[str, dict[str, dict[int, tuple]]] = {}
    for section in ("groundtruth", "initialization"):
        for name, vals in doc.get(section, {}).items():
            held = values.setdefault(section, {}).setdefault(name[0], {})
            for v in vals:
                assert v["type"] == "Pose3"
                if v["key"] in held:  # gtsam::Values::insert throws ValuesKeyAlreadyExists
                    raise ValueError(f"{section}.{name}: key {v['key']} twice")
                held[v["key"]] = _pose3(v)
    labels = {
        section: {name[0]: {tuple(p) for p in pairs} for name, pairs in doc[section].items()}
        for section in ("potential_outlier_factors", "outlier_factors")
        if section in doc
    }
    return {"name": doc["name"], "robots": robots, "factors": factors, "values": values, "labels": labels}


def _by_identity(parsed: dict) -> dict[tuple, tuple]:
    """Factors by what they are (robot, type, keys), whatever entry and index they sit at."""
    out: dict[tuple, tuple] = {}
    for (rid, _e, _m), (tag, stamp, keys, value, cov) in parsed["factors"].items():
        ident = (rid, tag, keys)
        assert ident not in out
        out[ident] = (stamp, value, cov)
    return out


def _labelled(parsed: dict, section: str) -> set[tuple]:
    return {
        (rid, parsed["factors"][(rid, e, m)][0], parsed["factors"][(rid, e, m)][2])
        for rid, ids in parsed["labels"][section].items()
        for e, m in ids
    }


def _same_pose(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], tol: float = 1e-12) -> bool:
    return bool(np.allclose(a[0], b[0], rtol=0, atol=tol) and np.allclose(a[1], b[1], rtol=0, atol=tol))


# ------------------------------------------------------------------------------------ fixtures


@pytest.fixture(scope="module")
def cosmo(tmp_path_factory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("cosmo")
    doc, team = cosmo_team()
    src = write_cosmo_jrl(root / "cosmo_like.jrl", doc)
    res = _run("convert", "jrl", src, "-o", root / "ds", "--no-rrd")
    assert res.exit_code == 0, res.output
    back = _run("export", root / "ds", "--format", "jrl", "-o", root / "back.jrl")
    assert back.exit_code == 0, back.output
    return {"root": root, "doc": doc, "team": team, "src": src, "ds": root / "ds", "back": root / "back.jrl"}


# ------------------------------------------------------------------------------------ tests


def test_convert_reads_robot_ids_as_jrl_writes_them_and_keeps_priors_and_labels(cosmo):
    doc, ds = cosmo["doc"], cosmo["ds"]
    assert doc["robots"] == [97, 98]
    graph = read_multi_g2o(ds)
    counts = json.loads((ds / "import.json").read_text())["counts"]
    assert [a.num_poses for a in graph.agents] == [8, 8]
    assert counts == {
        "odometry": 14,
        "intra_loop_closures": 1,
        "inter_loop_closures": 2,
        "outliers": 2,
        "priors": 2,
        "potential_outliers": 3,
    }
    priors = read_priors_txt(ds / "priors.txt", graph)
    assert priors.agent.tolist() == [0, 1] and priors.index.tolist() == [0, 0]
    np.testing.assert_array_equal(priors.poses[0], cosmo["team"].truth["a"][0])
    # the prior's information in the edges' g2o order: translation 1/sigma^2, the quaternion's vector part 4/sigma^2
    info = priors.information_upper[0]
    diag = info[[0, 6, 11, 15, 18, 20]]
    sig = np.array(PRIOR_SIGMAS)
    np.testing.assert_allclose(diag, [*(1 / sig[3:] ** 2), *(4 / sig[:3] ** 2)], rtol=1e-9)
    # labelled: a7 -> a1 (intra) and b7 -> a3 (inter); potential: every loop closure
    outliers = {tuple(r) for r in read_dataset_outliers(ds, graph).tolist()}
    assert outliers == {(0, 7, 0, 1), (1, 7, 0, 3)}
    potential = {tuple(r) for r in read_dataset_outliers(ds, graph, "potential_outliers.txt").tolist()}
    assert potential == {(0, 7, 0, 1), (0, 6, 1, 2), (1, 7, 0, 3)}
    # stamps: each pose's keyframe entry
    for k, r in enumerate("ab"):
        assert graph.agents[k].stamps_ns.tolist() == cosmo["team"].stamps_ns[r]


def test_a_pose_takes_its_owners_values_not_another_robots_copy(cosmo):
    graph = read_multi_g2o(cosmo["ds"])
    team = cosmo["team"]
    # robot a's file section holds its own (offset) estimate of b2; b's own value is the one kept
    np.testing.assert_array_equal(graph.agents[1].initial[2], team.initial["b"][2])
    np.testing.assert_array_equal(graph.agents[0].initial[3], team.initial["a"][3])
    np.testing.assert_array_equal(graph.agents[1].ground_truth, team.truth["b"])


def test_robot_ids_as_one_character_strings_read_the_same(cosmo, tmp_path):
    doc = dict(cosmo["doc"], robots=["a", "b"])
    src = write_cosmo_jrl(tmp_path / "chars.jrl", doc)
    res = _run("convert", "jrl", src, "-o", tmp_path / "ds", "--no-rrd")
    assert res.exit_code == 0, res.output
    a, b = read_multi_g2o(tmp_path / "ds"), read_multi_g2o(cosmo["ds"])
    for x, y in zip(a.agents, b.agents):
        np.testing.assert_array_equal(x.initial, y.initial)
        np.testing.assert_array_equal(x.odometry.information_upper, y.odometry.information_upper)
    assert (tmp_path / "ds" / "priors.txt").read_bytes() == (cosmo["ds"] / "priors.txt").read_bytes()


def test_ground_truth_copies_that_disagree_are_one_warning(cosmo, tmp_path):
    doc = json.loads(json.dumps(cosmo["doc"]))
    doc["groundtruth"]["a"][-1]["translation"][0] += 1.0  # a's copy of b2
    src = write_cosmo_jrl(tmp_path / "copy.jrl", doc)
    res = _run("convert", "jrl", src, "-o", tmp_path / "ds", "--no-rrd")
    assert res.exit_code == 0, res.output
    assert res.output.count("copies of other robots' poses differ") == 1
    graph = read_multi_g2o(tmp_path / "ds")
    np.testing.assert_array_equal(graph.agents[1].ground_truth[2], cosmo["team"].truth["b"][2])


def test_jrls_parser_reads_the_export_as_the_file_that_was_converted(cosmo):
    """convert -> dataset folder -> export, read by jrl's parsing rules: the same factors (keys,
    measurement, covariance, entry stamp), priors, values and labels as the COSMO-layout file."""
    before = jrl_parse(cosmo["doc"])
    after = jrl_parse(json.loads(cosmo["back"].read_text()))
    assert after["robots"] == before["robots"] == ["a", "b"]
    f0, f1 = _by_identity(before), _by_identity(after)
    assert f1.keys() == f0.keys()
    assert sum(1 for ident in f1 if ident[1] == "PriorFactorPose3") == 2
    for ident, (stamp, value, cov) in f0.items():
        stamp1, value1, cov1 = f1[ident]
        assert stamp1 == stamp, ident
        assert _same_pose(value1, value), ident
        np.testing.assert_allclose(cov1, cov, rtol=1e-9, atol=1e-12 * np.abs(cov).max())
    for section in ("potential_outlier_factors", "outlier_factors"):
        assert _labelled(after, section) == _labelled(before, section)
    for section in ("groundtruth", "initialization"):
        for rid in "ab":
            # every key of a robot's factors has a value in its own section (copies included)
            keys = {k for (r, _, ks) in f1 if r == rid for k in ks}
            assert keys <= after["values"][section][rid].keys()
            own = {k for k in after["values"][section][rid] if k >> 56 == ord(rid)}
            for k in own:
                assert _same_pose(after["values"][section][rid][k], before["values"][section][rid][k], 1e-15)


def test_the_studios_export_was_unreadable_by_jrl_before_robot_ids_were_numbers(cosmo):
    doc = json.loads(cosmo["back"].read_text())
    assert doc["robots"] == [97, 98]
    with pytest.raises(TypeError, match="302"):
        jrl_parse(dict(doc, robots=["a", "b"]))


def test_a_second_round_trip_keeps_every_factor_at_its_factor_id(cosmo, tmp_path):
    """The studio's own export converted and exported again: every FactorId names the same factor,
    values bit for bit; covariances pass through information and back (not bit for bit)."""
    res = _run("convert", "jrl", cosmo["back"], "-o", tmp_path / "ds2", "--no-rrd")
    assert res.exit_code == 0, res.output
    res = _run("export", tmp_path / "ds2", "--format", "jrl", "-o", tmp_path / "again.jrl", "--name", "ds")
    assert res.exit_code == 0, res.output
    first = jrl_parse(json.loads(cosmo["back"].read_text()))
    second = jrl_parse(json.loads((tmp_path / "again.jrl").read_text()))
    assert second["factors"].keys() == first["factors"].keys()
    assert second["labels"] == first["labels"]
    for fid, (tag, stamp, keys, value, cov) in first["factors"].items():
        tag2, stamp2, keys2, value2, cov2 = second["factors"][fid]
        assert (tag2, stamp2, keys2) == (tag, stamp, keys)
        assert _same_pose(value2, value, 0.0)
        np.testing.assert_allclose(cov2, cov, rtol=1e-12, atol=1e-15 * np.abs(cov).max())


def test_formats_without_priors_say_they_leave_them_out(cosmo, tmp_path):
    res = _run("export", cosmo["ds"], "--format", "symbols", "-o", tmp_path / "sym")
    assert res.exit_code == 0, res.output
    assert "symbols: the 2 pose priors (priors.txt) are left out" in res.output
    meta = json.loads((tmp_path / "sym" / "export.json").read_text())
    assert any("pose priors" in w for w in meta["warnings"])


# ------------------------------------------------------------------------------------ bad input


def _bad(doc: dict) -> dict:
    return json.loads(json.dumps(doc))


def _unknown_robot(doc: dict) -> dict:
    bad = _bad(doc)
    bad["measurements"]["a"][2]["measurements"][0]["key2"] = key("z", 2)
    return bad


def _prior_on_missing_key(doc: dict) -> dict:
    bad = _bad(doc)
    bad["measurements"]["b"][0]["measurements"][0]["key"] = key("b", 40)
    return bad


def _factor_id_out_of_range(doc: dict) -> dict:
    bad = _bad(doc)
    bad["outlier_factors"]["a"].append([7, 5])
    return bad


def _potential_entry_out_of_range(doc: dict) -> dict:
    bad = _bad(doc)
    bad["potential_outlier_factors"]["b"] = [[8, 0]]
    return bad


def _quaternion_off_unit(doc: dict) -> dict:
    bad = _bad(doc)
    bad["groundtruth"]["b"][1]["rotation"] = [x * 1.001 for x in bad["groundtruth"]["b"][1]["rotation"]]
    return bad


def _number_beyond_a_double(doc: dict) -> dict:
    """Found by mutating the stand-in: an integer literal past a double was an OverflowError."""
    bad = _bad(doc)
    bad["measurements"]["a"][1]["measurements"][0]["covariance"][0] = 10**400
    return bad


def _robot_id_not_a_char(doc: dict) -> dict:
    return dict(_bad(doc), robots=[97, "bb"])


@pytest.mark.parametrize(
    ("change", "place", "needle"),
    [
        (_unknown_robot, "measurements.a[2].measurements[0].key2", "names no robot"),
        (_prior_on_missing_key, "measurements.b[0].measurements[0].key", "a prior on pose 40 of 'b'"),
        (_factor_id_out_of_range, "outlier_factors.a[1]", "FactorId [7, 5] is out of range"),
        (_potential_entry_out_of_range, "potential_outlier_factors.b[0]", "measurements.b has 8 entries"),
        (_quaternion_off_unit, "groundtruth.b[1].rotation", "not unit length"),
        (_robot_id_not_a_char, "robots[1]", "expected a robot id"),
        (_number_beyond_a_double, "measurements.a[1].measurements[0].covariance[0]", "beyond a double"),
    ],
)
def test_bad_jrl_is_one_line_naming_the_file_and_json_path(cosmo, tmp_path, change, place, needle):
    src = write_cosmo_jrl(tmp_path / "bad.jrl", change(cosmo["doc"]))
    out = tmp_path / "ds"
    res = _run("convert", "jrl", src, "-o", out, "--no-rrd")
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert "bad.jrl" in lines[0] and place in lines[0] and needle in lines[0], lines[0]
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".studio-staging")]


def test_export_of_a_dataset_with_a_bad_priors_file_writes_nothing(cosmo, tmp_path):
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(cosmo["ds"], ds)
    text = (ds / "priors.txt").read_text().replace("\n2 0 ", "\n2 99 ")
    (ds / "priors.txt").write_text(text)
    res = _run("export", ds, "--format", "jrl", "-o", tmp_path / "x.jrl")
    assert res.exit_code == 2, res.output
    assert "priors.txt" in res.output and "vertex 99" in res.output
    assert not (tmp_path / "x.jrl").exists()


def test_a_planar_prior_round_trips_with_its_dense_covariance(tmp_path):
    cov = np.array([[0.04, 0.01, 0.002], [0.01, 0.09, -0.003], [0.002, -0.003, 0.01]])
    odo = {"type": "Pose2", "x": 1.0, "y": 0.0, "theta": 0.1}
    doc = {
        "name": "planar",
        "robots": [97],
        "measurements": {
            "a": [
                {
                    "stamp": 10,
                    "measurements": [
                        {
                            "type": "PriorFactorPose2",
                            "key": key("a", 0),
                            "prior": {"type": "Pose2", "x": 0.5, "y": -0.25, "theta": 0.3},
                            "covariance": cov.flatten(order="F").tolist(),
                        }
                    ],
                },
                *(
                    {
                        "stamp": 10 + k,
                        "measurements": [
                            {
                                "type": "BetweenFactorPose2",
                                "key1": key("a", k - 1),
                                "key2": key("a", k),
                                "measurement": odo,
                                "covariance": np.eye(3).flatten().tolist(),
                            }
                        ],
                    }
                    for k in (1, 2)
                ),
            ]
        },
    }
    src = write_cosmo_jrl(tmp_path / "planar.jrl", doc)
    assert _run("convert", "jrl", src, "-o", tmp_path / "ds", "--no-rrd").exit_code == 0
    graph = read_multi_g2o(tmp_path / "ds")
    priors = read_priors_txt(tmp_path / "ds" / "priors.txt", graph)
    assert priors.poses.tolist() == [[0.5, -0.25, 0.3]]
    info = np.linalg.inv(cov)
    np.testing.assert_allclose(priors.information_upper[0], info[np.triu_indices(3)], rtol=1e-12)
    res = _run("export", tmp_path / "ds", "--format", "jrl", "-o", tmp_path / "back.jrl")
    assert res.exit_code == 0, res.output
    back = json.loads((tmp_path / "back.jrl").read_text())
    first = back["measurements"]["a"][0]["measurements"][0]
    assert first["type"] == "PriorFactorPose2" and first["key"] == key("a", 0)
    assert first["prior"] == {"type": "Pose2", "x": 0.5, "y": -0.25, "theta": 0.3}
    np.testing.assert_allclose(np.array(first["covariance"]).reshape(3, 3, order="F"), cov, rtol=1e-12)


# ------------------------------------------------------------------------------------ real files


def _real_jrl_files() -> list[Path]:
    root = os.environ.get("STUDIO_REAL_DATA")
    return sorted(Path(root).rglob("*.jrl")) if root else []


@pytest.mark.skipif(not os.environ.get("STUDIO_REAL_DATA"), reason="STUDIO_REAL_DATA names no real data folder")
def test_real_jrl_files_convert_and_come_back_as_jrl_wrote_them(tmp_path):
    """Every ``*.jrl`` under ``$STUDIO_REAL_DATA`` (COSMO-Bench's, MESA's) converts; its counts are
    the file's own (robots, between factors by class, priors, labels); the export reads back, by
    jrl's parsing rules, as the same factors, priors and labels."""
    files = _real_jrl_files()
    if not files:
        pytest.skip(f"no *.jrl file under {os.environ['STUDIO_REAL_DATA']}")
    for n, src in enumerate(files):
        doc = json.loads(src.read_text())
        before = jrl_parse(doc)
        ds, back = tmp_path / f"ds{n}", tmp_path / f"back{n}.jrl"
        res = _run("convert", "jrl", src, "-o", ds, "--no-rrd")
        assert res.exit_code == 0, f"{src}: {res.output}"
        between = [v for v in before["factors"].values() if v[0] == "BetweenFactorPose3"]
        inter = sum(1 for v in between if v[2][0] >> 56 != v[2][1] >> 56)
        counts = json.loads((ds / "import.json").read_text())["counts"]
        assert counts["inter_loop_closures"] == inter, src
        assert counts["odometry"] + counts["intra_loop_closures"] == len(between) - inter, src
        assert counts.get("priors", 0) == len(before["factors"]) - len(between), src
        assert counts["outliers"] == len(_labelled(before, "outlier_factors")), src
        res = _run("export", ds, "--format", "jrl", "-o", back)
        assert res.exit_code == 0, f"{src}: {res.output}"
        after = jrl_parse(json.loads(back.read_text()))
        assert _by_identity(after).keys() == _by_identity(before).keys(), src
        for section in ("potential_outlier_factors", "outlier_factors"):
            if section in before["labels"]:
                assert _labelled(after, section) == _labelled(before, section), src
