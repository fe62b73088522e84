"""Every command's --help runs and names its choices: a word option shows ``<a|b|c>`` built from the
registry (or the library's tuple) that checks it; only free-form text is ``<str>``."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from typing import get_args

import pytest
import typer.main
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.build import GraphOptions  # noqa: F401  (the CLI builds flags from it)
from studio.converters.graph_split import GROUND_TRUTH_CHOICES, PARTITIONS
from studio.converters.registry import SOURCES
from studio.converters.transforms import HEADING_METHODS
from studio.core.residuals import Convention
from studio.export import EXPORT_FORMATS
from studio.solvers import METHODS

runner = CliRunner()
COMMANDS = sorted(typer.main.get_command(app).commands)  # type: ignore[attr-defined]

#: Options whose value is free text (a name, a command line, a model string, an address, a size).
FREE_TEXT = {"--name", "--command", "--comms", "--backend", "--bandwidth", "--scheduler", "--size"}


def _help(command: str) -> str:
    res = runner.invoke(app, [command, "--help"], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    return res.output


def test_every_command_has_a_help_that_runs():
    assert {"synth", "convert", "evaluate", "solve", "check", "bench", "sweep", "replay", "export"} <= set(COMMANDS)
    for command in COMMANDS:
        text = _help(command)
        assert text.startswith(f"Usage: studio {command} "), command
        assert "Example" in text, f"studio {command} --help gives no example"


@pytest.mark.parametrize("command", COMMANDS)
def test_only_free_text_options_show_str(command):
    text = _help(command)
    vague = set(re.findall(r"(--[a-z0-9-]+) <str>", text))
    assert vague <= FREE_TEXT, f"studio {command}: {sorted(vague - FREE_TEXT)} take words but list no choices"


def _choices(text: str, flag: str) -> list[str]:
    found = re.search(rf"{flag} <([a-z0-9|._-]+)>", text)
    assert found, f"{flag} lists no choices"
    return found.group(1).split("|")


def test_choices_are_the_registries():
    convert = _help("convert")
    assert _choices(convert, "--partition") == list(PARTITIONS)
    assert _choices(convert, "--ground-truth") == list(GROUND_TRUTH_CHOICES)
    assert _choices(convert, "--heading-method") == list(HEADING_METHODS)
    assert _choices(convert, "--orientation") == ["auto", "keep", "derive"]
    assert _choices(convert, "--folder-names") == ["agents", "robots"]
    assert _choices(convert, "--odometry") == ["synthetic", "real"]
    assert _choices(_help("export"), "--format") == list(EXPORT_FORMATS)
    assert _choices(_help("check"), "--convention") == list(get_args(Convention))
    assert _choices(_help("solve"), "--method") == list(METHODS)


def test_convert_names_its_source_as_the_errors_do():
    text = _help("convert")
    assert "[SOURCE] [INPUT...]" in text and "FORMAT" not in text
    for name in SOURCES:
        assert f"{name}: " in text, name
    res = runner.invoke(app, ["convert", "nosuch", "x", "-o", "out"])
    assert res.exit_code == 2 and "SOURCE" in res.stderr


def test_check_says_it_takes_a_single_g2o():
    assert "or a single g2o file NAME.g2o" in " ".join(_help("check").split())


def test_a_word_option_outside_its_choices_is_refused_in_one_line(tmp_path):
    res = runner.invoke(
        app, ["convert", "tum", str(tmp_path / "a.tum"), "-o", str(tmp_path / "o"), "--orientation", "x"]
    )
    assert res.exit_code == 2 and "--orientation: expected auto, keep or derive, got 'x'" in res.stderr


@pytest.mark.parametrize("columns", [60, 150])
def test_help_follows_the_terminal_width(columns):
    """click's own cap (80 columns) no longer wraps help in a wide terminal, and a narrow one is kept.
    Run as a process: ``CliRunner`` forces its own width on click's formatter."""
    env = {**os.environ, "COLUMNS": str(columns)}
    res = subprocess.run(
        [sys.executable, "-m", "studio.cli", "convert", "--help"], env=env, capture_output=True, text=True, check=True
    )
    widths = [len(line) for line in res.stdout.splitlines()]
    assert max(widths) <= columns
    assert max(widths) > columns - 10  # the long option help fills the width it was given
