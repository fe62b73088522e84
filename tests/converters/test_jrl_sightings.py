"""JRL's ``BearingRangeFactorPose2`` read back: ``studio convert mrclam --planar`` -> ``studio export
--format jrl`` -> ``studio convert jrl`` gives the sightings table the converter made, on MR.CLAM-layout
files the tests write (tests/converters/mrclam_files.py); bad factors are one line naming the JSON
path, exit 2, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.check import check
from studio.cli import app
from studio.export import export_dataset
from studio.io.jrl import read_jrl
from studio.io.multig2o import read_multi_g2o
from studio.io.range_bearing import read_range_bearing
from tests.converters.mrclam_files import write_mrclam_dataset

runner = CliRunner()
_FAST = ("--lc-prob-intra", "0", "--lc-prob-inter", "0", "--no-rrd")
_COLUMNS = (
    "stamps_ns",
    "observer_agent",
    "observer_index",
    "observed_agent",
    "observed_index",
    "range_m",
    "bearing_rad",
    "sigma_range_m",
    "sigma_bearing_rad",
    "observer_offset_ns",
    "observed_offset_ns",
)


def _run(*args):
    return runner.invoke(app, [*map(str, args)])


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    """A planar MR.CLAM conversion at the default keyframes (sightings seconds from their keyframes)."""
    root = tmp_path_factory.mktemp("jrls")
    folder = write_mrclam_dataset(root / "MRCLAM_Dataset1", seconds=40.0, seed=7)
    res = _run("convert", "mrclam", folder, "-o", root / "planar", "--planar", *_FAST)
    assert res.exit_code == 0, res.output
    return root / "planar"


@pytest.fixture(scope="module")
def exported(converted) -> dict:
    target = converted.parent / "planar.jrl"
    export_dataset(converted, target, format="jrl")
    return json.loads(target.read_text())


def _write(path: Path, doc: dict) -> Path:
    path.write_text(json.dumps(doc))
    return path


def _factor_places(doc: dict) -> list[tuple[str, int, int]]:
    return [
        (c, e, m)
        for c, entries in doc["measurements"].items()
        for e, entry in enumerate(entries)
        for m, f in enumerate(entry["measurements"])
        if f["type"] == "BearingRangeFactorPose2"
    ]


def test_export_then_import_gives_the_converters_sightings_back(converted, exported, tmp_path):
    out = tmp_path / "back"
    res = _run("convert", "jrl", converted.parent / "planar.jrl", "-o", out, "--no-rrd")
    assert res.exit_code == 0, res.output
    src = read_range_bearing(converted / "range_bearing.txt", read_multi_g2o(converted))
    got = read_range_bearing(out / "range_bearing.txt", read_multi_g2o(out))
    assert len(src) > 50 and np.abs(src.observer_offset_ns).max() > 0  # sightings away from their keyframes
    for name in _COLUMNS:
        assert np.array_equal(getattr(got, name), getattr(src, name)), name
    # the file itself too: the same bytes as the converter wrote
    assert (out / "range_bearing.txt").read_bytes() == (converted / "range_bearing.txt").read_bytes()
    meta = json.loads((out / "import.json").read_text())
    assert meta["counts"]["range_bearing"] == len(src) and not meta["warnings"]
    assert f", {len(src)} range-bearing sightings from jrl" in res.output
    # and studio check finds the same range-bearing residuals on the imported dataset
    a, b = check(converted).range_bearing, check(out).range_bearing
    assert a is not None and b is not None and a.chi2_per_dof == pytest.approx(b.chi2_per_dof, rel=1e-12)


def test_the_imported_recording_logs_the_sightings_as_the_converted_datasets_does(converted, exported, tmp_path):
    from studio.recording.rrd_checks import fingerprint_rrd

    out = tmp_path / "rec"
    assert _run("convert", "jrl", converted.parent / "planar.jrl", "-o", out).exit_code == 0
    res = _run("record", converted, "-o", tmp_path / "converted.rrd")
    assert res.exit_code == 0, res.output
    got, want = fingerprint_rrd(out / "rec.rrd"), fingerprint_rrd(tmp_path / "converted.rrd")
    sightings = {k: v for k, v in want.items() if "sightings" in k}
    assert any("Robot1/sightings" in k for k in sightings)
    assert {k: v for k, v in got.items() if "sightings" in k} == sightings


def test_a_second_export_of_the_imported_dataset_writes_the_same_factors(converted, exported, tmp_path):
    out = tmp_path / "back"
    assert _run("convert", "jrl", converted.parent / "planar.jrl", "-o", out, "--no-rrd").exit_code == 0
    export_dataset(out, tmp_path / "again.jrl", format="jrl")
    again = json.loads((tmp_path / "again.jrl").read_text())
    assert again["measurements"] == exported["measurements"]


def test_the_format_documents_bare_numbers_and_a_correlation_is_dropped_with_a_warning(exported, tmp_path):
    """``format/VALUE_FORMAT.md`` lists ``bearing`` and ``range`` as doubles while jrl's parser reads
    a ``Rot2`` and a ``Scalar``: both spellings read the same. A covariance with a bearing-range
    correlation keeps its two variances and says so once."""
    doc = json.loads(json.dumps(exported))
    places = _factor_places(doc)
    for c, e, m in places[:5]:
        f = doc["measurements"][c][e]["measurements"][m]
        f["measurement"] = {
            "bearing": f["measurement"]["bearing"]["theta"],
            "range": f["measurement"]["range"]["value"],
        }
    for c, e, m in places[5:8]:
        cov = doc["measurements"][c][e]["measurements"][m]["covariance"]
        cov[1] = cov[2] = 0.1 * np.sqrt(cov[0] * cov[3])
    warnings: list[str] = []
    got = read_jrl(_write(tmp_path / "bare.jrl", doc), warn=warnings.append).range_bearing
    want = read_jrl(_write(tmp_path / "ok.jrl", exported)).range_bearing
    assert got is not None and want is not None
    for name in _COLUMNS:
        assert np.array_equal(getattr(got, name), getattr(want, name)), name
    assert warnings == [
        f"{tmp_path / 'bare.jrl'}: 3 BearingRangeFactorPose2 covariances correlate bearing and range; "
        "the sightings keep their two standard deviations only"
    ]


def test_other_bearing_range_kinds_are_still_counted_and_skipped(exported, tmp_path):
    doc = json.loads(json.dumps(exported))
    c, e, m = _factor_places(doc)[0]
    doc["measurements"][c][e]["measurements"][m]["type"] = "BearingRangeFactor2D"
    warnings: list[str] = []
    got = read_jrl(_write(tmp_path / "l.jrl", doc), warn=warnings.append)
    assert got.skipped == {"BearingRangeFactor2D": 1}
    assert got.range_bearing is not None and len(got.range_bearing) == len(_factor_places(exported)) - 1
    assert any("1 BearingRangeFactor2D" in w for w in warnings)


def test_a_file_without_sightings_has_none(converted, exported, tmp_path):
    doc = json.loads((converted.parent / "planar.jrl").read_text())
    for entries in doc["measurements"].values():
        for entry in entries:
            entry["measurements"] = [f for f in entry["measurements"] if f["type"] != "BearingRangeFactorPose2"]
    out = tmp_path / "none"
    res = _run("convert", "jrl", _write(tmp_path / "n.jrl", doc), "-o", out, "--no-rrd")
    assert res.exit_code == 0, res.output
    assert not (out / "range_bearing.txt").exists() and "range-bearing" not in res.output
    assert "range_bearing" not in json.loads((out / "import.json").read_text())["counts"]


def _broken(doc: dict, change) -> tuple[dict, str]:
    bad = json.loads(json.dumps(doc))
    c, e, m = _factor_places(bad)[0]  # the first: a Pose3 graph is named at its first sighting
    change(bad["measurements"][c][e]["measurements"][m], bad)
    return bad, f"measurements.{c}[{e}].measurements[{m}]"


def _set(key, value):
    def change(f, doc):
        f[key] = value

    return change


def _measurement(part, value):
    def change(f, doc):
        f["measurement"][part] = value

    return change


def _to_pose3(f, doc):
    for entries in doc["measurements"].values():
        for entry in entries:
            for g in entry["measurements"]:
                if g["type"] == "BetweenFactorPose2":
                    z = g["measurement"]
                    g["type"] = "BetweenFactorPose3"
                    g["measurement"] = {"translation": [z["x"], z["y"], 0.0], "rotation": [1.0, 0.0, 0.0, 0.0]}
                    g["covariance"] = np.eye(6).ravel().tolist()
    for section in ("groundtruth", "initialization"):
        for values in doc[section].values():
            for v in values:
                x, y = v.pop("x"), v.pop("y")
                v.pop("theta")
                v.update(type="Pose3", translation=[x, y, 0.0], rotation=[1.0, 0.0, 0.0, 0.0])


def _same_robot(f, doc):
    f["key2"] = f["key1"] + 1


def _no_such_pose(f, doc):
    f["key2"] = (f["key2"] >> 56 << 56) + 10**9


@pytest.mark.parametrize(
    "change, place, needle",
    [
        (_measurement("range", {"type": "Scalar", "value": -0.5}), ".measurement.range", "cannot be negative"),
        (_measurement("bearing", {"type": "Rot2"}), ".measurement.bearing", "missing key 'theta'"),
        (_measurement("range", "far"), ".measurement.range", "expected a number"),
        (_set("covariance", [1.0, 0.0, 0.0]), ".covariance", "expected a list of 4 numbers"),
        (_set("covariance", [1.0, 2.0, 2.0, 1.0]), ".covariance", "not a symmetric positive definite 2x2"),
        (_set("covariance", [1.0, 0.5, 0.0, 1.0]), ".covariance", "not a symmetric positive definite 2x2"),
        (_set("key2", (ord("q") << 56) + 3), ".key2", "names no robot"),
        (_no_such_pose, ".key2", "is in no values or pose-graph measurement"),
        (_same_robot, "", "a robot does not sight itself"),
        (_to_pose3, "", "BearingRangeFactorPose2 in a graph of BetweenFactorPose3 measurements"),
    ],
)
def test_bad_bearing_range_factors_fail_in_one_line_naming_the_json_path(exported, tmp_path, change, place, needle):
    bad, path = _broken(exported, change)
    out = tmp_path / "o"
    res = _run("convert", "jrl", _write(tmp_path / "bad.jrl", bad), "-o", out, "--no-rrd")
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.output, res.output
    assert f"bad.jrl: {path}{place}: " in lines[0] and needle in lines[0], lines[0]
    assert not out.exists() and not list(tmp_path.glob(".studio-staging-*"))


def test_a_skipped_factor_before_an_error_is_still_one_line(exported, tmp_path):
    """A reader warns of the factors it skips as it meets them; when it then fails, the command
    prints the error alone (the CLI holds a command's warnings until it ends)."""
    doc = json.loads(json.dumps(exported))
    places = _factor_places(doc)
    c, e, m = places[0]
    doc["measurements"][c][e]["measurements"][m]["type"] = "BearingRangeFactor2D"  # skipped, warned
    robot = next(iter(doc["groundtruth"]))
    x = doc["groundtruth"][robot][0]["x"]
    doc["groundtruth"][robot][0]["x"] = "far"  # read after the factors (and their warning)
    out = tmp_path / "o"
    res = _run("convert", "jrl", _write(tmp_path / "both.jrl", doc), "-o", out, "--no-rrd")
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and f"groundtruth.{robot}[0]" in lines[0], res.output
    assert not out.exists()
    doc["groundtruth"][robot][0]["x"] = x
    res = _run("convert", "jrl", _write(tmp_path / "skip.jrl", doc), "-o", out, "--no-rrd")
    assert res.exit_code == 0, res.output
    assert "warning: " in res.output and "1 BearingRangeFactor2D" in res.output
