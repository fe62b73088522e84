"""Options are declared once: the convert flags, their defaults, help and units come from
GraphOptions; errors name the option in the library and the flag on the command line."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.convert import config_from_mapping
from studio.converters.build import GraphOptions, option_help
from studio.core.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]


def _help() -> str:
    res = CliRunner().invoke(app, ["convert", "--help"], env={"COLUMNS": "300"})
    assert res.exit_code == 0
    return re.sub(r"\s+", " ", res.output)


def test_convert_help_keeps_units_and_comes_from_graph_options():
    text = _help()
    for unit in ("[m]", "[rad]", "[s]", "[deg]", "[m/m]"):
        assert unit in text
    for f in dataclasses.fields(GraphOptions):
        assert "--" + f.name.replace("_", "-") in text
        assert re.sub(r"\s+", "", option_help(f.name)) in re.sub(r"\s+", "", text)  # help wraps lines
        assert f"[default: {f.default}]" in text or isinstance(f.default, bool)


def test_the_cli_repeats_no_graph_option():
    source = (REPO / "studio" / "cli.py").read_text(encoding="utf-8")
    for f in dataclasses.fields(GraphOptions):
        assert f'"--{f.name.replace("_", "-")}"' not in source, f.name
    assert "AlignChoice" not in source  # evaluate's Alignment is used directly


def test_errors_name_the_option_in_a_config_file_and_the_flag_on_the_command_line(tmp_path):
    with pytest.raises(ConfigError, match=r"^convert\.json: lc_radius: must be > 0$"):
        config_from_mapping({"source": "tum", "inputs": [], "lc_radius": 0}, "convert.json")
    f = tmp_path / "a.tum"
    f.write_text("1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n")
    res = CliRunner().invoke(app, ["convert", "tum", str(f), "-o", str(tmp_path / "o"), "--lc-radius", "0"])
    assert res.exit_code == 2
    assert res.output.strip() == "error: --lc-radius: must be > 0"


def test_library_errors_name_options_and_the_cli_shows_their_flags(tmp_path):
    """synth's and convert's limits are library options in the library's messages (no CLI flag in a
    library message), and flags on the command line."""
    from studio.convert import ConvertConfig, convert
    from studio.synth import load_synth_config, synthesize

    cfg = load_synth_config(str(REPO / "tests" / "data" / "configs" / "tiny_single.json"))
    for kwargs, option in (({"max_memory_gb": -1.0}, "max_memory_gb"), ({"jobs": -1}, "jobs")):
        with pytest.raises(ConfigError, match=rf"^{option}: ") as err:
            synthesize(cfg, tmp_path, **kwargs)
        assert err.value.option == option and "--" not in str(err.value)
    with pytest.raises(ConfigError, match=r"raise it with max_memory_gb\)$"):
        synthesize(cfg, tmp_path, max_memory_gb=1e-9)
    with pytest.raises(ConfigError, match=r"^max_memory_gb: ") as err:
        convert(ConvertConfig("tum", ()), tmp_path / "o", max_memory_gb=0)
    config = str(REPO / "tests" / "data" / "configs" / "tiny_single.json")
    res = CliRunner().invoke(app, ["synth", config, "-o", str(tmp_path), "--max-memory-gb", "-1"])
    assert res.exit_code == 2 and res.output.startswith("error: --max-memory-gb: "), res.output


def test_convert_pipeline_options_come_from_convert_config(tmp_path):
    """--split, --overlap, ... are ConvertConfig's fields: flag, default and help declared once there;
    an error naming the field is shown with its flag, also where the two differ (overlap_s)."""
    from studio.convert import ConvertConfig, pipeline_flags

    source = (REPO / "studio" / "cli.py").read_text(encoding="utf-8")
    text = re.sub(r"\s+", "", _help())
    flags = pipeline_flags()
    assert flags == {
        "orientation": "orientation",
        "heading_window_m": "heading_window_m",
        "heading_method": "heading_method",
        "body_frames": "body_frame",
        "split": "split",
        "overlap_s": "overlap",
        "folder_names": "folder_names",
        "odometry": "odometry",
        "odometry_from": "odometry_from",
        "keyframes_at_sightings": "keyframes_at_sightings",
        "sightings_as_closures": "sightings_as_closures",
    }
    for f in dataclasses.fields(ConvertConfig):
        if f.name not in flags:
            continue
        flag = "--" + flags[f.name].replace("_", "-")
        assert f'"{flag}"' not in source, flag
        assert flag in text and re.sub(r"\s+", "", f.metadata["help"]) in text
        if f.default != () and not isinstance(f.default, bool):  # a flag shows no default
            assert f"[default:{f.default}]" in text
    f = tmp_path / "a.tum"
    f.write_text("1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n")
    for args, message in (
        (["--split", "2", "--overlap", "-1"], "error: --overlap: expected a finite number >= 0, got -1.0"),
        (["--split", "1"], "error: --split: expected 0 (off) or an integer in 2..10000, got 1"),
        (["--body-frame", "x"], "error: --body-frame: 'x': expected NAME=CODE (e.g. robotA=ufl)"),
    ):
        res = CliRunner().invoke(app, ["convert", "tum", str(f), "-o", str(tmp_path / "o"), *args])
        assert res.exit_code == 2 and res.output.strip() == message, res.output
    with pytest.raises(ConfigError, match=r"^overlap_s: ") as err:
        ConvertConfig("tum", (), overlap_s=-1.0)
    assert err.value.option == "overlap_s"
