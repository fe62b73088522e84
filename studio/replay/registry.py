"""The back-ends of ``studio replay``, by name: the one place a back-end is declared
(:mod:`studio.replay.backends` holds their code). Each entry names its factory ``factory(setup) ->
ReplayBackend`` (:mod:`studio.replay.protocol`) by module and attribute
(:class:`~studio.core.lazy.Lazy`), imported when the back-end is used, so the command line lists
the back-ends without loading a solver or numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy

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
    return list(BACKENDS)


def get_backend(name: str) -> BackendFactory:
    try:
        return BACKENDS[name]
    except KeyError:
        raise ConfigError(f"backend: unknown back-end {name!r} (known: {', '.join(BACKENDS)})") from None
