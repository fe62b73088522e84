"""`studio record`, `studio synth --no-rrd`, `studio view` and `studio snapshot` through the CLI."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.io.atomic import STAGING_PREFIX
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data" / "configs"
runner = CliRunner()


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ds")
    return synthesize(load_synth_config(DATA / "small3x100.json"), out, rrd=False).dataset_dir


@pytest.fixture()
def copy(dataset, tmp_path) -> Path:
    target = tmp_path / "ds"
    shutil.copytree(dataset, target)
    return target


def _fails_cleanly(args: list[str], out_dir: Path, match: str) -> str:
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    err = res.stderr.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert match in err, err
    assert not list(out_dir.glob("*.rrd")) and not list(out_dir.glob(STAGING_PREFIX + "*"))
    return err


def test_record_writes_a_recording(dataset, tmp_path):
    res = runner.invoke(app, ["record", str(dataset), "-o", str(tmp_path / "x.rrd")])
    assert res.exit_code == 0, res.output
    assert "1203 poses, 1200 odometry, 313 intra-agent and 677 inter-agent loop closures" in res.stdout
    assert (tmp_path / "x.rrd").stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]  # no staging folder left


def test_record_refuses_to_overwrite_without_force(dataset, tmp_path):
    out = tmp_path / "x.rrd"
    out.write_bytes(b"old")
    res = runner.invoke(app, ["record", str(dataset), "-o", str(out)])
    assert res.exit_code == 2 and "already exists" in res.stderr
    assert out.read_bytes() == b"old"
    res = runner.invoke(app, ["record", str(dataset), "-o", str(out), "--force", "-q"])
    assert res.exit_code == 0 and res.stdout == ""
    assert out.stat().st_size > 10_000


def test_record_missing_folder(tmp_path):
    _fails_cleanly(["record", str(tmp_path / "nope"), "-o", str(tmp_path / "x.rrd")], tmp_path, "not a folder")


def test_record_folder_without_agents(tmp_path):
    (tmp_path / "empty").mkdir()
    _fails_cleanly(
        ["record", str(tmp_path / "empty"), "-o", str(tmp_path / "x.rrd")],
        tmp_path,
        "no agent folder with a posegraph.g2o",
    )


def test_record_malformed_g2o_names_file_and_line(copy, tmp_path):
    g2o = copy / "agent2" / "posegraph.g2o"
    lines = g2o.read_text().splitlines(keepends=True)
    lines[4] = "VERTEX_SE3:QUAT 4 1.0 oops\n"
    g2o.write_text("".join(lines))
    _fails_cleanly(["record", str(copy), "-o", str(tmp_path / "x.rrd")], tmp_path, f"{g2o}:5:")


def test_record_edge_to_unknown_vertex_names_file_and_line(copy, tmp_path):
    g2o = copy / "agent1" / "posegraph.g2o"
    lines = g2o.read_text().splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("EDGE"))
    parts = lines[k].split(" ")
    parts[2] = "99999"
    lines[k] = " ".join(parts)
    g2o.write_text("".join(lines))
    err = _fails_cleanly(["record", str(copy), "-o", str(tmp_path / "x.rrd")], tmp_path, f"{g2o}:{k + 1}:")
    assert "99999" in err


def test_record_tum_length_mismatch_names_the_file(copy, tmp_path):
    tum = copy / "agent3" / "agent3_GT.tum"
    tum.write_text("".join(tum.read_text().splitlines(keepends=True)[:-2]))
    _fails_cleanly(["record", str(copy), "-o", str(tmp_path / "x.rrd")], tmp_path, f"{tum}: 399 poses for 401")


def test_record_output_must_be_rrd(dataset, tmp_path):
    _fails_cleanly(["record", str(dataset), "-o", str(tmp_path / "x.png")], tmp_path, "must end in .rrd")


def test_failure_while_logging_leaves_nothing(dataset, tmp_path, monkeypatch):
    import studio.recording.dataset as recording
    from studio.core.errors import GraphError

    def boom(*args, **kwargs):
        raise GraphError("boom")

    monkeypatch.setattr(recording, "log_inter_loop_closures", boom)
    _fails_cleanly(["record", str(dataset), "-o", str(tmp_path / "x.rrd")], tmp_path, "boom")
    assert list(tmp_path.iterdir()) == []


def test_synth_writes_rrd_by_default_and_not_with_no_rrd(tmp_path):
    res = runner.invoke(app, ["synth", str(DATA / "small3x100.json"), "-o", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    assert str(tmp_path / "a" / "small3x100.rrd") in res.stdout
    assert (tmp_path / "a" / "small3x100.rrd").is_file()
    res = runner.invoke(app, ["synth", str(DATA / "small3x100.json"), "-o", str(tmp_path / "b"), "--no-rrd"])
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "b" / "small3x100.rrd").exists()
    assert (tmp_path / "b" / "small3x100").is_dir()


# --------------------------------------------------------------------------------------------------
# view and snapshot


def _empty_recording(rrd: Path) -> None:
    """A real (empty) recording: damaged ones are refused before a viewer starts."""
    import rerun as rr

    rec = rr.RecordingStream("t")
    rec.save(str(rrd))
    rec.disconnect()


def test_view_web_serves_on_localhost_only(tmp_path):
    import rerun as rr

    from studio.recording.viewer import view_web_command, web_viewer_address

    rrd = tmp_path / "x.rrd"
    rec = rr.RecordingStream("t")
    rec.save(str(rrd))  # a real (empty) recording: damaged ones are refused before a viewer starts
    rec.disconnect()
    served = view_web_command(rrd, port=9123)
    cmd = served.command
    assert cmd[1:6] == ["--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", "9123"]
    assert cmd[6:8] == ["--port", str(served.grpc_port)] and served.grpc_port != 9123
    assert cmd[-1] == str(rrd.resolve())
    assert served.address == web_viewer_address(9123, served.grpc_port)
    assert served.address == (f"http://127.0.0.1:9123/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{served.grpc_port}%2Fproxy")


def test_view_missing_file(tmp_path):
    _fails_cleanly(["view", str(tmp_path / "x.rrd"), "--web"], tmp_path, "no such recording")


def test_snapshot_without_vulkan_says_what_to_install(tmp_path, monkeypatch):
    import studio.recording.viewer as viewer

    rrd = tmp_path / "x.rrd"
    _empty_recording(rrd)
    monkeypatch.setattr(viewer, "vulkan_drivers", lambda: [])
    res = runner.invoke(app, ["snapshot", str(rrd), "-o", str(tmp_path / "x.png")])
    assert res.exit_code == 2
    assert "mesa-vulkan-drivers" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.png").exists()


def test_snapshot_bad_size(tmp_path):
    rrd = tmp_path / "x.rrd"
    _empty_recording(rrd)
    res = runner.invoke(app, ["snapshot", str(rrd), "-o", str(tmp_path / "x.png"), "--size", "big"])
    assert res.exit_code == 2 and "WIDTHxHEIGHT" in res.stderr


@pytest.mark.slow
def test_snapshot_renders_a_png(tmp_path):
    from studio.recording.viewer import vulkan_drivers

    if not vulkan_drivers():
        pytest.skip("no Vulkan driver (apt-get install -y mesa-vulkan-drivers)")
    rrd = Path(__file__).resolve().parent.parent.parent / "recordings" / "small3x100.rrd"
    res = runner.invoke(
        app, ["snapshot", str(rrd), "-o", str(tmp_path / "s.png"), "--node", "100", "--size", "800x500"]
    )
    assert res.exit_code == 0, res.output
    png = (tmp_path / "s.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert (width, height) in {(800, 500), (1600, 1000)}  # logical points, at scale 1 or 2


@pytest.mark.slow
def test_snapshot_light_theme_puts_the_views_on_white(tmp_path):
    """`--theme light`: the 3D view's background is the light theme's white, the dark one (13, 13, 13)."""
    from PIL import Image

    from studio.recording.colours import DARK_BACKGROUND_RGB, LIGHT_BACKGROUND_RGB
    from studio.recording.viewer import vulkan_drivers

    if not vulkan_drivers():
        pytest.skip("no Vulkan driver (apt-get install -y mesa-vulkan-drivers)")
    rrd = Path(__file__).resolve().parent.parent.parent / "recordings" / "three_loops.rrd"
    corners = {}
    for theme in ("dark", "light"):
        png = tmp_path / f"{theme}.png"
        res = runner.invoke(app, ["snapshot", str(rrd), "-o", str(png), "--size", "800x500", "--theme", theme])
        assert res.exit_code == 0, res.output
        image = Image.open(png).convert("RGB")
        w, h = image.size
        corners[theme] = image.getpixel((int(0.03 * w), int(0.25 * h)))  # in the 3D view, left of the data
    assert corners["dark"] == DARK_BACKGROUND_RGB and corners["light"] == LIGHT_BACKGROUND_RGB


def test_snapshot_unknown_theme(tmp_path):
    rrd = tmp_path / "x.rrd"
    _empty_recording(rrd)
    res = runner.invoke(app, ["snapshot", str(rrd), "-o", str(tmp_path / "x.png"), "--theme", "pink"])
    assert res.exit_code == 2 and not (tmp_path / "x.png").exists()
