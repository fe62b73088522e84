"""Optimizer back-ends (layer 3): each method solves a :class:`~studio.solvers.problem.Problem` of
columns and returns a :class:`~studio.solvers.problem.Solution`.

The registry is an explicit dict of :class:`SolveMethod` entries, the whole declaration of a
method: its name, one line of help, the shared :class:`~studio.solvers.options.SolveOptions` it
reads with its own defaults for them, and the class of its own options
(:class:`~studio.solvers.options.DgsOptions` for ``dgs``). ``studio solve --method`` (choices and
help), ``studio solve``'s defaults and per-method flags and ``studio bench``'s per-method options
are built from it; an unknown name raises and lists the known ones. An entry names its back-end by
module and attribute (:class:`~studio.core.lazy.Lazy`), imported when the method is used; the
back-end imports its library when called, and a missing library raises a one-line ConfigError
naming the extra to install (``pip install 'cslam-studio[solve]'``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy
from studio.solvers.options import (
    DEFAULT_MAX_ROUNDS,
    G2O_DEFAULT_ITERATIONS,
    SESYNC_MAX_ITERATIONS,
    CommandOptions,
    DgsOptions,
    SolveOptions,
    option_flag,
)

if TYPE_CHECKING:  # the back-ends' protocol: numpy types, not loaded to declare the registry
    from studio.solvers.problem import Method

__all__ = [
    "METHODS",
    "SolveMethod",
    "method_names",
    "get_method",
    "method_entry",
    "option_names",
    "solve_flag",
    "DEFAULT_METHOD",
]

DEFAULT_METHOD = "gtsam"

#: The shared options of :class:`SolveOptions`, the only names an entry may list or give a default
#: for (its own options are the fields of its ``method_options`` class).
_OPTION_FIELDS = tuple(f.name for f in dataclasses.fields(SolveOptions) if f.name != "own")


@dataclass(frozen=True)
class SolveMethod:
    """One optimizer back-end as the registry declares it."""

    name: str
    solve: Method
    help: str
    """One line for ``studio solve --help`` (what the method does)."""
    options: tuple[str, ...]
    """The shared :class:`SolveOptions` fields the method reads (the others are ignored by it)."""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    """The method's own defaults for some of :attr:`options` (``SolveOptions``' defaults otherwise)."""
    scores_rounds: bool = False
    """A method that works in rounds (dgs): with ground truth, ``solve`` scores the APE after each."""
    gauges: bool = False
    """The method takes pose priors and one held vertex per piece (:mod:`studio.solvers.gauge`);
    the others hold the anchor alone and are given connected graphs only."""
    method_options: type | None = None
    """The class of the method's own options (a frozen dataclass without numpy, its fields' defaults
    the method's; :class:`DgsOptions`), or None: the back-end gets an instance as
    :attr:`SolveOptions.own`. ``studio solve`` has a flag for each field of a built-in method's class."""

    def __post_init__(self) -> None:
        for key in (*self.options, *self.defaults):
            if key not in _OPTION_FIELDS:
                raise ConfigError(
                    f"method {self.name}: {key!r} is not a SolveOptions field (a method's own options "
                    "are the fields of its method_options class)"
                )
        for key in self.defaults:
            if key not in self.options:
                raise ConfigError(f"method {self.name}: a default for {key!r}, which it does not read")
        for key in self.own_option_names():
            if key in _OPTION_FIELDS or key == "own":
                raise ConfigError(f"method {self.name}: its own option {key!r} is a SolveOptions field")

    def own_option_names(self) -> tuple[str, ...]:
        """The fields of the method's own options class (none without one)."""
        if self.method_options is None:
            return ()
        return tuple(f.name for f in dataclasses.fields(self.method_options))

    def option_names(self) -> tuple[str, ...]:
        """Every option the method reads: the shared ones it names, then its own."""
        return (*self.options, *self.own_option_names())

    def own_options_from(self, given: Mapping[str, Any]) -> object:
        """The method's own options with ``given`` (by name) over its class's defaults; None for a
        method without own options. A name the method does not read is refused, naming it."""
        for key in given:
            if key not in self.own_option_names():
                reads = ", ".join(self.option_names()) or "nothing"
                raise ConfigError(f"{key}: method {self.name} does not read it (it reads {reads})", option=key)
        return None if self.method_options is None else self.method_options(**given)

    def default(self, option: str) -> Any:
        """The method's default for ``option`` (its own, else ``SolveOptions``')."""
        if option in self.defaults:
            return self.defaults[option]
        return getattr(SolveOptions(), option)


