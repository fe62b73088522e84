"""What a newcomer reads first: the overwrite hint speaks the caller's language (``force=True`` to a
script, ``--force`` on the command line), convert names its recording like synth, and counts of one
are singular."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.convert import ConvertConfig, convert
from studio.converters.options import GraphOptions
from studio.core.errors import OutputError
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory, write_tum_file

runner = CliRunner()


@pytest.fixture
def one_tum(tmp_path):
    s, p, q = loop_trajectory(600, centre=(UTM_EAST, UTM_NORTH, 50.0), phase=0, t0_s=1.6e9)
    return write_tum_file(tmp_path / "alpha.txt", s, p, q)


def test_existing_output_says_force_true_to_a_script_and_force_flag_on_the_command_line(tmp_path, one_tum):
    out = tmp_path / "ds"
    out.mkdir()
    with pytest.raises(OutputError, match=re.escape(f"{out} already exists (pass force=True to overwrite)")):
        convert(ConvertConfig("tum", (str(one_tum),), (), GraphOptions()), out, rrd=False)
    res = runner.invoke(app, ["convert", "tum", str(one_tum), "-o", str(out)])
    assert res.exit_code == 2
    assert res.output == f"error: {out} already exists (use --force to overwrite)\n"


def test_convert_lists_its_recording_and_counts_one_agent_in_the_singular(tmp_path, one_tum):
    out = tmp_path / "ds"
    res = runner.invoke(app, ["convert", "tum", str(one_tum), "-o", str(out)])
    assert res.exit_code == 0, res.output
    first, *paths = res.output.splitlines()
    assert first.startswith("ds: 1 agent, ") and "1 agents" not in first
    assert f"  {out}" in paths and f"  {out / 'ds.rrd'}" in paths
    assert (out / "ds.rrd").is_file()
    quiet = runner.invoke(app, ["convert", "tum", str(one_tum), "-o", str(tmp_path / "b"), "--no-rrd"])
    assert quiet.exit_code == 0 and ".rrd" not in quiet.output


def test_export_of_one_file_says_file(tmp_path, one_tum):
    ds = tmp_path / "ds"
    assert runner.invoke(app, ["convert", "tum", str(one_tum), "-o", str(ds), "--no-rrd"]).exit_code == 0
    res = runner.invoke(app, ["export", str(ds), "-f", "jrl", "-o", str(tmp_path / "jrl")])
    assert res.exit_code == 0, res.output
    assert re.search(r": jrl, 1 file in ", res.output), res.output


def test_the_output_guard_speaks_the_callers_language_and_leaves_paths_alone(tmp_path, monkeypatch):
    """synth's output goes through the output guard itself (not a pipeline's own check); a folder
    named ``force`` in the path stays as it is when the hint becomes ``--force``."""
    from studio.synth import load_synth_config, synthesize
    from tests.conftest import DATA

    monkeypatch.chdir(tmp_path)
    config = load_synth_config(DATA / "configs" / "tiny_three.json")
    synthesize(config, "force", rrd=False, jobs=1)
    with pytest.raises(OutputError, match=re.escape("force/tiny_three already exists (pass force=True to overwrite)")):
        synthesize(config, "force", rrd=False, jobs=1)
    res = runner.invoke(app, ["synth", str(DATA / "configs" / "tiny_three.json"), "-o", "force", "--no-rrd", "-q"])
    assert res.exit_code == 2
    assert res.output == "error: force/tiny_three already exists (use --force to overwrite)\n"
