"""Optimizer back-ends (layer 3): each method solves a :class:`~studio.solvers.problem.Problem` of
columns and returns a :class:`~studio.solvers.problem.Solution`.

The registry is an explicit dict; an unknown name raises and lists the known ones. A method imports
its library when called, and a missing library raises a one-line ConfigError naming the extra to
install (``pip install 'cslam-studio[solve]'``).
"""

from __future__ import annotations

from studio.core.errors import ConfigError
from studio.solvers.command import solve_command
from studio.solvers.dgs import solve_dgs
from studio.solvers.g2o_method import solve_g2o
from studio.solvers.gtsam_method import solve_gnc, solve_gtsam
from studio.solvers.problem import Method

__all__ = ["METHODS", "method_names", "get_method", "DEFAULT_METHOD"]

DEFAULT_METHOD = "gtsam"

METHODS: dict[str, Method] = {
    "gtsam": solve_gtsam,
    "g2o": solve_g2o,
    "gnc": solve_gnc,
    "command": solve_command,
    "dgs": solve_dgs,
}


def method_names() -> list[str]:
    return list(METHODS)


def get_method(name: str) -> Method:
    try:
        return METHODS[name]
    except KeyError:
        raise ConfigError(f"method: unknown method {name!r} (known: {', '.join(METHODS)})") from None
