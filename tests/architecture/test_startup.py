"""Start-up stays light (issue 28): loading the command line and declaring every command's options
imports no numpy, pandas, Rerun, solver library or generator; the heavy modules load inside the
commands, at use. Each check runs in a fresh interpreter (this test process has them all loaded)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import typer.main

import studio.cli
from studio.core.preset_names import PRESET_NAMES
from studio.generator.presets import PRESETS

#: What a command's declaration must not load: numeric and recording libraries, the solvers'
#: libraries, typer's pydantic coercion (typer 0.29+), rich (loaded by the progress display only when
#: stderr is a terminal), the generator and importlib.metadata (email, zipfile and csv come with it;
#: plug-ins are listed without it, :func:`studio.core.plugins.plugin_names`).
HEAVY = (
    "numpy",
    "pandas",
    "scipy",
    "rerun",
    "gtsam",
    "g2opy",
    "evo",
    "pydantic",
    "rich",
    "studio.generator",
    "importlib.metadata",
)

COMMANDS = sorted(typer.main.get_command(studio.cli.app).commands)  # type: ignore[attr-defined]


def _loaded_after(code: str) -> list[str]:
    """The HEAVY modules loaded once ``code`` has run in a new interpreter."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return list(json.loads(res.stdout.strip().splitlines()[-1]))


def test_importing_the_command_line_loads_nothing_heavy():
    assert _loaded_after("import studio.cli") == []
    assert _loaded_after("import studio._entry") == []


@pytest.mark.parametrize("command", COMMANDS)
def test_declaring_and_parsing_a_command_loads_nothing_heavy(command):
    """``studio COMMAND --help``: typer builds every command's options (choices and help from the
    registries) and parses the arguments, as it does before any command runs."""
    code = (
        "import sys\nimport studio.cli\n"
        f"sys.argv = ['studio', {command!r}, '--help']\n"
        "try:\n    studio.cli.app()\nexcept SystemExit as end:\n    assert end.code in (0, None), end.code\n"
    )
    assert _loaded_after(code) == []


def test_the_probe_sees_a_heavy_import():
    """The check above is not blind: a command that runs does load numpy."""
    assert "numpy" in _loaded_after("import studio.synth")


def test_the_preset_names_are_the_presets():
    """synth's help lists the presets from a light constant: it names exactly the generator's presets."""
    assert PRESET_NAMES == tuple(PRESETS)


def test_only_the_command_being_run_is_built_and_the_app_stays_whole():
    # typer builds every registered command's options before it parses: `studio synth ...` builds
    # only synth's, on a copy; --help, an unknown or missing name keep the whole app
    import studio.cli as cli

    names = [c.callback.__name__ for c in cli.app.registered_commands]
    one = cli._for_the_command(["synth", "multi3500x8", "-o", "out"])
    assert one is not cli.app and [c.callback.__name__ for c in one.registered_commands] == ["synth"]
    assert [c.callback.__name__ for c in cli.app.registered_commands] == names and len(names) > 10
    for argv in ([], ["--help"], ["synt"], ["--version", "synth"]):
        assert cli._for_the_command(argv) is cli.app
    import typer.testing

    res = typer.testing.CliRunner().invoke(one, ["synth", "--help"])
    assert res.exit_code == 0 and "CONFIG.json|PRESET" in res.output
