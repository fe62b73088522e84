"""``studio synth CONFIG --seeds FIRST..LAST``: one folder per replicate, in one process, resumable."""

from __future__ import annotations

import filecmp
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.core.errors import ConfigError
from studio.generator.config import replicate_config
from studio.io.atomic import STAGING_PREFIX
from studio.io.synth_config import synth_config_to_json
from studio.recording.rrd_checks import fingerprint_rrd
from studio.synth import load_synth_config, parse_seeds, seed_folder_name, synthesize_seeds

DATA = Path(__file__).resolve().parent.parent / "data"
CONFIG = DATA / "configs" / "tiny_single.json"
ENV = dict(os.environ, CI="true")


def _files(folder: Path) -> list[Path]:
    return sorted(p.relative_to(folder) for p in folder.rglob("*") if p.is_file() and p.name != ".studio-output")


def _same_tree(a: Path, b: Path) -> bool:
    """The same files with the same bytes; recordings (whose chunk and row ids are random) with the
    same content fingerprint."""
    files = _files(a)

    def same(f: Path) -> bool:
        if f.suffix == ".rrd":
            return fingerprint_rrd(a / f) == fingerprint_rrd(b / f)
        return filecmp.cmp(a / f, b / f, shallow=False)

    return bool(files) and files == _files(b) and all(same(f) for f in files)


def test_each_seed_folder_is_a_separate_synth_of_that_replicate(tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["synth", str(CONFIG), "-o", str(tmp_path / "batch"), "--seeds", "0..2", "-q"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "batch").iterdir()) == ["seed0000", "seed0001", "seed0002"]
    cfg = load_synth_config(CONFIG)
    for k in range(3):
        # the replicate as its own kollagen JSON file, given to a plain `studio synth`
        single = tmp_path / f"config{k}" / f"{cfg.name}.json"
        single.parent.mkdir()
        single.write_text(json.dumps(synth_config_to_json(replicate_config(cfg, k)), indent=4))
        res = runner.invoke(app, ["synth", str(single), "-o", str(tmp_path / f"alone{k}"), "-q"])
        assert res.exit_code == 0, res.output
        assert _same_tree(tmp_path / "batch" / seed_folder_name(k), tmp_path / f"alone{k}")
    # the replicates differ from one another (the seeds are really moved)
    a, b = (tmp_path / "batch" / f"seed000{k}" / cfg.name / "agent1" / "posegraph.g2o" for k in (0, 1))
    assert a.read_bytes() != b.read_bytes()


def test_a_second_run_keeps_finished_seeds_and_force_writes_them_again(tmp_path):
    cfg = load_synth_config(CONFIG)
    first = synthesize_seeds(cfg, tmp_path, [0, 1], rrd=False)
    assert first.written == (0, 1) and first.kept == ()
    g2o = tmp_path / "seed0001" / cfg.name / "agent1" / "posegraph.g2o"
    inode = g2o.stat().st_ino
    again = synthesize_seeds(cfg, tmp_path, range(3), rrd=False)
    assert again.written == (2,) and again.kept == (0, 1)
    assert g2o.stat().st_ino == inode  # kept, not written again
    forced = synthesize_seeds(cfg, tmp_path, [1], rrd=False, force=True)
    assert forced.written == (1,) and g2o.stat().st_ino != inode


def test_a_seed_folder_studio_did_not_write_is_refused(tmp_path):
    (tmp_path / "seed0000").mkdir()
    (tmp_path / "seed0000" / "mine.txt").write_text("a user's file\n")
    res = CliRunner().invoke(app, ["synth", str(CONFIG), "-o", str(tmp_path), "--seeds", "0..1", "-q"])
    assert res.exit_code == 2
    assert "seed0000" in res.output and "Traceback" not in res.output
    assert (tmp_path / "seed0000" / "mine.txt").read_text() == "a user's file\n"
    assert not (tmp_path / "seed0001").exists()


@pytest.mark.parametrize(
    ("text", "seeds"), [("0..3", [0, 1, 2, 3]), ("7", [7]), ("1,5,9", [1, 5, 9]), ("2..3, 9", [2, 3, 9])]
)
def test_seed_lists(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "3..1", "-1..2", "a..b", "1..", "0..5,3", "0..2000000"])
def test_bad_seed_lists_are_one_line_errors(text, tmp_path):
    with pytest.raises(ConfigError, match="seeds"):
        parse_seeds(text)
    res = CliRunner().invoke(app, ["synth", str(CONFIG), "-o", str(tmp_path / "o"), "--seeds", text])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
    assert not (tmp_path / "o").exists()


def test_a_killed_batch_resumes_and_ends_with_every_seed(tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "studio.cli", "synth", str(CONFIG), "-o", str(out), "--seeds", "0..199", "-q"]
    proc = subprocess.Popen(cmd, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "seed0002").exists():
            break
        time.sleep(0.005)
    assert proc.poll() is None, "the batch ended before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    finished = sorted(p.name for p in out.iterdir() if p.name.startswith("seed"))
    assert 3 <= len(finished) < 200
    g2o = out / "seed0000" / "tiny_single" / "agent1" / "posegraph.g2o"
    inode = g2o.stat().st_ino
    cmd[cmd.index("0..199")] = "0..4" if len(finished) < 5 else f"0..{len(finished) + 1}"
    last = int(cmd[cmd.index("--seeds") + 1].split("..")[1])
    done = subprocess.run(cmd, env=ENV, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    names = sorted(p.name for p in out.iterdir())
    assert not [n for n in names if n.startswith(STAGING_PREFIX)]  # the killed run's staging is gone
    assert [n for n in names if n.startswith("seed")] == sorted(
        {seed_folder_name(k) for k in range(last + 1)} | set(finished)
    )
    assert g2o.stat().st_ino == inode  # a finished seed was kept
    # every seed, kept or written after the kill, holds the same files as a fresh batch
    fresh = synthesize_seeds(load_synth_config(CONFIG), tmp_path / "fresh", range(last + 1))
    assert fresh.written == tuple(range(last + 1))
    for k in range(last + 1):
        assert _same_tree(out / seed_folder_name(k), tmp_path / "fresh" / seed_folder_name(k))
