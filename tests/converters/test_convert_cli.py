"""`studio convert` end to end through the CLI: output, read-back, determinism, config, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.io.multig2o import read_multi_g2o
from studio.io.tum import read_tum
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory, write_tum_file

runner = CliRunner()


def run(*args):
    return runner.invoke(app, ["convert", *map(str, args)])


def folder_bytes(root: Path) -> dict[str, bytes]:
    """Every dataset file's bytes. The recording is left out: it is named after the folder and never
    byte-identical (chunk ids); its content is compared by fingerprint below and in
    tests/recording/test_committed_recordings.py."""
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file() and p.suffix != ".rrd"
    }


def rrd_fingerprint(root: Path) -> dict[str, str]:
    from studio.recording.rrd_checks import fingerprint_rrd

    # the recording's name property is the folder's name; everything else must match
    return {
        k: v
        for k, v in fingerprint_rrd(root / f"{root.name}.rrd").items()
        if not k.endswith(("RecordingInfo:name", "dataset name"))
    }


@pytest.fixture
def tum_files(tmp_path):
    files = []
    for k, name in enumerate(["alpha", "bob", "carol"]):
        s, p, q = loop_trajectory(600, centre=(UTM_EAST + 2 * k, UTM_NORTH, 50.0), phase=k, t0_s=1.6e9 + k)
        keep = np.ones(600, bool)
        if name == "carol":
            keep[200:240] = False  # a 4 s ground-truth gap
        files.append(write_tum_file(tmp_path / f"{name}.txt", s[keep], p[keep], q[keep]))
    return files


def test_tum_end_to_end_reads_back_and_keeps_real_stamps(tmp_path, tum_files):
    out = tmp_path / "ds"
    r = run("tum", *tum_files, "-o", out, "--outlier-fraction", "0.1")
    assert r.exit_code == 0, r.output
    assert "gap: carol" in r.output
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["alpha", "bob", "carol"]
    assert g.kind.value == "SE3" and len(g.inter) > 0
    # kollagen's folder names, the robots' names in agents.json
    assert (out / "agent1" / "posegraph.g2o").read_text().startswith("VERTEX_SE3:QUAT 0 ")
    agents = json.loads((out / "agents.json").read_text())["agents"]
    assert [(a["folder"], a["name"], a["source"]) for a in agents] == [
        ("agent1", "alpha", "alpha.txt"),
        ("agent2", "bob", "bob.txt"),
        ("agent3", "carol", "carol.txt"),
    ]
    # the ground truth of every keyframe carries its real (UTM-run) timestamp
    gt = read_tum(out / "agent1" / "agent1_GT.tum")
    src = read_tum(tum_files[0])
    assert np.isin(gt.stamps_ns, src.stamps_ns).all() and gt.stamps_ns[0] == src.stamps_ns[0]
    report = json.loads((out / "report.json").read_text())
    assert report["origin_xyz"] == [UTM_EAST + 10.0, UTM_NORTH, 50.0]
    assert [gap["agent"] for gap in report["gaps"]] == ["carol"] and report["gaps"][0]["seconds"] == pytest.approx(4.1)
    outliers = [ln for ln in (out / "outliers.txt").read_text().splitlines() if not ln.startswith("#")]
    assert len(outliers) == report["counts"]["outliers"] > 0
    cfg = json.loads((out / "convert.json").read_text())
    assert cfg["source"] == "tum" and cfg["seed"] == 0 and cfg["outlier_fraction"] == 0.1
    assert cfg["inputs"] == [str(p.resolve()) for p in tum_files]
    assert not list(tmp_path.glob(".studio-staging-*"))


def test_full_precision_read_back_gives_the_same_graph(tmp_path, tum_files):
    from studio.convert import ConvertConfig, convert
    from studio.core.model import graphs_equal

    res = convert(ConvertConfig("tum", tum_files), tmp_path / "ds")
    assert graphs_equal(read_multi_g2o(tmp_path / "ds"), res.build.graph)


def test_same_inputs_and_seed_give_byte_identical_output(tmp_path, tum_files):
    assert run("tum", *tum_files, "-o", tmp_path / "a", "--seed", "3", "--outlier-fraction", "0.1").exit_code == 0
    assert run("tum", *tum_files, "-o", tmp_path / "b", "--seed", "3", "--outlier-fraction", "0.1").exit_code == 0
    assert run("tum", *tum_files, "-o", tmp_path / "c", "--seed", "4", "--outlier-fraction", "0.1").exit_code == 0
    a, b, c = (folder_bytes(tmp_path / x) for x in "abc")
    assert a == b
    fa, fb = rrd_fingerprint(tmp_path / "a"), rrd_fingerprint(tmp_path / "b")
    assert len(fa) > 50 and fa == fb
    assert a["agent1/posegraph.g2o"] != c["agent1/posegraph.g2o"]


def test_config_reproduces_the_dataset_and_cli_options_win(tmp_path, tum_files):
    assert run("tum", *tum_files, "-o", tmp_path / "a", "--seed", "9", "--lc-radius", "3").exit_code == 0
    r = run("--config", tmp_path / "a" / "convert.json", "-o", tmp_path / "b")
    assert r.exit_code == 0, r.output
    assert folder_bytes(tmp_path / "a") == folder_bytes(tmp_path / "b")
    r = run("--config", tmp_path / "a" / "convert.json", "-o", tmp_path / "c", "--seed", "10")
    assert r.exit_code == 0
    cfg = json.loads((tmp_path / "c" / "convert.json").read_text())
    assert cfg["seed"] == 10 and cfg["lc_radius"] == 3.0


def test_existing_output_needs_force(tmp_path, tum_files):
    out = tmp_path / "ds"
    assert run("tum", *tum_files, "-o", out).exit_code == 0
    before = folder_bytes(out)
    r = run("tum", *tum_files[:1], "-o", out)
    assert r.exit_code == 2 and "already exists (use --force" in r.output
    assert folder_bytes(out) == before
    assert run("tum", *tum_files[:1], "-o", out, "--force").exit_code == 0
    assert [p.name for p in sorted(out.iterdir()) if p.is_dir()] == ["agent1"]


def bad(tmp_path: Path, body: str) -> Path:
    f = tmp_path / "bad.txt"
    f.write_text(body)
    return f


@pytest.mark.parametrize(
    "body, message",
    [
        ("1 0 0 0 0 0 0 1\n2 0 0 nan 0 0 0 1\n", "bad.txt:2: value is not finite"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", "bad.txt:2: expected 8 columns"),
        ("", "bad.txt: no poses"),
        ("1 0 0 0 0 0 0 1\n", "a trajectory needs at least 2"),
    ],
)
def test_bad_tum_input_is_one_line_exit_2_and_writes_nothing(tmp_path, tum_files, body, message):
    out = tmp_path / "new" / "ds"
    r = run("tum", tum_files[0], bad(tmp_path, body), "-o", out)
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0]
    assert not (tmp_path / "new").exists()


def test_unsorted_stamps_warn_with_counts(tmp_path, tum_files):
    f = bad(tmp_path, "3 3 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n")
    r = run("tum", f, "-o", tmp_path / "ds", "--keyframe-distance", "0.5")
    assert r.exit_code == 0
    assert "warning: " in r.output and "1 out-of-order timestamp sorted, 1 duplicate timestamp dropped" in r.output


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["nope", "x"],
            "cannot tell the source of nope: name it (studio convert SOURCE INPUT..., SOURCE one of "
            "tum, s3e, airmuseum, bag, euroc, kitti, kimera-multi, jrl, symbols, dpgo, g2o, mrclam)",
        ),
        (["tum", "missing.txt"], "missing.txt: no such file or folder"),
        (["tum", "{f}", "--lc-radius", "0"], "--lc-radius: must be > 0"),
        ([], "give a FORMAT"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, tum_files, args, message):
    args = [a.replace("{f}", str(tum_files[0])) for a in args]
    r = run(*args, "-o", tmp_path / "ds")
    assert r.exit_code == 2 and message in r.output
    assert not (tmp_path / "ds").exists()


def test_bad_config_keys_are_rejected_with_a_hint(tmp_path, tum_files):
    cfg = tmp_path / "c.json"
    cfg.write_text(json.dumps({"source": "tum", "inputs": [str(tum_files[0])], "lc_radiuss": 2}))
    r = run("--config", cfg, "-o", tmp_path / "ds")
    assert r.exit_code == 2 and "unknown key 'lc_radiuss' (did you mean 'lc_radius'?)" in r.output


def test_planar_writes_2d_records(tmp_path, tum_files):
    assert run("tum", *tum_files[:2], "-o", tmp_path / "ds", "--planar").exit_code == 0
    assert (tmp_path / "ds" / "agent1" / "posegraph.g2o").read_text().startswith("VERTEX_SE2 0 ")
    assert read_multi_g2o(tmp_path / "ds").kind.value == "SE2"


def test_recorder_hook_writes_inside_the_staged_dataset(tmp_path, tum_files):
    from studio.convert import ConvertConfig, convert
    from studio.core.errors import OutputError

    seen = {}

    def recorder(graph, folder):
        seen["stamps"] = graph.agents[0].stamps_ns
        assert folder.parent.name.startswith(".studio-staging-")
        (folder / "hook.bin").write_bytes(b"rrd")  # (a .rrd would be checked for its Rerun footer)

    res = convert(ConvertConfig("tum", tum_files), tmp_path / "ds", recorder=recorder)
    assert (tmp_path / "ds" / "hook.bin").read_bytes() == b"rrd"
    assert seen["stamps"][0] == res.trajectories[0].stamps_ns[0]

    def broken(graph, folder):
        raise OutputError("cannot record")

    with pytest.raises(OutputError, match="cannot record"):
        convert(ConvertConfig("tum", tum_files), tmp_path / "ds2", recorder=broken)
    assert not (tmp_path / "ds2").exists() and not list(tmp_path.glob(".studio-staging-*"))


def test_loop_closure_search_over_the_memory_limit_is_refused_before_it_starts(tmp_path, tum_files):
    r = run("tum", *tum_files, "-o", tmp_path / "a", "--lc-radius", "1000", "--max-memory-gb", "0.0001")
    assert r.exit_code == 2
    assert "keyframe pairs (about" in r.stderr and "over the 0.0001 GB limit): use a smaller --lc-radius" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "a").exists()
    assert run("tum", *tum_files, "-o", tmp_path / "b", "--lc-radius", "1000").exit_code == 0
