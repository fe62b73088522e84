"""What a user sees on opening a recording: every studio recording opens at its end (its time panel
follows the data), and `studio snapshot --views-only` gives only the views (issue 27)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.synth import load_synth_config, synthesize

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data" / "configs"
runner = CliRunner()

#: Rerun's PlayState enum as stored: 1 paused, 2 playing, 3 following
_FOLLOWING = 3


def _play_state(rrd: Path) -> int:
    """The time panel's play state saved in the recording's blueprint."""
    import rerun.chunk as rc

    reader = rc.RrdReader(rrd)
    states = []
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            if str(chunk.entity_path) != "/time_panel":
                continue
            batch = chunk.to_record_batch()
            if "TimePanelBlueprint:play_state" in batch.schema.names:
                states += [v[0] for v in batch.column("TimePanelBlueprint:play_state").to_pylist() if v]
    assert states, f"{rrd}: no time panel play state"
    return states[-1]


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("first_look")
    res = synthesize(load_synth_config(DATA / "small3x100.json"), out)
    assert res.rrd_path is not None
    ds = res.dataset_dir
    solved = runner.invoke(
        app, ["solve", str(ds), "-o", str(out / "solved"), "--rrd", str(out / "solve.rrd"), "--json"]
    )
    assert solved.exit_code == 0, solved.output
    ev = runner.invoke(app, ["evaluate", str(ds), "--rrd", str(out / "evaluate.rrd")])
    assert ev.exit_code == 0, ev.output
    rp = runner.invoke(
        app,
        ["replay", str(ds), "-o", str(out / "replay"), "-b", "independent", "--every", "100"]
        + ["--rrd", str(out / "replay.rrd")],
    )
    assert rp.exit_code == 0, rp.output
    return {
        "dataset": res.rrd_path,
        "solve": out / "solve.rrd",
        "evaluate": out / "evaluate.rrd",
        "replay": out / "replay.rrd",
    }


@pytest.mark.parametrize("kind", ["dataset", "solve", "evaluate", "replay"])
def test_every_recording_kind_follows_its_data_so_it_opens_at_the_end(recordings, kind):
    assert _play_state(recordings[kind]) == _FOLLOWING


@pytest.mark.parametrize("name", ["small3x100.rrd", "three_loops.rrd"])
def test_the_committed_recordings_open_at_the_end(name):
    assert _play_state(REPO / "recordings" / name) == _FOLLOWING


def _needs_vulkan() -> None:
    from studio.recording.viewer import vulkan_drivers

    if not vulkan_drivers():
        pytest.skip("no Vulkan driver (apt-get install -y mesa-vulkan-drivers)")


@pytest.mark.slow
def test_a_viewer_opens_a_dataset_recording_at_its_last_node():
    """The real viewer, untouched after loading: the cursor is on the last node, not node 0."""
    from studio.recording.viewer import opened_at

    _needs_vulkan()
    assert opened_at(REPO / "recordings" / "small3x100.rrd") == ("node", 400)


@pytest.mark.slow
def test_views_only_snapshot_has_no_panels_around_the_views(tmp_path):
    from PIL import Image

    from studio.recording.colours import DARK_BACKGROUND_RGB

    _needs_vulkan()
    rrd = REPO / "recordings" / "three_loops.rrd"
    pictures = {}
    for label, extra in (("full", []), ("views", ["--views-only"])):
        png = tmp_path / f"{label}.png"
        res = runner.invoke(app, ["snapshot", str(rrd), "-o", str(png), "--size", "800x500", *extra])
        assert res.exit_code == 0, res.output
        assert res.output.strip() == f"{png}: node 132"  # the timeline's name, and its last node
        pictures[label] = Image.open(png).convert("RGB")
    full, views = pictures["full"], pictures["views"]
    assert views.width == full.width
    assert full.height - 60 < views.height < full.height  # the window strip above the views is trimmed

    # the bottom left: the time panel's stream tree (text) in the full picture, the 3D view's empty
    # background without it
    def patch(im):
        w, h = im.size
        return {
            im.getpixel((x, y)) for x in range(int(0.02 * w), int(0.2 * w), 3) for y in range(int(0.8 * h), h - 4, 3)
        }

    assert patch(views) == {DARK_BACKGROUND_RGB}
    assert len(patch(full)) > 3


def _web_viewer(rrd: Path, *extra: str):
    """`studio view --web` as a user runs it; (process, its first output line)."""
    import os
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-c", "from studio._entry import main; main()", "view", str(rrd), "--web", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "CI": "true", "RERUN_ANALYTICS": "0"},
    )
    assert proc.stdout is not None
    return proc, proc.stdout.readline()


def _children(pid: int) -> list:
    import psutil

    return psutil.Process(pid).children(recursive=True)


def _wait_for_children(pid: int, timeout_s: float = 20.0) -> list:
    import time

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        kids = _children(pid)
        if kids:
            return kids
        time.sleep(0.1)
    raise AssertionError("the viewer did not start")


def test_two_web_viewers_at_once_and_sigterm_leaves_no_child(tmp_path):
    import signal
    import socket

    import psutil

    rrd = REPO / "recordings" / "small3x100.rrd"
    first, line1 = _web_viewer(rrd)
    second, line2 = _web_viewer(rrd)
    kids: list = []
    try:
        kids += _wait_for_children(first.pid) + _wait_for_children(second.pid)
        assert line1.startswith("web viewer: open http://127.0.0.1:") and line2.startswith("web viewer: open ")
        assert line1 != line2  # two page ports and two gRPC ports
        # a port asked for that is taken: one line naming it, exit 2
        with socket.socket() as busy:
            busy.bind(("127.0.0.1", 0))
            busy.listen()
            port = busy.getsockname()[1]
            third, line3 = _web_viewer(rrd, "--port", str(port))
            assert third.wait(timeout=60) == 2
            assert (
                line3.strip()
                == f"error: --port {port}: 127.0.0.1:{port} is in use (leave --port out to take a free port)"
            )
        for proc in (first, second):
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(timeout=30) == 128 + signal.SIGTERM
        gone, alive = psutil.wait_procs(kids, timeout=15)
        assert not alive, [p.cmdline() for p in alive]
    finally:  # a failing run leaves no viewer serving either (one did, for an hour, at 70 % CPU)
        for proc in (first, second):
            if proc.poll() is None:
                kids += _children(proc.pid)  # every viewer it started, not only the first seen
                proc.kill()
        for kid in kids:
            if kid.is_running():
                kid.kill()


def test_evaluate_fits_the_terminal_and_keeps_every_number(tmp_path):
    """At $COLUMNS=100 the table is turned (metrics as rows, agents as columns) in blocks that fit;
    in a pipe (no $COLUMNS) it stays the wide table, agents as rows."""
    import re

    config = load_synth_config(DATA / "small3x100.json")
    ds = synthesize(config, tmp_path, rrd=False).dataset_dir
    wide = runner.invoke(app, ["evaluate", str(ds)], env={"COLUMNS": ""})
    narrow = runner.invoke(app, ["evaluate", str(ds)], env={"COLUMNS": "45"})
    assert wide.exit_code == 0 and narrow.exit_code == 0, (wide.output, narrow.output)
    table = [line for line in wide.output.splitlines() if re.match(r"^(agent\d|all) ", line)]
    assert len(table) == 4 and max(map(len, wide.output.splitlines())) > 100
    body = narrow.output.split("\n\n", 1)[1]
    assert max(map(len, body.splitlines())) <= 45
    assert body.count("APE t mean") == 2  # two blocks of agents
    # every number of the wide table is in the turned one
    numbers = lambda text: sorted(re.findall(r"\b\d+\.\d{6}\b", text))  # noqa: E731
    assert numbers(wide.output) == numbers(narrow.output) and len(numbers(wide.output)) == 4 * 10
    assert re.search(r"^APE t mean\s+\d", body, re.M) and body.rstrip().split("\n\n")[-1].split()[1:3] == [
        "agent3",
        "all",
    ]
