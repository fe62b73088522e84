"""Nothing lost, nothing escapes, round four (issue 41): names given as options or found in data
never decide where a file goes, inputs that live inside an output are never replaced, every input
is a regular file, and each refusal comes before the first byte is written (every byte of the
working folder is compared before and after)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.reliability import test_guard as guard

made, world = guard.made, guard.world  # the guard tests' fixtures: a synth dataset and a working folder
refused_intact = guard.refused_intact

#: Every hostile path component: a parent, an absolute path, a separator, NUL, a line break.
HOSTILE_NAMES = ["..", "../../ds/agent1/posegraph", "/tmp/studio-escaped", "a/b", "a\x00b", "a\nb"]


# --------------------------------------------------------------------------- names from options
@pytest.mark.parametrize("fmt", ["dpgo", "symbols", "jrl"])
@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_export_name_must_be_one_plain_component(world, fmt, hostile):
    """``--name ../../ds/agent1/posegraph`` once wrote DPGO's g2o over the dataset's own file
    (exit 0); ``/abs`` and ``../../escaped`` wrote outside ``-o``."""
    out = "out.jrl" if fmt == "jrl" else "out"
    err = refused_intact(["export", "ds", "-f", fmt, "-o", out, "--name", hostile], world, "--name: ")
    assert "\\n" in err or "\n" not in hostile  # the line break is shown escaped, the message one line
    assert not Path("/tmp/studio-escaped.g2o").exists()


@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_bag_agent_name_must_be_one_plain_component(world, hostile):
    (world / "run.bag").write_bytes(b"")  # never read: the name is refused first
    refused_intact(["convert", "bag", "run.bag", "--agent", f"{hostile}=/odom", "-o", "out"], world, "agent name")


def test_export_library_refuses_a_name_that_is_not_a_string(world):
    from studio.core.errors import ConfigError
    from studio.export import export_dataset

    with pytest.raises(ConfigError, match="--name: expected a string, got int"):
        export_dataset(world / "ds", world / "out", format="dpgo", name=3)  # type: ignore[arg-type]
    assert not (world / "out").exists()


def test_a_plain_export_name_names_the_files(world):
    from studio.export import export_dataset

    res = export_dataset(world / "ds", world / "out", format="dpgo", name="my data+1")
    assert "my data+1.g2o" in res.files and (world / "out" / "my data+1.g2o").is_file()


# --------------------------------------------------------------------------- names from data
@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_agent_names_in_agents_json_stay_inside_the_output(world, hostile):
    """Names found in data are made plain (``studio.io.names.safe_file_name``), never followed."""
    ds = world / "ds"
    agents = [{"folder": f"agent{k + 1}", "name": n} for k, n in enumerate([hostile, "bob", "carol"])]
    (ds / "agents.json").write_text(json.dumps({"format": "cslam-studio agents 1", "agents": agents}))
    before = guard._tree(world)
    res = guard.runner.invoke(guard.app, ["solve", "ds", "-o", "est"])
    assert res.exit_code == 0, res.stderr
    assert all(m.startswith("est") for m in set(guard._tree(world)) - set(before))
    assert not Path("/tmp/studio-escaped.tum").exists()
