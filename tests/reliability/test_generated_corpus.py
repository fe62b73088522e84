"""A generated hostile corpus (issue 10): every case is written by the test, run through the CLI in
process, and must give exit 2, exactly one ``error:`` line naming the file (and place), no traceback,
no warning line and nothing written."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from tests.conftest import DATA
from tests.test_hostile import _INFO, VALID_DAT, VALID_G2O, VALID_GT

runner = CliRunner()

BAD_NUMBERS = ["nan", "inf", "-inf", "1e400", "-1e400", "0x10", "1,5", "--", "", "1e200"]


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def refused(args: list, where: Path, *, names: str | None = None) -> str:
    before = _tree(where)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning would fail the case
        res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 2, (res.exit_code, res.stdout, res.stderr, res.exception)
    assert isinstance(res.exception, SystemExit), res.exception
    err = res.stderr
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "Traceback" not in err and "warning" not in err.lower() and "╭" not in err
    if names is not None:
        assert names in err, (names, err)
    assert _tree(where) == before, _tree(where) ^ before
    return err


def _dataset(root: Path, *, g2o: str = VALID_G2O, gt: str = VALID_GT, dat: str = VALID_DAT) -> Path:
    ds = root / "ds"
    for agent in ("agent1", "agent2"):
        (ds / agent).mkdir(parents=True)
        (ds / agent / "posegraph.g2o").write_text(VALID_G2O)
        (ds / agent / f"{agent}_GT.tum").write_text(VALID_GT)
    (ds / "agent1" / "posegraph.g2o").write_text(g2o)
    (ds / "agent1" / "agent1_GT.tum").write_text(gt)
    (ds / "inter_agent_lc.dat").write_text(dat)
    return ds


# --------------------------------------------------------------------------- g2o: each field of each record
_V = ["VERTEX_SE3:QUAT", "0", "0.0", "0", "0", "0", "0", "0", "1"]
_E = ["EDGE_SE3:QUAT", "0", "1", "1", "0", "0", "0", "0", "0", "1", *_INFO.split()]
G2O_CASES = []
for field in range(1, len(_V)):
    for bad in ("nan", "inf", "1e400", "x"):
        v = list(_V)
        v[field] = bad
        G2O_CASES.append(("vertex", field, bad, " ".join(v) + "\n" + VALID_G2O.split("\n", 1)[1]))
for field in (1, 3, 4, 9, 10, 11, 16, 30):
    for bad in ("nan", "inf", "x"):
        e = list(_E)
        e[field] = bad
        lines = VALID_G2O.splitlines()
        G2O_CASES.append(("edge", field, bad, "\n".join(lines[:3] + [" ".join(e)] + lines[4:]) + "\n"))


@pytest.mark.parametrize("kind,field,bad,text", G2O_CASES, ids=[f"{k}{f}-{b}" for k, f, b, _ in G2O_CASES])
def test_g2o_field(tmp_path, kind, field, bad, text):
    ds = _dataset(tmp_path, g2o=text)
    refused(["record", ds, "-o", tmp_path / "o.rrd"], tmp_path, names="posegraph.g2o")


# --------------------------------------------------------------------------- ground truth (TUM) values
TUM_CASES = [(col, bad) for col in range(8) for bad in ("nan", "inf", "1e400", "abc")]


@pytest.mark.parametrize("col,bad", TUM_CASES, ids=[f"c{c}-{b}" for c, b in TUM_CASES])
def test_tum_field_convert(tmp_path, col, bad):
    rows = [f"{i} {float(i)} 0 0 0 0 0 1".split() for i in range(4)]
    rows[1][col] = bad
    (tmp_path / "a.tum").write_text("\n".join(" ".join(r) for r in rows) + "\n")
    (tmp_path / "b.tum").write_text(VALID_GT)
    refused(["convert", "tum", tmp_path / "a.tum", tmp_path / "b.tum", "-o", tmp_path / "o"], tmp_path, names="a.tum")


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_tum_first_line_not_a_header(tmp_path, bad):
    (tmp_path / "a.tum").write_text(f"{bad} 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n")
    (tmp_path / "b.tum").write_text(VALID_GT)
    refused(["convert", "tum", tmp_path / "a.tum", tmp_path / "b.tum", "-o", tmp_path / "o"], tmp_path, names="a.tum:1")


# --------------------------------------------------------------------------- inter_agent_lc.dat
DAT_CASES = [
    "1 0 2",
    "1 0 2 1 x",
    "0 0 2 1",
    "3 0 2 1",
    "1 9 2 1",
    "1 0 2 9",
    "1 -1 2 1",
    "1 0 2 1.5",
    "1 0 2 1 nan 0 0 0 0 0 1 " + _INFO,
    "1 0 2 1 1 0 0 0 0 0 inf " + _INFO,
    "a b c d",
    "1e400 0 2 1",
]


@pytest.mark.parametrize("line", DAT_CASES)
def test_dat_line(tmp_path, line):
    ds = _dataset(tmp_path, dat=line + "\n")
    refused(["record", ds, "-o", tmp_path / "o.rrd"], tmp_path, names="inter_agent_lc.dat")


# --------------------------------------------------------------------------- synth JSON configs
def _config() -> dict:
    return json.loads((DATA / "configs" / "tiny_three.json").read_text())


SYNTH_CASES = (
    [("number_of_steps", v) for v in (-1, 0.5, "3", None, 1e300, True)]
    + [("number_of_agents", v) for v in (-1, 0, 10_001, 2.5, "x", None)]
    + [("agent_parameters.stepsize", v) for v in (-1, 0, 1e-300, "x", None, 1e300)]
    + [("agent_parameters.step_fragment", v) for v in (-1, 0, 0.5, None)]
    + [("inter_agent_loop_closure_parameters.loop_closure_radius", v) for v in (-1, "x", None, 1e300)]
)


@pytest.mark.parametrize("key,value", SYNTH_CASES, ids=[f"{k}={v}" for k, v in SYNTH_CASES])
def test_synth_config_value(tmp_path, key, value):
    cfg = _config()
    node = cfg
    *path, last = key.split(".")
    for p in path:
        node = node[p]
    node[last] = value
    (tmp_path / "c.json").write_text(json.dumps(cfg))
    refused(["synth", tmp_path / "c.json", "-o", tmp_path / "o"], tmp_path, names="c.json")


@pytest.mark.parametrize("text", ["", "{", "[]", "null", "1", '{"number_of_agents": 2}', "\ufeff{}", "{" * 5000])
def test_synth_json_malformed(tmp_path, text):
    (tmp_path / "c.json").write_text(text)
    refused(["synth", tmp_path / "c.json", "-o", tmp_path / "o"], tmp_path, names="c.json")


# --------------------------------------------------------------------------- option values
CONVERT_OPTIONS = [
    "--lc-radius",
    "--keyframe-distance",
    "--odo-sigma-m-per-m",
    "--max-gap",
    "--lc-sigma-m",
    "--max-memory-gb",
]
OPTION_CASES = [(o, v) for o in CONVERT_OPTIONS for v in ("nan", "inf", "-1", "1e-300", "1e300")]


@pytest.mark.parametrize("option,value", OPTION_CASES, ids=[f"{o}={v}" for o, v in OPTION_CASES])
def test_convert_option_value(tmp_path, option, value):
    (tmp_path / "a.tum").write_text(VALID_GT)
    (tmp_path / "b.tum").write_text(VALID_GT)
    refused(
        ["convert", "tum", tmp_path / "a.tum", tmp_path / "b.tum", "-o", tmp_path / "o", option, value],
        tmp_path,
        names=option,
    )


@pytest.mark.parametrize(
    "option,value",
    [("--max-memory-gb", v) for v in ("nan", "inf", "-1", "0", "1e300")]
    + [("--max-output-gb", v) for v in ("nan", "-1", "0")]
    + [("--jobs", "-1"), ("--jobs", "100000")],
)
def test_synth_option_value(tmp_path, option, value):
    refused(
        ["synth", DATA / "configs" / "tiny_three.json", "-o", tmp_path / "o", option, value], tmp_path, names=option
    )


# --------------------------------------------------------------------------- symlinks and special files
def _link_cases(tmp_path: Path, ds: Path) -> dict[str, Path]:
    outside = tmp_path / "outside.g2o"
    outside.write_text(VALID_G2O)
    return {
        "dangling": tmp_path / "missing.g2o",
        "outside": outside,
        "devzero": Path("/dev/zero"),
        "devnull": Path("/dev/null"),
    }


@pytest.mark.parametrize("case", ["dangling", "outside", "devzero", "devnull", "self"])
@pytest.mark.parametrize("command", ["record", "evaluate"])
def test_dataset_symlink(tmp_path, case, command):
    ds = _dataset(tmp_path)
    link = ds / "agent2" / "posegraph.g2o"
    link.unlink()
    if case == "self":
        link.symlink_to(link)
    else:
        link.symlink_to(_link_cases(tmp_path, ds)[case])
    args = ["record", ds, "-o", tmp_path / "o.rrd"] if command == "record" else ["evaluate", ds]
    refused(args, tmp_path, names="agent2/posegraph.g2o")


def test_dataset_fifo(tmp_path):
    ds = _dataset(tmp_path)
    os.mkfifo(ds / "agent2" / "agent2_GT.tum.fifo")
    refused(["record", ds, "-o", tmp_path / "o.rrd"], tmp_path, names="agent2_GT.tum.fifo")


# --------------------------------------------------------------------------- outputs that overlap inputs
def test_outputs_overlapping_inputs(tmp_path, monkeypatch):
    ds = _dataset(tmp_path)
    (tmp_path / "a.tum").write_text(VALID_GT)
    (tmp_path / "b.tum").write_text(VALID_GT)
    a, b = tmp_path / "a.tum", tmp_path / "b.tum"
    monkeypatch.chdir(tmp_path)
    cases = [
        (["convert", "tum", a, b, "-o", ".", "--force"], "current folder"),
        (["convert", "tum", a, b, "-o", "..", "--force"], ".."),
        (["convert", "tum", a, b, "-o", tmp_path, "--force"], "current folder"),
        (["record", ds, "-o", ds / "agent1" / "x.rrd"], "sits inside the input"),
        (["record", ds, "-o", "ds/x.rrd", "--force"], "sits inside the input"),
        (["evaluate", ds, "--rrd", ds, "--force"], ".rrd"),
        (["evaluate", ds, "--rrd", ds / "agent1.rrd", "--force"], "sits inside the input"),
        (["evaluate", ds, "--rrd", tmp_path / "x.txt"], ".rrd"),
        (["record", ds, "-o", tmp_path / "x.png"], ".rrd"),
    ]
    for args, match in cases:
        refused(args, tmp_path, names=match)
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "a.tum").write_text(VALID_GT)
    refused(["convert", "tum", "data/a.tum", b, "-o", "data", "--force"], tmp_path, names="contains the input")
    rrd_ds = tmp_path / "x.rrd"
    os.rename(ds, rrd_ds)
    refused(["record", rrd_ds, "-o", rrd_ds, "--force"], tmp_path, names="is the input")
    link = tmp_path / "alias"
    link.symlink_to(rrd_ds)
    refused(["record", rrd_ds, "-o", link / "r.rrd", "--force"], tmp_path, names="sits inside the input")


def test_force_never_replaces_a_folder_studio_did_not_write(tmp_path):
    (tmp_path / "a.tum").write_text(VALID_GT)
    (tmp_path / "b.tum").write_text(VALID_GT)
    mine = tmp_path / "photos"
    mine.mkdir()
    (mine / "holiday.jpg").write_text("precious")
    refused(
        ["convert", "tum", tmp_path / "a.tum", tmp_path / "b.tum", "-o", mine, "--force"],
        tmp_path,
        names="did not write",
    )
    assert (mine / "holiday.jpg").read_text() == "precious"
    ok = runner.invoke(
        app,
        ["convert", "tum", str(tmp_path / "a.tum"), str(tmp_path / "b.tum"), "-o", str(tmp_path / "ds"), "--no-rrd"],
    )
    assert ok.exit_code == 0, ok.stderr
    again = runner.invoke(
        app,
        [
            "convert",
            "tum",
            str(tmp_path / "a.tum"),
            str(tmp_path / "b.tum"),
            "-o",
            str(tmp_path / "ds"),
            "--no-rrd",
            "--force",
        ],
    )
    assert again.exit_code == 0, again.stderr  # its own earlier output is replaced


# --------------------------------------------------------------------------- snapshot and view
def test_snapshot_and_view_targets(tmp_path):
    from studio.recording.viewer import view_command, view_web_command

    ds = _dataset(tmp_path)
    rrd = tmp_path / "r.rrd"
    assert runner.invoke(app, ["record", str(ds), "-o", str(rrd)]).exit_code == 0
    (tmp_path / "pic.png").mkdir()
    (tmp_path / "old.png").write_bytes(b"old")
    (tmp_path / "trunc.rrd").write_bytes(rrd.read_bytes()[: rrd.stat().st_size // 2])
    (tmp_path / "zero.rrd").write_bytes(b"")
    (tmp_path / "junk.rrd").write_bytes(os.urandom(5000))
    for args, match in [
        (["snapshot", rrd, "-o", tmp_path / "pic.png"], "pic.png"),
        (["snapshot", rrd, "-o", tmp_path / "old.png"], "already exists"),
        (["snapshot", rrd, "-o", tmp_path / "x.jpg"], ".png"),
        (["snapshot", ds, "-o", tmp_path / "y.png"], "folder"),
        (["snapshot", tmp_path / "trunc.rrd", "-o", tmp_path / "y.png"], "trunc.rrd"),
        (["snapshot", tmp_path / "zero.rrd", "-o", tmp_path / "y.png"], "zero.rrd"),
        (["snapshot", tmp_path / "junk.rrd", "-o", tmp_path / "y.png"], "junk.rrd"),
        (["view", tmp_path / "trunc.rrd", "--web"], "trunc.rrd"),
        (["view", tmp_path / "junk.rrd", "--web"], "junk.rrd"),
    ]:
        refused(args, tmp_path, names=match)
    assert (tmp_path / "old.png").read_bytes() == b"old"
    assert "127.0.0.1" in view_web_command(rrd).command
    if os.environ.get("DISPLAY"):
        assert "127.0.0.1" in view_command(rrd)
