"""The output guard (issue 23), enforced on the code: every command's output options are listed
here, each is run through the shared hostile output cases of tests/reliability/test_guard.py, and no
module outside studio/io/ writes a file without going through studio/io/atomic.py.

A new command with an output, or a new output option, fails :func:`test_every_output_option_is_listed`
until it is added to :data:`OUTPUTS` and to the shared cases; a module that writes files on its own
(``open(..., "w")``, ``write_text``, ``os.replace`` ...) without the guard fails
:func:`test_no_module_writes_around_the_guard`.
"""

from __future__ import annotations

import ast
import inspect
import typing
from pathlib import Path

import typer.main

from studio.cli import app
from tests.reliability.test_guard import COMMANDS

REPO = Path(__file__).resolve().parents[2]

#: Every command's output options (the paths it writes). Everything else it takes is read.
OUTPUTS: dict[str, set[str]] = {
    "synth": {"--out"},
    "record": {"--out"},
    "evaluate": {"--rrd", "--jrm"},
    "snapshot": {"--out"},
    "convert": {"--out"},
    "solve": {"--out", "--rrd"},
    "bench": {"--out"},
    "sweep": {"--out"},
    "export": {"--out"},
    "replay": {"--out", "--rrd"},
}
#: Path options that are inputs.
INPUT_OPTIONS: dict[str, set[str]] = {"evaluate": {"--estimate"}, "convert": {"--config"}, "check": {"--certify"}}
#: The shared output cases' entries (tests/reliability/test_guard.py) for each output option.
CASES = {
    ("record", "--out"): "record",
    ("evaluate", "--rrd"): "evaluate --rrd",
    ("evaluate", "--jrm"): "evaluate --jrm",
    ("snapshot", "--out"): "snapshot",
    ("convert", "--out"): "convert",
    ("solve", "--out"): "solve",
    ("solve", "--rrd"): "solve --rrd",
    ("bench", "--out"): "bench",
    ("sweep", "--out"): "sweep",
    ("export", "--out"): "export",
    ("replay", "--out"): "replay",
    ("replay", "--rrd"): "replay --rrd",
}
#: Covered by their own tests: synth writes several outputs under a parent folder
#: (tests/reliability/test_generated_corpus.py, tests/studio/test_cli_synth.py).
OWN_TESTS = {("synth", "--out")}


def _is_path(annotation: object) -> bool:
    return annotation is Path or Path in typing.get_args(annotation)


def _path_options() -> dict[str, set[str]]:
    group = typer.main.get_command(app)
    found: dict[str, set[str]] = {}
    for name, command in group.commands.items():  # type: ignore[attr-defined]
        hints = typing.get_type_hints(inspect.unwrap(command.callback))
        for param in command.params:
            if param.param_type_name != "option" or not _is_path(hints.get(param.name)):
                continue
            long = next(o for o in param.opts if o.startswith("--"))
            found.setdefault(name, set()).add(long)
    return found


def test_every_output_option_is_listed():
    found = _path_options()
    outputs = {c: opts - INPUT_OPTIONS.get(c, set()) for c, opts in found.items()}
    assert {c: o for c, o in outputs.items() if o} == OUTPUTS


def test_every_output_option_runs_the_shared_hostile_cases():
    for command, options in OUTPUTS.items():
        for option in options:
            key = (command, option)
            assert key in OWN_TESTS or CASES.get(key) in COMMANDS, key


_WRITE_METHODS = {"write_text", "write_bytes", "to_csv", "to_parquet", "savefig", "mkdir", "touch"}
_RENAMES = {("os", "replace"), ("os", "rename"), ("shutil", "move"), ("shutil", "copy"), ("shutil", "copytree")}
_GUARD = {"staged_outputs", "write_replacing", "output_workspace"}


def _writes(tree: ast.AST) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if isinstance(f, ast.Attribute) and f.attr in _WRITE_METHODS:
            found.append(f"{f.attr} (line {node.lineno})")
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and (f.value.id, f.attr) in _RENAMES:
            found.append(f"{f.value.id}.{f.attr} (line {node.lineno})")
        if isinstance(f, ast.Name) and f.id == "open" and len(node.args) > 1:
            mode = node.args[1]
            if isinstance(mode, ast.Constant) and isinstance(mode.value, str) and set(mode.value) & set("wax+"):
                found.append(f"open(..., {mode.value!r}) (line {node.lineno})")
    return found


def _guarded(tree: ast.AST) -> bool:
    return any(
        isinstance(n, ast.ImportFrom) and n.module == "studio.io.atomic" and {a.name for a in n.names} & _GUARD
        for n in ast.walk(tree)
    )


def test_no_module_writes_around_the_guard():
    """A module that writes files is a format writer of studio/io/ (it writes where its caller, inside
    the guard, tells it), or it imports the guard. Renames are the guard's alone."""
    bad = []
    for folder in ("studio", "converters", "generator"):
        for path in sorted((REPO / folder).rglob("*.py")):
            rel = path.relative_to(REPO)
            if rel.as_posix() == "studio/io/atomic.py":
                continue
            tree = ast.parse(path.read_text(encoding="utf-8"))
            writes = _writes(tree)
            renames = [w for w in writes if w.split(" ")[0].split(".")[0] in ("os", "shutil")]
            if renames:
                bad.append(f"{rel}: {', '.join(renames)} (renames belong to studio/io/atomic.py)")
            elif writes and rel.parts[:2] != ("studio", "io") and not _guarded(tree):
                bad.append(f"{rel}: {', '.join(writes)} without studio.io.atomic")
    assert not bad, "\n".join(bad)
