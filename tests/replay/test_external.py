"""``studio replay -b command:PROGRAM``: a back-end in another process speaking the protocol as JSON
lines (issue 38). A small Python script stands in for a C++ or ROS 2 program: it replays tiny_three
exactly as its in-process twin does, and its crash, hang, garbage and wrong counts each end the run
with one line naming the back-end, exit 2, nothing written."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.core.comms import robot_pairs
from studio.core.errors import ConfigError
from studio.replay import replay
from studio.replay.protocol import Checkpoint, KeptPoses, Setup, Step
from studio.replay.registry import BACKENDS, get_backend, output_name
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"
PROGRAM = Path(__file__).resolve().parent / "programs" / "echo_backend.py"
COMMAND = f"command:{sys.executable} {PROGRAM}"
runner = CliRunner()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("external")
    return synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), root, rrd=False, jobs=1).dataset_dir


class EchoTwin:
    """What programs/echo_backend.py does, in-process: own poses as first given; per delivered
    closure whose other end was given, its robot keeps that pose, one message of one pose."""

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        self.own = setup.problem.initial.copy()
        self.given = np.zeros(setup.problem.num_vertices, dtype=bool)
        self.kept: dict[tuple[int, int], np.ndarray] = {}
        pairs = robot_pairs(setup.num_robots).tolist()
        self.link = {tuple(p): k for k, p in enumerate(pairs)}
        self.messages = np.zeros(len(pairs), np.int64)

    def advance(self, news: Checkpoint) -> Step:
        p, agent = self.setup.problem, self.setup.agent_of_vertex
        self.given[news.vertices] = True
        for e in news.closures.tolist():
            a, b = int(agent[p.edge_from[e]]), int(agent[p.edge_to[e]])
            for mine, other in ((a, int(p.edge_to[e])), (b, int(p.edge_from[e]))):
                if self.given[other]:
                    self.kept[(mine, other)] = p.initial[other]
                    self.messages[self.link[(min(a, b), max(a, b))]] += 1
        return self.finish()

    def finish(self) -> Step:
        keys = sorted(self.kept)
        kept = KeptPoses(
            np.array([r for r, _ in keys], np.int64),
            np.array([v for _, v in keys], np.int64),
            np.array([self.kept[k] for k in keys]).reshape(len(keys), self.own.shape[1]),
        )
        sizes = self.messages * self.setup.pose_bytes
        return Step(self.own.copy(), 0.0, self.messages.copy(), sizes, kept)


def test_the_program_replays_as_its_in_process_twin(tiny, tmp_path, monkeypatch):
    monkeypatch.setitem(BACKENDS, "twin", EchoTwin)
    res = replay(tiny, tmp_path / "r", backends=[COMMAND, "twin"], comms="range:15,p=0.7", every=10, seed=3)
    program, twin = res.runs
    assert program.name == "command-echo_backend" == output_name(COMMAND)
    assert program.messages.sum() > 0 and (program.bytes == twin.bytes).all()
    assert (program.messages == twin.messages).all()
    assert np.array_equal(program.final_poses, twin.final_poses)
    assert np.array_equal(program.ape_team_se3_m, twin.ape_team_se3_m)
    assert program.sve is not None and np.array_equal(program.sve, twin.sve, equal_nan=True)
    assert np.isfinite(program.sve[-1]).all()
    metrics = (tmp_path / "r" / "metrics.csv").read_text(encoding="utf-8").splitlines()
    ours = [m.split(",", 1)[1] for m in metrics if m.startswith("command-echo_backend,")]
    theirs = [m.split(",", 1)[1] for m in metrics if m.startswith("twin,")]
    assert ours == theirs and len(ours) > 5
    jrr = (tmp_path / "r" / "command-echo_backend.jrr").read_text(encoding="utf-8")
    assert jrr.replace("command-echo_backend", "twin") == (tmp_path / "r" / "twin.jrr").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("mode", "reason"),
    [
        ("crash", "the program ended with exit code 3 before answering (echo_backend: simulated crash)"),
        ("hang", "no answer within the time limit of 1 s"),
        ("garbage", "the answer is not one JSON object: 'this is not JSON'"),
        ("counts", '"messages": expected 3 counts (one per link), non-negative integers'),
    ],
)
def test_a_program_that_misbehaves_ends_the_run_in_one_line(tiny, tmp_path, mode, reason):
    out = tmp_path / "r"
    backend = f"{COMMAND} {mode}"
    r = runner.invoke(
        app,
        ["replay", str(tiny), "-b", f"centralized,{backend}", "-o", str(out), "--every", "10"] + ["--time-limit", "1"],
    )
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert lines[-1] == f"error: backend {backend}: checkpoint at tick 10: {reason}", r.output
    assert "Traceback" not in r.output and not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == []  # no staging left behind


def test_a_program_that_cannot_start_or_a_bad_command(tiny, tmp_path):
    r = runner.invoke(app, ["replay", str(tiny), "-b", "command:/no/such/program", "-o", str(tmp_path / "r")])
    assert (
        r.exit_code == 2
        and r.output
        == "error: backend command:/no/such/program: cannot start /no/such/program: No such file or directory\n"
    )
    with pytest.raises(ConfigError, match="No closing quotation"):
        get_backend("command:prog 'open")
    with pytest.raises(ConfigError, match="give the program to run"):
        get_backend("command:")
    with pytest.raises(ConfigError, match="time_limit"):
        replay(tiny, tmp_path / "x", backends=[COMMAND], time_limit_s=-1.0)
