"""Optimizer back-ends (layer 3): each method solves a :class:`~studio.solvers.problem.Problem` of
columns and returns a :class:`~studio.solvers.problem.Solution`.

The registry is an explicit dict of :class:`SolveMethod` entries, the whole declaration of a
method: its name, one line of help, the :class:`~studio.solvers.problem.SolveOptions` it reads and
its own defaults for them. ``studio solve --method`` (choices and help), ``studio solve``'s
defaults and ``studio bench``'s per-method options are built from it; an unknown name raises and
lists the known ones. An entry names its back-end by module and attribute
(:class:`~studio.core.lazy.Lazy`), imported when the method is used; the back-end imports its
library when called, and a missing library raises a one-line ConfigError naming the extra to
install (``pip install 'cslam-studio[solve]'``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy
from studio.solvers.options import DEFAULT_MAX_ROUNDS, G2O_DEFAULT_ITERATIONS, SESYNC_MAX_ITERATIONS, SolveOptions

if TYPE_CHECKING:  # the back-ends' protocol: numpy types, not loaded to declare the registry
    from studio.solvers.problem import Method

__all__ = [
    "METHODS",
    "SolveMethod",
    "method_names",
    "get_method",
    "method_entry",
    "option_names",
    "DEFAULT_METHOD",
]

DEFAULT_METHOD = "gtsam"

#: The fields of :class:`SolveOptions`, the only names an entry may list or give a default for.
_OPTION_FIELDS = tuple(f.name for f in dataclasses.fields(SolveOptions))


@dataclass(frozen=True)
class SolveMethod:
    """One optimizer back-end as the registry declares it."""

    name: str
    solve: Method
    help: str
    """One line for ``studio solve --help`` (what the method does)."""
    options: tuple[str, ...]
    """The :class:`SolveOptions` fields the method reads (the others are ignored by it)."""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    """The method's own defaults for some of :attr:`options` (``SolveOptions``' defaults otherwise)."""
    scores_rounds: bool = False
    """A method that works in rounds (dgs): with ground truth, ``solve`` scores the APE after each."""
    gauges: bool = False
    """The method takes pose priors and one held vertex per piece (:mod:`studio.solvers.gauge`);
    the others hold the anchor alone and are given connected graphs only."""

    def __post_init__(self) -> None:
        for key in (*self.options, *self.defaults):
            if key not in _OPTION_FIELDS:
                raise ConfigError(f"method {self.name}: {key!r} is not a SolveOptions field")
        for key in self.defaults:
            if key not in self.options:
                raise ConfigError(f"method {self.name}: a default for {key!r}, which it does not read")

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
        SolveMethod("command", Lazy("studio.solvers.command", "solve_command"), "an external program", ("command",)),
        SolveMethod(
            "dgs",
            Lazy("studio.solvers.dgs", "solve_dgs"),
            "Distributed Gauss-Seidel: chordal rotations, then poses, each robot its own block, rounds counted",
            (
                "max_iterations",
                "robots",
                "rotation_tol",
                "pose_tol",
                "rotation_gamma",
                "pose_gamma",
                "rotation_momentum",
                "pose_momentum",
                "coarse_size",
                "schedule",
            ),
            {"max_iterations": DEFAULT_MAX_ROUNDS},
            scores_rounds=True,
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
    """Every option some method reads, in :class:`SolveOptions`' order."""
    used = {key for entry in METHODS.values() for key in entry.options}
    return tuple(key for key in _OPTION_FIELDS if key in used)
