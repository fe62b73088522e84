"""The converters' option declarations, without numpy: :class:`GraphOptions` (how trajectories become
a graph, each field's help and unit in its metadata), the heading methods of
:func:`studio.converters.transforms.derive_orientation` and the choices of a graph source's split
(:mod:`studio.converters.graph_split`).

The command line declares its flags from these; they live apart from the maths that uses them so
that declaring ``studio convert``'s options (at every ``studio`` start-up) loads no reader, builder or
numpy. The modules that use them re-export them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from studio.core.errors import ConfigError
from studio.core.option_values import check_option
from studio.core.units import MAX_SPLIT_ROBOTS

__all__ = [
    "GraphOptions",
    "GraphImportOptions",
    "option_help",
    "HEADING_METHODS",
    "PARTITIONS",
    "GROUND_TRUTH_CHOICES",
    "OPTION_NEEDS",
]

#: ``derive_orientation`` methods: ``auto`` (the default: one of the others and its window chosen from
#: the path, :mod:`studio.converters.heading_choice`), ``smoothed``, ``turns`` (``smoothed`` with turns
#: on the spot decoded from the tracked point's motion in stops) and ``chord``.
HEADING_METHODS = ("auto", "smoothed", "turns", "chord")
#: How ``studio convert g2o --split N`` cuts a single-robot graph into robots.
PARTITIONS = ("contiguous", "metis", "time")
#: Where a single g2o file's ground truth comes from (``--ground-truth``).
GROUND_TRUTH_CHOICES = ("auto", "vertices", "none")
#: Options that mean something only with another one set: a partition or an overlap cuts robots
#: only when there is a split into robots (``studio convert`` refuses one given without the other).
OPTION_NEEDS: dict[str, str] = {"partition": "split", "overlap_s": "split"}


def _opt(default: Any, help: str, unit: str = "") -> Any:
    """A :class:`GraphOptions` field: its default, help text and unit, declared once (the CLI and the
    docs read them from here)."""
    return field(default=default, metadata={"help": help, "unit": unit})


def option_help(name: str) -> str:
    """The help text of option ``name`` with its unit, e.g. ``Loop-closure radius R. [m]``."""
    meta = {f.name: f.metadata for f in fields(GraphOptions)}[name]
    return meta["help"] + (f" [{meta['unit']}]" if meta["unit"] else "")


@dataclass(frozen=True)
class GraphOptions:
    """How trajectories become a graph. Each field's help and unit are in its metadata
    (:func:`option_help`); a value of 0 turns an optional rule off where noted."""

    seed: int = _opt(
        0,
        "Seed of every random draw (noise, loop-closure selection, outliers): same inputs, "
        "options and seed give byte-identical output.",
    )
    keyframe_distance: float = _opt(1.0, "A keyframe every this much path (0: off).", "m")
    keyframe_angle: float = _opt(15.0, "A keyframe every this much accumulated rotation (0: off).", "deg")
    keyframe_time: float = _opt(0.0, "A keyframe every this long (0: off).", "s")
    max_gap: float = _opt(1.0, "Stamps further apart than this are a ground-truth gap: bridged and reported.", "s")
    gap_sigma_m_per_s: float = _opt(0.05, "Extra translation std dev of a gap-bridging edge per second of gap.", "m/s")
    gap_sigma_rad_per_s: float = _opt(
        0.005, "Extra rotation std dev of a gap-bridging edge per second of gap.", "rad/s"
    )
    odo_sigma_m_per_m: float = _opt(0.02, "Odometry translation std dev per metre travelled, on each axis.", "m/m")
    odo_sigma_rad_per_rad: float = _opt(0.02, "Odometry rotation std dev per radian turned, on each axis.", "rad/rad")
    odo_sigma_rad_per_m: float = _opt(0.001, "Odometry rotation std dev per metre travelled.", "rad/m")
    odo_sigma_min_m: float = _opt(0.002, "Odometry translation std dev floor.", "m")
    odo_sigma_min_rad: float = _opt(0.0005, "Odometry rotation std dev floor.", "rad")
    lc_radius: float = _opt(2.0, "Loop-closure radius R.", "m")
    lc_prob_intra: float = _opt(
        0.5,
        "Intra-agent loop-closure probability p at distance 0 "
        "(a pair at distance d is accepted with p exp(-5 (d/R)^2)).",
    )
    lc_prob_inter: float = _opt(0.5, "Inter-agent loop-closure probability p at distance 0.")
    lc_min_time: float = _opt(30.0, "Intra-agent pairs must be at least this far apart in time.", "s")
    lc_min_index: int = _opt(10, "Intra-agent pairs must be at least this many keyframes apart.")
    lc_max_heading: float = _opt(
        0.0, "Heading compatibility: the x axes of both poses within this angle (0: off).", "deg"
    )
    rendezvous: float = _opt(0.0, "Inter-agent pairs must be within this time of each other (0: any time).", "s")
    lc_sigma_m: float = _opt(0.05, "Loop-closure translation noise std dev, on each axis.", "m")
    lc_sigma_rad: float = _opt(0.01, "Loop-closure rotation noise std dev, on each axis.", "rad")
    outlier_fraction: float = _opt(
        0.0,
        "Fraction of accepted loop closures turned into outliers (a wrong vertex), in [0, 1); listed in outliers.txt.",
    )
    planar: bool = _opt(False, "Project to SE(2) (x, y, yaw) and write 2D records.")

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            key = f.name
            if f.name == "planar":
                if not isinstance(v, bool):
                    raise ConfigError(f"{key}: expected true or false, got {v!r}", option=key)
                continue
            if f.name in ("seed", "lc_min_index"):
                if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                    raise ConfigError(f"{key}: expected a non-negative integer, got {v!r}", option=key)
                continue
            check_option(key, v)
            object.__setattr__(self, f.name, float(v))  # 3 and 3.0 give the same convert.json
        if self.lc_radius <= 0:
            raise ConfigError("lc_radius: must be > 0", option="lc_radius")
        if self.max_gap <= 0:
            raise ConfigError("max_gap: must be > 0", option="max_gap")
        for name in ("lc_prob_intra", "lc_prob_inter"):
            if getattr(self, name) > 1:
                raise ConfigError(f"{name}: a probability must be <= 1", option=name)
        if self.outlier_fraction >= 1:
            raise ConfigError("outlier_fraction: must be < 1", option="outlier_fraction")
        if self.lc_max_heading > 180:
            raise ConfigError("lc_max_heading: must be <= 180 degrees", option="lc_max_heading")


def _import(default: Any, help: str, *, choices: tuple[str, ...] = ()) -> Any:
    """A :class:`GraphImportOptions` field: its default, help and choices, declared once (the CLI
    builds its flags from them)."""
    return field(default=default, metadata={"help": help, "choices": choices})


@dataclass(frozen=True)
class GraphImportOptions:
    """How a graph source's graph becomes the dataset's (``studio convert g2o`` options). A source
    reads the fields its registry entry names (``Source.graph_options``)."""

    split: int = _import(0, "Split a single-robot graph into this many robots (0: keep its robots).")
    """Split a single-robot graph into this many robots (0: keep its robots)."""
    partition: str = _import(
        "contiguous",
        "With --split: contiguous (DPGO's split), metis (balanced, fewest cut edges) or time.",
        choices=PARTITIONS,
    )
    """contiguous (DPGO's split), metis (balanced, fewest cut edges) or time (equal time windows)."""
    overlap_s: float = _import(0.0, "Overlap of consecutive --split windows, in seconds.")
    """Overlap [s] of consecutive time windows (``partition="time"``)."""
    ground_truth: str = _import(
        "auto",
        "auto (<stem>_GT.tum beside the file), vertices (the file's vertices; initial estimate from the "
        "odometry) or none.",
        choices=GROUND_TRUTH_CHOICES,
    )
    """Single g2o files: ``auto`` reads ``<stem>_GT.tum`` beside the file where there is one;
    ``vertices`` takes the file's vertices as the ground truth (synthetic graphs) and composes the
    initial estimate along the odometry; ``none``."""

    def __post_init__(self) -> None:
        if self.split != 0 and not (
            not isinstance(self.split, bool) and isinstance(self.split, int) and 2 <= self.split <= MAX_SPLIT_ROBOTS
        ):
            raise ConfigError(
                f"split: expected 0 (off) or an integer in 2..{MAX_SPLIT_ROBOTS}, got {self.split!r}", option="split"
            )
        if self.partition not in PARTITIONS:
            raise ConfigError(f"partition: expected one of {', '.join(PARTITIONS)}, got {self.partition!r}")
        if self.ground_truth not in GROUND_TRUTH_CHOICES:
            raise ConfigError(
                f"ground_truth: expected one of {', '.join(GROUND_TRUTH_CHOICES)}, got {self.ground_truth!r}"
            )
        check_option("overlap_s", self.overlap_s)
        if self.partition != PARTITIONS[0] and not self.split:
            raise ConfigError(f"partition: {self.partition} needs a split into robots (split)", option="partition")
        if self.overlap_s and not self.split:  # it would be silently ignored: nothing is cut
            raise ConfigError("overlap_s: an overlap needs a split into robots (split)", option="overlap_s")
