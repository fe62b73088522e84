"""The back-ends of ``studio replay``, by name: the one place a back-end is declared
(:mod:`studio.replay.backends` holds their code). Each entry names its factory ``factory(setup) ->
ReplayBackend`` (:mod:`studio.replay.protocol`) by module and attribute
(:class:`~studio.core.lazy.Lazy`), imported when the back-end is used, so the command line lists
the back-ends without loading a solver or numpy.

A plug-in of another package (entry point group ``studio.replay_backends``,
:mod:`studio.core.plugins`) reaches the same protocol. A built-in name wins over a plug-in's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy
from studio.core.plugins import REPLAY_BACKENDS, load_plugin, plugin_names

if TYPE_CHECKING:
    from studio.replay.protocol import BackendFactory

__all__ = ["BACKENDS", "DEFAULT_BACKENDS", "backend_names", "get_backend"]

#: What ``studio replay`` runs without ``--backend``.
DEFAULT_BACKENDS = ("centralized", "independent", "swarm")

BACKENDS: dict[str, BackendFactory] = {
    "centralized": Lazy("studio.replay.backends", "Centralized"),
    "independent": Lazy("studio.replay.backends", "Independent"),
    "swarm": Lazy("studio.replay.backends", "Swarm"),
    "dgs": Lazy("studio.replay.backends", "make_dgs"),
}


def backend_names() -> list[str]:
    """The built-in back-ends, then the installed plug-ins' (by entry-point name, nothing imported)."""
    return list(BACKENDS) + [n for n in plugin_names(REPLAY_BACKENDS) if n not in BACKENDS]


def get_backend(name: str) -> BackendFactory:
    """The factory of back-end ``name``: built-in, ``command:...``, or an installed plug-in's (imported
    now: a plug-in that fails to import, or names no callable, is a ConfigError naming it)."""
    if name in BACKENDS:
        return BACKENDS[name]
    if name in plugin_names(REPLAY_BACKENDS):
        factory = load_plugin(REPLAY_BACKENDS, name)
        if not callable(factory):
            raise ConfigError(f"replay back-end plug-in {name!r}: names {type(factory).__name__}, not a factory")
        return factory  # type: ignore[no-any-return]
    known = ", ".join(backend_names())
    raise ConfigError(f"backend: unknown back-end {name!r} (known: {known})") from None
