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
    return {"dataset": res.rrd_path, "solve": out / "solve.rrd", "evaluate": out / "evaluate.rrd"}


@pytest.mark.parametrize("kind", ["dataset", "solve", "evaluate"])
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
