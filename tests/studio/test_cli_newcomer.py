"""What a newcomer meets first: `--version`, `view` without a display, re-running the effective config."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from studio import __version__
from studio.cli import app

REPO = Path(__file__).resolve().parent.parent.parent
DATA = REPO / "tests" / "data"
runner = CliRunner()


def test_version_prints_the_package_version():
    from importlib.metadata import version

    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"studio {version('cslam-studio')}"
    assert version("cslam-studio") == __version__  # pyproject.toml and studio/__init__.py agree


def test_view_without_a_display_names_web_and_snapshot(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    rrd = REPO / "recordings" / "small3x100.rrd"
    proc = subprocess.run(
        [sys.executable, "-m", "studio.cli", "view", str(rrd)], env=env, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "--web" in lines[0] and "studio snapshot" in lines[0] and "no display" in lines[0]
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_synth_of_the_effective_config_keeps_the_dataset_name(tmp_path):
    first = tmp_path / "first"
    res = runner.invoke(app, ["synth", str(DATA / "configs" / "tiny_three.json"), "-o", str(first), "--no-rrd"])
    assert res.exit_code == 0, res.output
    again = tmp_path / "again"
    res = runner.invoke(app, ["synth", str(first / "tiny_three.config.json"), "-o", str(again), "--no-rrd"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in again.iterdir()) == ["tiny_three", "tiny_three.config.json", "tiny_three_singleg2o"]
    assert (again / "tiny_three.config.json").read_bytes() == (first / "tiny_three.config.json").read_bytes()


def test_version_is_answered_without_loading_the_command_line():
    """``studio --version`` is printed by the console script's entry point: neither typer nor numpy
    (nor any registry's readers or solvers) is imported for it."""
    import subprocess
    import sys

    code = (
        "import sys; sys.argv = ['studio', '--version']; from studio._entry import main; main(); "
        "print(sorted(m for m in ('typer', 'numpy', 'studio.cli', 'studio.converters.tum') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    from studio.runtime.version import installed_version

    assert done.stdout.splitlines() == [f"studio {installed_version()}", "[]"]


def test_the_registries_import_no_reader_or_solver_module():
    """The registries name their entries' code by module path; building the command line imports
    none of the readers' or solvers' modules (they load when a command uses them)."""
    import subprocess
    import sys

    heavy = ["studio.converters.tum", "studio.converters.jrl", "studio.solvers.gtsam_method", "studio.solvers.dgs"]
    code = f"import sys, studio.cli; print([m for m in {heavy!r} if m in sys.modules])"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
