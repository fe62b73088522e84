"""The communication models of ``studio replay --comms``, by name: the one place a model is declared.

Each :class:`CommsModelEntry` holds what the command line and the error messages say of a model (its
grammar and a help line) and its parser, named by module and attribute
(:class:`~studio.core.lazy.Lazy`) so that building the command line loads no numpy. The parser takes
the text after ``NAME:`` (None when the spec has no colon) and the whole spec for messages, and
returns the model (:mod:`studio.core.comms`), or for a model read from a file the file's path.
A new model is one class and one parser in :mod:`studio.core.comms` and one entry here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy

__all__ = [
    "DEFAULT_COMMS",
    "CommsParser",
    "CommsModelEntry",
    "COMMS_MODELS",
    "get_comms_model",
    "comms_grammar",
    "comms_help",
]


class CommsParser(Protocol):
    """``(argument after NAME:, or None; the whole spec) -> model`` (or a file to read the model from)."""

    def __call__(self, arg: str | None, spec: str) -> Any: ...


@dataclass(frozen=True)
class CommsModelEntry:
    """One communication model as the registry declares it."""

    grammar: str
    """How ``--comms`` writes it (``range:R[,period=T][,p=P][,partners=K][,rounds=N]``)."""
    help: str
    """One line for ``studio replay --help`` and docs/replay.md: who can talk when."""
    parse: CommsParser
    """The parser (a :class:`~studio.core.lazy.Lazy` reference into :mod:`studio.core.comms`)."""


#: What ``studio replay`` runs without ``--comms``.
DEFAULT_COMMS = "always"

COMMS_MODELS: dict[str, CommsModelEntry] = {
    "always": CommsModelEntry(
        "always",
        "every pair at every tick (the centralized upper bound)",
        Lazy("studio.core.comms", "parse_always"),
    ),
    "never": CommsModelEntry(
        "never",
        "no pair ever (the independent lower bound)",
        Lazy("studio.core.comms", "parse_never"),
    ),
    "range": CommsModelEntry(
        "range:R[,period=T][,p=P][,partners=K][,rounds=N]",
        "robots whose ground-truth positions at the same time are within R m (MESA's comm_range); "
        "with period only at the first tick of every T s (MESA's comm_freq = 1/T); with p each contact "
        "succeeds with probability P, drawn from the seed; with partners or rounds, iMESA's model: "
        "N rounds per tick, each taking in-range pairs in a seeded random order of the robots while both "
        "have fewer than K partners, then keeping each with probability P",
        Lazy("studio.core.comms", "parse_range"),
    ),
    "rendezvous": CommsModelEntry(
        "rendezvous:FILE[,partners=K][,rounds=N][,p=P]",
        "Swarm-SLAM's simulated rendezvous file: two robots talk when both are inside one of their windows; "
        "with partners, rounds or p, iMESA's model (as for range) among those pairs",
        Lazy("studio.core.comms", "parse_rendezvous"),
    ),
    "recorded": CommsModelEntry(
        "recorded",
        "each inter-robot closure reaches its robots when it is recorded in the dataset, and its two robots "
        "are in contact only then (for datasets that hold only the closures their communication kept, "
        "such as COSMO-Bench's)",
        Lazy("studio.core.comms", "parse_recorded"),
    ),
}


def comms_grammar() -> str:
    """``always | never | range:R[,period=T][,p=P] | ...``: every model as ``--comms`` writes it."""
    return " | ".join(entry.grammar for entry in COMMS_MODELS.values())


def comms_help() -> str:
    """``--comms``'s help: each model's grammar and help line."""
    return "; ".join(f"{entry.grammar}: {entry.help}" for entry in COMMS_MODELS.values()) + "."


def get_comms_model(name: str, spec: str) -> CommsModelEntry:
    """The entry of model ``name`` (the part of ``spec`` before any colon); an unknown name raises
    and lists every model's grammar."""
    try:
        return COMMS_MODELS[name]
    except KeyError:
        raise ConfigError(f"comms: unknown model {spec!r} (known: {comms_grammar()})") from None
