"""Plug-ins from other packages: replay back-ends and solve methods declared as Python entry points.

An installed package declares them in its ``pyproject.toml``::

    [project.entry-points."studio.replay_backends"]
    mine = "my_package.backend:MyBackend"      # factory(setup) -> ReplayBackend
    [project.entry-points."studio.solve_methods"]
    mine = "my_package.method:METHOD"          # a studio.solvers.SolveMethod

The command line lists them by their entry-point names, read from the installed packages'
``entry_points.txt`` files (:func:`plugin_names`: a listing of each folder of ``sys.path`` and a read
of those files; ``importlib.metadata.entry_points()`` parses every installed package's metadata,
too slow for every start of the command line), nothing imported; a plug-in is imported only when it
is used, and one that fails to import is a one-line :class:`~studio.core.errors.ConfigError` naming it, never a traceback. A built-in name wins
over a plug-in of the same name (``studio plugins`` says so).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from studio.core.errors import ConfigError

if TYPE_CHECKING:
    from importlib.metadata import EntryPoint

__all__ = ["REPLAY_BACKENDS", "SOLVE_METHODS", "GROUPS", "Plugin", "plugins", "plugin_names", "load_plugin"]

REPLAY_BACKENDS = "studio.replay_backends"
SOLVE_METHODS = "studio.solve_methods"
#: The entry-point groups the studio reads, and what a plug-in of each is.
GROUPS = {REPLAY_BACKENDS: "replay back-end", SOLVE_METHODS: "solve method"}


@dataclass(frozen=True)
class Plugin:
    """One entry point of a group: its name, its ``module:attr`` and the package declaring it."""

    group: str
    name: str
    value: str
    package: str


def _entries(group: str) -> list[EntryPoint]:
    # Imported here, not with the module: importlib.metadata brings email, zipfile and csv with it,
    # which the command line's start (it imports this module for plugin_names) does not need.
    from importlib.metadata import entry_points

    return sorted(entry_points(group=group), key=lambda e: (e.name, e.value))


def _package(entry: EntryPoint) -> str:
    dist = entry.dist
    return "?" if dist is None else f"{dist.name} {dist.version}"


def plugins(group: str) -> list[Plugin]:
    """The entry points of ``group`` in the installed packages, by name (nothing imported)."""
    return [Plugin(group, e.name, e.value, _package(e)) for e in _entries(group)]


def _declared(text: str, group: str) -> set[str]:
    """The names an ``entry_points.txt`` (INI: ``[group]`` then ``name = module:attr``) gives ``group``."""
    names: set[str] = set()
    section = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1].strip()
        elif section == group and "=" in line:
            names.add(line.partition("=")[0].strip())
    return names


def plugin_names(group: str) -> list[str]:
    """The names of ``group``'s entry points in the packages on ``sys.path``, sorted, each once
    (nothing imported, no package metadata parsed)."""
    names: set[str] = set()
    for folder in sys.path:
        try:
            children = os.listdir(folder or ".")
        except OSError:
            continue
        for child in children:
            if not child.endswith((".dist-info", ".egg-info")):
                continue
            try:
                with open(os.path.join(folder or ".", child, "entry_points.txt"), encoding="utf-8") as f:
                    text = f.read()
            except OSError:
                continue
            if f"[{group}]" in text:
                names |= _declared(text, group)
    return sorted(names)


def load_plugin(group: str, name: str) -> Any:
    """The object entry point ``name`` of ``group`` names, imported now; ConfigError (one line
    naming the plug-in and its package) if there is none or it fails to import."""
    found = [e for e in _entries(group) if e.name == name]
    if not found:
        raise ConfigError(f"{GROUPS[group]}: no plug-in {name!r} in entry-point group {group}")
    entry = found[0]
    try:
        return entry.load()
    except Exception as err:  # any failure of third-party code at import: one line, not a traceback
        reason = (str(err).splitlines() or [""])[0]
        raise ConfigError(
            f"{GROUPS[group]} plug-in {name!r} ({entry.value}, from {_package(entry)}) failed to load: "
            f"{type(err).__name__}: {reason}"
        ) from None
