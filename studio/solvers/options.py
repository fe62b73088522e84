"""The options of the optimizer back-ends, without numpy: :class:`SolveOptions`, the few every
method may read, and each method's own options class (:class:`DgsOptions`, :class:`CommandOptions`),
named by its registry entry (:attr:`studio.solvers.SolveMethod.method_options`). The method
registry (:mod:`studio.solvers`) and the command line's ``studio solve`` options are declared from
them at start-up, before any solver or graph is loaded. :mod:`studio.solvers.problem` re-exports
the shared ones.

A field of a method's own class carries its help in its metadata (``help``, a phrase that follows
the method's name: ``dgs: poses per run ...``; ``flag`` where the command line's flag is not the
name in kebab case; ``choices`` for a word): ``studio solve`` has one flag per field of every
built-in method's class, built from these.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields
from typing import Any, Literal, TypeVar, get_args

from studio.core.errors import ConfigError
from studio.core.option_values import check_option
from studio.core.units import MAX_SPLIT_ROBOTS

__all__ = [
    "SolveOptions",
    "DgsOptions",
    "CommandOptions",
    "Optimizer",
    "Init",
    "Schedule",
    "option_flag",
    "G2O_DEFAULT_ITERATIONS",
    "DEFAULT_MAX_ROUNDS",
    "SESYNC_MAX_ITERATIONS",
    "DEFAULT_ROTATION_TOL",
    "DEFAULT_POSE_TOL",
    "DEFAULT_ROTATION_GAMMA",
    "DEFAULT_POSE_GAMMA",
    "PLAIN_POSE_GAMMA",
    "DEFAULT_COARSE_SIZE",
    "DEFAULT_ROTATION_MOMENTUM",
    "DEFAULT_POSE_MOMENTUM",
    "DEFAULT_SCHEDULE",
]

Optimizer = Literal["gn", "lm"]
Init = Literal["chordal", "spanning-tree", "odometry"]
#: DGS's rounds: robots update in turn (Gauss-Seidel) or all from the last round (Jacobi).
Schedule = Literal["gauss-seidel", "jacobi"]
#: DGS's rounds unless told: Gauss-Seidel, as the paper.
DEFAULT_SCHEDULE: Schedule = "gauss-seidel"

#: g2o's default iterations: the paper's setup, 10 Gauss-Newton iterations.
G2O_DEFAULT_ITERATIONS = 10
#: sesync's trust-region iterations at most per rank of the staircase (SE-Sync's ``max_iterations``).
SESYNC_MAX_ITERATIONS = 1000
#: DGS's default rounds at most, both stages together.
DEFAULT_MAX_ROUNDS = 100

#: DGS's rotation stage: stop when no entry of a rotation matrix changes by more than this in a round.
DEFAULT_ROTATION_TOL = 0.2
#: DGS's pose stage: stop a linear system's rounds when no update entry (m, rad) changes by more than this.
DEFAULT_POSE_TOL = 1e-2
#: Over-relaxation of DGS's rotation stage's block updates.
DEFAULT_ROTATION_GAMMA = 1.0
#: Over-relaxation of DGS's pose stage's block updates with the two-level correction (fastest of 1,
#: 1.5 and 1.9 on Multi3500x8: docs/solve.md).
DEFAULT_POSE_GAMMA = 1.5
#: ... and of plain DGS (``coarse_size=0``): fastest of 1, 1.3, 1.6 and 1.9 on kollagen's graphs.
PLAIN_POSE_GAMMA = 1.9
#: Vertices per aggregate of DGS's two-level correction (0: plain DGS).
DEFAULT_COARSE_SIZE = 5
#: Nesterov momentum of DGS's rotation stage's Gauss-Seidel rounds (0: none; Jacobi rounds default to 0).
DEFAULT_ROTATION_MOMENTUM = 0.9
#: Nesterov momentum of DGS's pose stage's rounds (0: none).
DEFAULT_POSE_MOMENTUM = 0.0

T = TypeVar("T")


def _opt(default: Any, help: str, *, flag: str = "", choices: tuple[str, ...] = ()) -> Any:
    """An option field: its default, help, command-line flag (the name in kebab case unless given)
    and word choices, declared once (``studio solve`` builds its flags from them)."""
    return field(default=default, metadata={"help": help, "flag": flag, "choices": choices})


def option_flag(cls: type, name: str) -> str:
    """The ``studio solve`` flag of option ``name`` of options class ``cls`` (``--coarse``,
    ``--iterations``)."""
    flag = next(f for f in fields(cls) if f.name == name).metadata.get("flag") or name
    return "--" + flag.replace("_", "-")


@dataclass(frozen=True)
class SolveOptions:
    """The options a method may read besides its own (each method's registry entry names the ones
    it reads, and its own defaults for them), and the method's own options in :attr:`own`."""

    optimizer: Optimizer = "gn"
    """Gauss-Newton or Levenberg-Marquardt."""
    init: Init = "chordal"
    """Initial guess: chordal relaxation, spanning tree of the measurements, or the dataset's values."""
    max_iterations: int = field(default=20, metadata={"flag": "iterations"})
    """Iterations at most (the ``g2o`` method runs exactly this many, 10 by default as the paper)."""
    relative_tolerance: float = 1e-9
    """Stop when the cost decreases by less than this fraction."""
    own: object = None
    """The method's own options: an instance of its entry's ``method_options`` class (None: that
    class's defaults, or a method without own options). A back-end reads it with :meth:`own_options`."""

    def own_options(self, kind: type[T]) -> T:
        """:attr:`own` as the method's options class ``kind`` (its defaults where :attr:`own` is None)."""
        if self.own is None:
            return kind()
        if not isinstance(self.own, kind):
            raise ConfigError(f"options: expected {kind.__name__}, got {type(self.own).__name__}")
        return self.own

    def to_dict(self) -> dict[str, Any]:
        """The shared options and the method's own, one flat mapping (``solve.json``'s ``options``)."""
        shared = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "own"}
        return shared | ({} if self.own is None else dataclasses.asdict(self.own))  # type: ignore[call-overload]


