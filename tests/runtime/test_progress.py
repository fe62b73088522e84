"""Progress lines: drawn on a terminal (a pseudo-terminal here), a plain line every few seconds in a
pipe or a log, nothing with --quiet."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from studio.runtime.progress import plain_progress, report, terminal_progress

REPO = Path(__file__).resolve().parent.parent.parent
CONFIG = REPO / "tests" / "data" / "configs" / "tiny_three.json"
TRAJECTORIES = REPO / "tests" / "data" / "trajectories"

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE", "NO_COLOR")}
    env.update(COLUMNS="160", TERM="xterm-256color", RERUN_ANALYTICS="0")
    return env


def _in_pty(args: list[str], cwd: Path) -> tuple[int, str]:
    """Run ``python -m studio.cli ARGS`` with stdin, stdout and stderr on a pseudo-terminal."""
    leader, follower = os.openpty()
    proc = subprocess.Popen(
        [sys.executable, "-m", "studio.cli", *args],
        stdin=follower,
        stdout=follower,
        stderr=follower,
        cwd=cwd,
        env=_env(),
    )
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    text = b"".join(chunks).decode("utf-8", "replace")
    return proc.wait(timeout=120), re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)  # colours and cursor moves


def _in_pipe(args: list[str], cwd: Path, interval_s: float = 3600.0) -> subprocess.CompletedProcess:
    env = {**_env(), "STUDIO_PROGRESS_INTERVAL_S": str(interval_s)}
    return subprocess.run(
        [sys.executable, "-m", "studio.cli", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=180
    )


def test_synth_draws_progress_per_agent_and_pair_on_a_terminal(tmp_path):
    rc, out = _in_pty(["synth", str(CONFIG), "-o", "out"], tmp_path)
    assert rc == 0, out
    assert "synth: walks and intra-agent loop closures" in out
    assert re.search(r"3/3\s+agents", out)  # tiny_three: three agents
    assert re.search(r"3/3\s+pairs", out)  # and three agent pairs
    assert "agents/s" in out and "pairs/s" in out
    assert "recording" in out
    assert "tiny_three: 3 agents, 723 poses" in out


def test_synth_is_silent_in_a_pipe_before_the_first_interval(tmp_path):
    proc = _in_pipe(["synth", str(CONFIG), "-o", "out"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert "pairs" not in proc.stdout and "\x1b[" not in proc.stdout
    assert proc.stdout.startswith("tiny_three: 3 agents, 723 poses")


def test_quiet_draws_nothing_even_on_a_terminal(tmp_path):
    rc, out = _in_pty(["synth", str(CONFIG), "-o", "out", "-q"], tmp_path)
    assert rc == 0, out
    assert out == ""


def test_convert_and_record_draw_their_steps(tmp_path):
    inputs = [str(p) for p in sorted(TRAJECTORIES.glob("*.tum"))]
    rc, out = _in_pty(["convert", "tum", *inputs, "-o", "ds"], tmp_path)
    assert rc == 0, out
    for step in ("reading", "keyframes and odometry", "loop-closure search", "writing", "recording"):
        assert step in out, step
    assert re.search(rf"{len(inputs)}/{len(inputs)}\s+agents", out)
    size = sum(Path(p).stat().st_size for p in inputs)
    assert re.search(rf"{size}/{size}\s+bytes", out)
    assert "bytes/s" in out
    rc, out = _in_pty(["record", "ds", "-o", "again.rrd"], tmp_path)
    assert rc == 0, out
    assert "recording" in out and "parts/s" in out
    proc = _in_pipe(["record", "ds", "-o", "third.rrd"], tmp_path)
    assert proc.returncode == 0 and proc.stderr == ""


def test_terminal_progress_is_plain_off_a_terminal_and_none_when_disabled(capsys):
    with terminal_progress() as progress:  # pytest captures stderr: not a terminal
        assert progress is not None
        report(progress, "step", 1, 2)
    assert capsys.readouterr().err == ""  # the suite's interval (an hour) was not reached
    with terminal_progress(False) as progress:
        assert progress is None
        report(progress, "step", 1, 2)  # a None progress is a no-op


def test_plain_progress_prints_the_latest_step_every_interval():
    log = io.StringIO()
    with plain_progress(log, 0.05) as progress:
        time.sleep(0.12)  # nothing reported yet: no line
        assert log.getvalue() == ""
        progress("bench cells", 3, 16, "cells")
        time.sleep(0.2)
        progress("writing", 7, 0, "")
        time.sleep(0.2)
    lines = log.getvalue().splitlines()
    assert len(lines) >= 4, lines
    assert re.fullmatch(r"progress: bench cells 3/16 cells, 0s", lines[0]), lines
    assert re.fullmatch(r"progress: writing 7, 0s", lines[-1]), lines  # no total: the count alone
    assert "\r" not in log.getvalue() and "\x1b" not in log.getvalue()
    count = len(lines)
    time.sleep(0.15)
    assert len(log.getvalue().splitlines()) == count  # the timer ended with the block


@pytest.mark.parametrize(
    "args",
    [
        ["synth", str(CONFIG), "-o", "out"],
        ["convert", "tum", *[str(p) for p in sorted(TRAJECTORIES.glob("*.tum"))], "-o", "out"],
    ],
    ids=["synth", "convert"],
)
def test_long_jobs_print_plain_progress_lines_in_a_pipe(tmp_path, args):
    proc = _in_pipe(args, tmp_path, interval_s=0.02)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert lines, "no progress line in the pipe"
    assert all(re.fullmatch(r"progress: .+ \d+(/\d+)?( \w+)?, \d+s", line) for line in lines), lines
    assert "\x1b" not in proc.stderr and "\r" not in proc.stderr
    assert proc.stdout.strip()  # the summary still goes to stdout
    rc = _in_pipe([*args[:-1], "again", "-q"], tmp_path, interval_s=0.02)
    assert rc.returncode == 0 and rc.stderr == ""  # --quiet: nothing at all


def test_a_command_in_a_pipe_does_not_load_rich(tmp_path):
    code = (
        "import sys\n"
        "from studio.runtime.progress import terminal_progress\n"
        "with terminal_progress() as p:\n"
        "    seen = (p is None, 'rich' in sys.modules)\n"
        "open('seen.txt', 'w').write(repr(seen))\n"
    )
    env = {k: v for k, v in _env().items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE")}

    def seen(extra: dict[str, str]) -> str:
        proc = subprocess.run(
            [sys.executable, "-c", code], cwd=tmp_path, env={**env, **extra}, capture_output=True, text=True, timeout=60
        )
        assert proc.returncode == 0, proc.stderr
        return (tmp_path / "seen.txt").read_text()

    assert seen({}) == "(False, False)"  # plain lines only, and rich never loaded
    assert seen({"FORCE_COLOR": "1"}) == "(False, True)"  # rich draws when told to


def test_replay_prints_its_checkpoints_in_a_pipe(tmp_path):
    assert _in_pipe(["synth", str(CONFIG), "-o", "out", "--no-rrd", "-q"], tmp_path).returncode == 0
    proc = _in_pipe(["replay", "out/tiny_three", "-o", "rp", "-b", "centralized"], tmp_path, interval_s=0.02)
    assert proc.returncode == 0, proc.stderr
    assert re.search(r"^progress: replay centralized \d/6 checkpoints, \d+s$", proc.stderr, re.M), proc.stderr


def test_the_readme_states_the_rule_for_pipes_the_code_follows():
    """The README once said nothing is printed in pipes while a plain line came every 5 s."""
    from studio.runtime.progress import PLAIN_INTERVAL_S

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    text = " ".join(readme.split())
    assert "nothing in pipes" not in text
    said = re.search(r"in a pipe or a log, one plain line every (\d+) s", text)
    assert said is not None and float(said.group(1)) == PLAIN_INTERVAL_S
    assert "STUDIO_PROGRESS_INTERVAL_S" in text