_GTSAM_OPTIONS = ("optimizer", "init", "max_iterations", "relative_tolerance")

METHODS: dict[str, SolveMethod] = {
    entry.name: entry
    for entry in (
        SolveMethod(
            "gtsam",
            Lazy("studio.solvers.gtsam_method", "solve_gtsam"),
            "chordal guess + GN",
            _GTSAM_OPTIONS,
            gauges=True,
        ),
        SolveMethod(
            "g2o",
            Lazy("studio.solvers.g2o_method", "solve_g2o"),
            "the paper's setup: spanning tree, then GN for exactly --iterations",
            ("init", "max_iterations"),
            {"max_iterations": G2O_DEFAULT_ITERATIONS},
        ),
        SolveMethod(
            "gnc",
            Lazy("studio.solvers.gtsam_method", "solve_gnc"),
            "robust: rejects outlier loop closures",
            _GTSAM_OPTIONS,
            gauges=True,
        ),
        SolveMethod(
            "command",
            Lazy("studio.solvers.command", "solve_command"),
            "an external program",
            (),
            method_options=CommandOptions,
        ),
        SolveMethod(
            "dgs",
            Lazy("studio.solvers.dgs", "solve_dgs"),
            "Distributed Gauss-Seidel: chordal rotations, then poses, each robot its own block, rounds counted",
            ("max_iterations",),
            {"max_iterations": DEFAULT_MAX_ROUNDS},
            scores_rounds=True,
            method_options=DgsOptions,
        ),
        SolveMethod(
            "sesync",
            Lazy("studio.solvers.sesync", "solve_sesync"),
            "SE-Sync: Riemannian staircase on SE-Sync's objective, certified or a suboptimality bound",
            ("max_iterations",),
            {"max_iterations": SESYNC_MAX_ITERATIONS},
        ),
    )
}


def method_names() -> list[str]:
    return list(METHODS)


def method_entry(name: str) -> SolveMethod:
    """The entry of method ``name``: the registry's, else an installed plug-in's (entry point group
    ``studio.solve_methods``, a :class:`SolveMethod`, imported now; :mod:`studio.core.plugins`)."""
    if name in METHODS:
        return METHODS[name]
    from studio.core.plugins import SOLVE_METHODS, load_plugin, plugin_names

    if name not in plugin_names(SOLVE_METHODS):
        known = ", ".join([*METHODS, *plugin_names(SOLVE_METHODS)])
        raise ConfigError(f"method: unknown method {name!r} (known: {known})")
    entry = load_plugin(SOLVE_METHODS, name)
    if not isinstance(entry, SolveMethod):
        raise ConfigError(f"solve method plug-in {name!r}: names {type(entry).__name__}, not a SolveMethod")
    return dataclasses.replace(entry, name=name)


def get_method(name: str) -> Method:
    """The back-end function of method ``name``."""
    return method_entry(name).solve


def option_names() -> tuple[str, ...]:
    """Every option some built-in method reads: the shared ones in :class:`SolveOptions`' order,
    then each method's own in registry order."""
    used = {key for entry in METHODS.values() for key in entry.options}
    own = [key for entry in METHODS.values() for key in entry.own_option_names()]
    return (*(key for key in _OPTION_FIELDS if key in used), *dict.fromkeys(own))


def solve_flag(name: str) -> str:
    """The ``studio solve`` flag of the solve option or keyword ``name`` as its declaration says
    (``max_iterations``: ``--iterations``, ``coarse_size``: ``--coarse``), else ``name`` in kebab case."""
    classes = [SolveOptions, *(e.method_options for e in METHODS.values() if e.method_options is not None)]
    for cls in classes:
        if name in {f.name for f in dataclasses.fields(cls)}:
            return option_flag(cls, name)
    return "--" + name.replace("_", "-")
