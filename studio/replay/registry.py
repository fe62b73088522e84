"""The back-ends of ``studio replay``, by name: the one place a back-end is declared
(:mod:`studio.replay.backends` holds their code). Each entry names its factory ``factory(setup) ->
ReplayBackend`` (:mod:`studio.replay.protocol`) by module and attribute
(:class:`~studio.core.lazy.Lazy`), imported when the back-end is used, so the command line lists
the back-ends without loading a solver or numpy.

Two more kinds of name reach the same protocol: a plug-in of another package (entry point group
``studio.replay_backends``, :mod:`studio.core.plugins`), and ``command:PROGRAM ARGS``, a program in
any language speaking the protocol as JSON lines (:mod:`studio.replay.external`). A built-in name
wins over a plug-in's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy
from studio.core.plugins import REPLAY_BACKENDS, load_plugin, plugin_names

if TYPE_CHECKING:
    from studio.replay.protocol import BackendFactory

__all__ = ["BACKENDS", "DEFAULT_BACKENDS", "COMMAND_PREFIX", "backend_names", "output_name", "get_backend"]

#: What ``studio replay`` runs without ``--backend``.
DEFAULT_BACKENDS = ("centralized", "independent", "swarm")

BACKENDS: dict[str, BackendFactory] = {
    "centralized": Lazy("studio.replay.backends", "Centralized"),
    "independent": Lazy("studio.replay.backends", "Independent"),
    "swarm": Lazy("studio.replay.backends", "Swarm"),
    "dgs": Lazy("studio.replay.backends", "make_dgs"),
}


#: ``command:PROGRAM ARGS``: an external program speaking the protocol (docs/replay.md).
COMMAND_PREFIX = "command:"


def backend_names() -> list[str]:
    """The built-in back-ends, then the installed plug-ins' (by entry-point name, nothing imported)."""
    return list(BACKENDS) + [n for n in plugin_names(REPLAY_BACKENDS) if n not in BACKENDS]


def output_name(name: str) -> str:
    """How the outputs name back-end ``name`` (``summary.csv``'s rows, ``<name>.jrr``): itself, but a
    ``command:`` back-end as ``command-`` and the stem of its last argument that names a file (the
    program or its script), else of the program: ``command:python3 my_backend.py --fast`` is
    ``command-my_backend``."""
    if not name.startswith(COMMAND_PREFIX):
        return name
    import os
    import re
    import shlex

    try:
        argv = shlex.split(name[len(COMMAND_PREFIX) :])
    except ValueError:
        argv = []
    files = [a for a in argv if os.path.isfile(a)]
    stem = os.path.splitext(os.path.basename(files[-1] if files else argv[0] if argv else ""))[0]
    return "command-" + (re.sub(r"[^A-Za-z0-9_.-]", "_", stem) or "program")


def get_backend(name: str, *, time_limit_s: float | None = None) -> BackendFactory:
    """The factory of back-end ``name``: built-in, ``command:...``, or an installed plug-in's (imported
    now: a plug-in that fails to import, or names no callable, is a ConfigError naming it);
    ``time_limit_s``: a ``command:`` program's limit per checkpoint (None: its default)."""
    if name in BACKENDS:
        return BACKENDS[name]
    if name.startswith(COMMAND_PREFIX):
        from studio.replay.external import DEFAULT_TIME_LIMIT_S, command_backend

        limit = DEFAULT_TIME_LIMIT_S if time_limit_s is None else time_limit_s
        return command_backend(name[len(COMMAND_PREFIX) :], limit)
    if name in plugin_names(REPLAY_BACKENDS):
        factory = load_plugin(REPLAY_BACKENDS, name)
        if not callable(factory):
            raise ConfigError(f"replay back-end plug-in {name!r}: names {type(factory).__name__}, not a factory")
        return factory  # type: ignore[no-any-return]
    known = ", ".join(backend_names() + [f"{COMMAND_PREFIX}PROGRAM"])
    raise ConfigError(f"backend: unknown back-end {name!r} (known: {known})") from None