@dataclass(frozen=True)
class DgsOptions:
    """The ``dgs`` method's own options (its rounds at most are :attr:`SolveOptions.max_iterations`)."""

    robots: int = _opt(0, "on a single .g2o, that many robots of contiguous ids (0: 8).")
    """On a problem without robot identity (a single g2o): that many robots of contiguous vertex ids
    (DPGO's split); 0: 8, or fewer if the graph has fewer vertices."""
    rotation_tol: float = _opt(
        DEFAULT_ROTATION_TOL, "the rotation stage stops when no rotation-matrix entry changes more in a round."
    )
    pose_tol: float = _opt(
        DEFAULT_POSE_TOL, "a pose-stage system stops when no update entry [m, rad] changes more in a round."
    )
    rotation_gamma: float = _opt(
        DEFAULT_ROTATION_GAMMA, "over-relaxation of the rotation stage's block updates (1: plain Gauss-Seidel)."
    )
    pose_gamma: float | None = _opt(
        None,
        f"over-relaxation of the pose stage's block updates (default {DEFAULT_POSE_GAMMA:g} with the "
        f"two-level correction, {PLAIN_POSE_GAMMA:g} for plain DGS).",
    )
    """None: the fastest measured for the two-level correction and for plain DGS (docs/solve.md)."""
    coarse_size: int = _opt(
        DEFAULT_COARSE_SIZE,
        "poses per run that the two-level correction moves rigidly each round (0: plain DGS).",
        flag="coarse",
    )
    """Vertices per aggregate of the two-level correction (each run of that many poses of a robot
    moved rigidly, solved jointly by a coordinator every round); 0: plain DGS."""
    rotation_momentum: float | None = _opt(
        None,
        f"Nesterov momentum of the rotation stage's rounds (default {DEFAULT_ROTATION_MOMENTUM:g} with "
        "gauss-seidel rounds, 0 with jacobi's).",
    )
    """Each robot extrapolates its own block; 0: none; None: measured on kollagen's datasets (docs/replay.md)."""
    pose_momentum: float = _opt(
        DEFAULT_POSE_MOMENTUM,
        "Nesterov momentum of the pose stage's rounds (0: none; it diverges with over-relaxation).",
    )
    schedule: Schedule = _opt(
        DEFAULT_SCHEDULE,
        "robots update in turn (gauss-seidel) or all from the last round (jacobi).",
        choices=get_args(Schedule),
    )

    def __post_init__(self) -> None:
        robots = self.robots
        if isinstance(robots, bool) or not isinstance(robots, int) or not 0 <= robots <= MAX_SPLIT_ROBOTS:
            raise ConfigError(
                f"robots: expected 0 (the default) or a count up to {MAX_SPLIT_ROBOTS}, got {robots!r}",
                option="robots",
            )
        coarse = self.coarse_size
        if isinstance(coarse, bool) or not isinstance(coarse, int) or not 0 <= coarse <= 1_000_000:
            raise ConfigError(
                f"coarse_size: expected 0 (plain DGS) or a count of poses, got {coarse!r}", option="coarse_size"
            )
        for f in fields(self):  # the numbers finite and not negative (dgs_rounds checks their ranges)
            value = getattr(self, f.name)
            if f.name not in ("robots", "coarse_size") and isinstance(value, (bool, int, float)):
                check_option(f.name, value)
        if self.schedule not in get_args(Schedule):
            raise ConfigError(
                f"schedule: expected {' or '.join(get_args(Schedule))}, got {self.schedule!r}", option="schedule"
            )


@dataclass(frozen=True)
class CommandOptions:
    """The ``command`` method's own option: the program to run."""

    command: str = _opt(
        "",
        "the program to run, with {input} and {output}, e.g. 'se-sync {input} {output}'.",
    )
    """The program, with ``{input}`` and ``{output}`` placeholders (the method refuses it empty)."""
