"""What the real MR.CLAM files do (datasets 6 and 7 as public repositories carry them, read outside
the project; docs/converters.md), each reproduced in files the tests write in the shipped layout:

* columns right-aligned, each followed by a space, joined by tabs, a space at every line's end;
* the ground truth at about 60 Hz (median step 16 ms) with gaps, one of them 2 s long;
* odometry at about 100 Hz (median step 10 ms), repeated stamps, starting 12-16 s after the ground
  truth and, for one robot, running two minutes past the end of its ground truth (and so do its
  measurements);
* the robots turn 0.15-0.2 s after their angular velocity commands;
* barcodes read that no subject carries (43, 34, 50).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from studio.converters import mrclam
from studio.converters.mrclam import command_lag_ns, read_mrclam, read_mrclam_odometry
from tests.converters.mrclam_files import write_mrclam_dataset
from tests.converters.test_mrclam import run


def _body_rows(path: Path) -> tuple[list[str], list[str]]:
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    head = [x for x in lines if x.startswith("#")]
    return head, [x for x in lines if not x.startswith("#")]


def test_the_real_files_column_layout_reads_as_tab_separated_columns(tmp_path):
    tabs = write_mrclam_dataset(tmp_path / "tabs" / "MRCLAM_Dataset1", seconds=20.0, seed=1)
    padded = write_mrclam_dataset(tmp_path / "padded" / "MRCLAM_Dataset1", seconds=20.0, seed=1, padded=True)
    line = _body_rows(padded / "Robot1_Groundtruth.dat")[1][0]
    assert " \t " in line and line.endswith(" \n") and len(_body_rows(padded / "Robot1_Groundtruth.dat")[0]) == 4
    crlf = tmp_path / "crlf" / "MRCLAM_Dataset1"
    crlf.mkdir(parents=True)
    for f in padded.iterdir():  # and Windows line ends, in case a copy has them
        (crlf / f.name).write_bytes(f.read_bytes().replace(b"\n", b"\r\n"))
    outs = []
    for name, root in (("tabs", tabs), ("padded", padded), ("crlf", crlf)):
        res = run("mrclam", root, "-o", tmp_path / f"out_{name}", "--planar", "--odometry", "real", "--no-rrd")
        assert res.exit_code == 0, res.output
        outs.append(tmp_path / f"out_{name}")
    for f in ("agent1/posegraph.g2o", "agent3/agent3_GT.tum", "inter_agent_lc.dat", "range_bearing.txt"):
        assert (outs[0] / f).read_bytes() == (outs[1] / f).read_bytes() == (outs[2] / f).read_bytes(), f


def test_the_lag_of_the_motion_behind_the_commands_is_estimated_and_removed(tmp_path, monkeypatch):
    lagged = write_mrclam_dataset(tmp_path / "lag" / "MRCLAM_Dataset1", seconds=60.0, seed=2, lag_s=0.2)
    prompt = write_mrclam_dataset(tmp_path / "nolag" / "MRCLAM_Dataset1", seconds=60.0, seed=2)
    for root, lag in ((lagged, 0.2), (prompt, 0.0)):
        gt = read_mrclam([root])
        odo = read_mrclam_odometry([root], gt)
        for t in gt:
            rows = np.loadtxt(root / f"{t.name}_Odometry.dat", comments="#")
            got = command_lag_ns(np.round(rows[:, 0] * 1e6).astype(np.int64) * 1000, rows[:, 2], t) / 1e9
            assert abs(got - lag) <= 0.02, (t.name, got)
            assert f"commands shifted by {got:+.2f} s" in (odo[t.name].source or "")
    # the shift is what makes the real odometry's rotations fit: read as stamped (no shift), the
    # rotation errors of the lagged robots are larger
    res = run("mrclam", lagged, "-o", tmp_path / "out", "--planar", "--odometry", "real", "--no-rrd")
    assert res.exit_code == 0, res.output
    fits = json.loads((tmp_path / "out" / "report.json").read_text())["odometry"]["fits"]
    monkeypatch.setattr(mrclam, "command_lag_ns", lambda *a: 0)
    res = run("mrclam", lagged, "-o", tmp_path / "as_stamped", "--planar", "--odometry", "real", "--no-rrd")
    assert res.exit_code == 0, res.output
    as_stamped = json.loads((tmp_path / "as_stamped" / "report.json").read_text())["odometry"]["fits"]
    ratios = [f0["rms_rotation_rad"] / f["rms_rotation_rad"] for f, f0 in zip(fits, as_stamped)]
    assert min(ratios) > 1.1, ratios


def _rewrite(path: Path, keep) -> None:
    head, rows = _body_rows(path)
    path.write_text("".join(head) + "".join(r for r in rows if keep(float(r.split()[0]))), encoding="utf-8")


@pytest.fixture(scope="module")
def quirky(tmp_path_factory) -> tuple[Path, Path, str]:
    root = write_mrclam_dataset(
        tmp_path_factory.mktemp("q") / "MRCLAM_Dataset6", seconds=60.0, seed=4, lag_s=0.15, padded=True
    )
    t0 = float(_body_rows(root / "Robot1_Groundtruth.dat")[1][0].split()[0])
    # Robot1's ground truth ends at 40 s; its odometry and measurements run on to 60 s
    _rewrite(root / "Robot1_Groundtruth.dat", lambda t: t < t0 + 40.0)
    # Robot4's ground truth loses 2 s (Vicon out of view)
    _rewrite(root / "Robot4_Groundtruth.dat", lambda t: not t0 + 20.0 < t < t0 + 22.03)
    # the ground truth starts 12 s before the odometry (the robots stand still), at 60 Hz
    for k in range(1, 6):
        head, rows = _body_rows(root / f"Robot{k}_Groundtruth.dat")
        first = rows[0].split()
        still = [f"{t0 - 12.0 + i / 60:.3f} \t {first[1]} \t {first[2]} \t {first[3]} \n" for i in range(720)]
        (root / f"Robot{k}_Groundtruth.dat").write_text("".join(head + still + rows), encoding="utf-8")
    # and the odometry repeats stamps
    head, rows = _body_rows(root / "Robot2_Odometry.dat")
    doubled = [r for i, r in enumerate(rows) for _ in range(2 if i % 50 == 0 else 1)]
    (root / "Robot2_Odometry.dat").write_text("".join(head) + "".join(doubled), encoding="utf-8")
    # barcodes nobody carries, as the real files have (43, 34, 50)
    head, rows = _body_rows(root / "Robot3_Measurement.dat")
    extra = [f"{t0 + 30.0 + i:.3f} \t {code} \t 2.0000 \t 0.1000 \n" for i, code in enumerate((43, 34, 50))]
    body = sorted(rows + extra, key=lambda r: float(r.split()[0]))
    (root / "Robot3_Measurement.dat").write_text("".join(head) + "".join(body), encoding="utf-8")
    out = root.parent / "out"
    res = run("mrclam", root, "-o", out, "--planar", "--odometry", "real", "--no-rrd")
    assert res.exit_code == 0, res.output
    return root, out, res.output


def test_a_ground_truth_ending_early_keeps_the_robot_to_its_span(quirky):
    root, out, output = quirky
    report = json.loads((out / "report.json").read_text())
    r1 = next(a for a in report["agents"] if a["name"] == "Robot1")
    assert r1["last_stamp_ns"] - r1["first_stamp_ns"] < 52.0e9  # 12 s standing, then 40 s
    # sightings by or of Robot1 after its ground truth ended cannot be tied to it: dropped, counted
    assert report["range_bearing"]["dropped_outside_time_span"] > 0
    assert "outside the ground truth dropped" in output


def test_a_ground_truth_gap_is_bridged_and_reported(quirky):
    _, out, output = quirky
    gaps = json.loads((out / "report.json").read_text())["gaps"]
    assert [g["agent"] for g in gaps] == ["Robot4"] and 2.0 < gaps[0]["seconds"] < 2.1
    assert "gap: Robot4" in output


def test_late_and_repeated_odometry_stamps_are_integrated(quirky):
    _, out, _ = quirky
    fits = json.loads((out / "report.json").read_text())["odometry"]["fits"]
    assert [f["agent"] for f in fits] == [f"Robot{k}" for k in range(1, 6)]
    assert all(f["drift_m_per_m"] < 0.2 and f["rms_rotation_rad"] < 0.1 for f in fits), fits
    assert all("commands shifted by +0.1" in f["source"] for f in fits)  # the 0.15 s lag, found


def test_misread_barcodes_are_counted_and_warned(quirky):
    _, out, output = quirky
    report = json.loads((out / "report.json").read_text())
    assert report["range_bearing"]["source_counts"]["unknown_barcodes"] == 5 + 3  # the writer's 99s too
    assert "8 measurements of barcodes not in Barcodes.dat left out" in output


def test_a_negative_range_names_its_file_and_line_and_writes_nothing(tmp_path):
    root = write_mrclam_dataset(tmp_path / "MRCLAM_Dataset1", seconds=10.0, seed=1, padded=True)
    path = root / "Robot2_Measurement.dat"
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    k = next(i for i, x in enumerate(lines) if not x.startswith("#")) + 2  # the third data row
    parts = lines[k].split()
    lines[k] = f"{parts[0]} \t {parts[1]} \t -1.2500 \t {parts[3]} \n"
    path.write_text("".join(lines), encoding="utf-8")
    res = run("mrclam", root, "-o", tmp_path / "out", "--no-rrd")
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [f"error: {path}:{k + 1}: a negative range (-1.25 m)"]
    assert not (tmp_path / "out").exists()
