"""``studio convert``'s own options: :class:`ConvertConfig`, each pipeline field's default, help,
flag and choices declared once in its metadata (the command line builds its flags from them).

Kept apart from :mod:`studio.convert` (which re-exports it) and free of numpy at import, so that
declaring the command line's options loads no reader; the checks that need a reader's or a
transform's rules import them when a config is made.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from studio.converters.options import HEADING_METHODS, GraphOptions
from studio.converters.registry import get_reader, get_source
from studio.core.errors import ConfigError
from studio.core.option_values import check_option
from studio.core.units import MAX_SPLIT_ROBOTS

__all__ = ["ConvertConfig"]


def _pipeline(default: Any, help: str, *, flag: str = "", metavar: str = "", choices: tuple[str, ...] = ()) -> Any:
    """A pipeline field of :class:`ConvertConfig`: its default, help text, command-line flag
    (``--split``; the field's name unless given) and, for a word option, its ``choices`` (checked by
    :class:`ConvertConfig`, listed by ``studio convert --help``), declared once (the CLI builds its
    options from them)."""
    return field(default=default, metadata={"help": help, "flag": flag, "metavar": metavar, "choices": choices})


def _one_of(choices: tuple[str, ...]) -> str:
    """``a, b or c``."""
    return choices[0] if len(choices) == 1 else ", ".join(choices[:-1]) + " or " + choices[-1]


@dataclass(frozen=True)
class ConvertConfig:
    """What ``studio convert`` did: the source format, its inputs, ``--agent`` specs and the options."""

    source: str
    """A name of :data:`converters.registry.SOURCES` (tum, s3e, airmuseum, bag, ...)."""
    inputs: tuple[str, ...]
    """Paths of the inputs (absolute once resolved by :func:`convert`)."""
    agents: tuple[str, ...] = ()
    """``NAME=SPEC`` strings (bags only)."""
    options: GraphOptions = field(default_factory=GraphOptions)
    orientation: str = _pipeline(
        "auto",
        "keep the trajectories' orientation, derive headings from the motion, or "
        "auto: derive where it carries no information (S3E).",
        choices=("auto", "keep", "derive"),
    )
    """``keep`` the trajectories' orientation, ``derive`` headings from the motion, or ``auto``: derive
    where the orientation carries no information (all the same, e.g. identity)."""
    heading_window_m: float = _pipeline(
        2.0, "Path length over which a derived heading is measured (auto: the longest chord), in metres."
    )
    """Path length [m] over which a derived heading is measured (``chord``; ``auto``'s longest chord)."""
    heading_method: str = _pipeline(
        "auto",
        "Derived headings: auto (turns or chord and its window chosen from each path's rate, speed, "
        "stops and turns; the choice is printed and in report.json), smoothed (central differences of "
        "positions smoothed over about 1 s), turns (smoothed, with turns on the spot decoded from the "
        "tracked point's motion in stops) or chord (the chord over --heading-window-m of path).",
        choices=tuple(HEADING_METHODS),
    )
    """How headings are derived from motion: ``auto`` (``turns`` or ``chord`` and its window chosen
    from each path: :mod:`studio.converters.heading_choice`; ``heading_window_m`` is its longest
    chord), ``smoothed`` (central differences of positions smoothed over about 1 s), ``turns``
    (``smoothed``, with turns on the spot decoded from the tracked point's motion in stops:
    :mod:`studio.converters.spot_turns`) or ``chord`` (the chord over ``heading_window_m`` of path);
    see :func:`studio.converters.transforms.derive_orientation`."""
    body_frames: tuple[str, ...] = _pipeline(
        (),
        "An agent's body axes, e.g. robotA=ufl (the source's own, AirMuseum's, are the default).",
        flag="body_frame",
        metavar="NAME=CODE",
    )
    """``NAME=CODE`` body frames (``robotA=ufl``), besides the source's defaults (AirMuseum's)."""
    split: int = _pipeline(0, "Split each trajectory into this many agents over time (0: off).")
    """Split every trajectory into this many agents over consecutive time windows (0: off)."""
    overlap_s: float = _pipeline(0.0, "Overlap of consecutive --split windows, in seconds.", flag="overlap")
    """Overlap [s] of consecutive split windows."""
    folder_names: str = _pipeline(
        "agents",
        "agents: folders agent1..agentN with agents.json (kollagen's reader); robots: folders named after the robots.",
        choices=("agents", "robots"),
    )
    """``agents``: folders agent1..agentN with agents.json (kollagen's reader needs them); ``robots``."""
    odometry: str = _pipeline(
        "synthetic",
        "synthetic: drawn from the ground truth; real: the source's own odometry (mrclam), "
        "information fitted to its errors against the ground truth.",
        choices=("synthetic", "real"),
    )
    """``synthetic``: odometry drawn from the ground truth (GraphOptions' noise model); ``real``: the
    source's own odometry (MR.CLAM's wheel odometry), information fitted to its errors
    (:mod:`studio.converters.odometry_source`)."""
    odometry_from: tuple[str, ...] = _pipeline(
        (),
        "Real odometry of agent NAME from a second source: NAME=FILE.tum or NAME=BAG:/topic.",
        metavar="NAME=FILE",
    )
    """``NAME=FILE.tum`` or ``NAME=BAG:SPEC``: real odometry for agent NAME from a second source."""
    sightings_as_closures: bool = _pipeline(
        False,
        "Also add an inter-agent loop closure per robot sighting (mrclam): position from range and "
        "bearing, relative heading from the ground truth with --lc-sigma-rad noise.",
    )
    """Also turn every robot-to-robot sighting into an inter-agent loop closure
    (:func:`studio.converters.sightings.sighting_closures`): its position is the range and bearing
    measured, its relative heading (unobserved) the ground truth's with ``lc_sigma_rad`` noise."""
    keyframes_at_sightings: bool = _pipeline(
        False,
        "Put a keyframe where each robot sighting was made, on both robots (mrclam), so each "
        "sighting's keyframes are at its time.",
    )
    """Make the pose nearest in time to every sighting a keyframe of both robots, so that each side of
    a sighting is tied to a keyframe at its own time (offsets of at most half a ground-truth step)."""

    def __post_init__(self) -> None:
        # the readers' and transforms' modules load numpy: imported when a config is made, not declared
        from studio.converters.odometry_source import parse_odometry_spec
        from studio.converters.transforms import body_frame_rotation

        get_reader(self.source)  # unknown names raise and list the known ones
        object.__setattr__(self, "inputs", tuple(str(p) for p in self.inputs))
        object.__setattr__(self, "agents", tuple(self.agents))
        object.__setattr__(self, "body_frames", tuple(self.body_frames))
        object.__setattr__(self, "odometry_from", tuple(self.odometry_from))
        for f in dataclasses.fields(self):
            choices = f.metadata.get("choices") if f.metadata else None
            if choices and getattr(self, f.name) not in choices:
                raise ConfigError(
                    f"{f.name}: expected {_one_of(choices)}, got {getattr(self, f.name)!r}", option=f.name
                )
        if self.odometry == "real" and get_source(self.source).odometry is None:
            raise ConfigError(
                f"odometry: {self.source} ships no odometry of its own; give a second source with "
                "--odometry-from NAME=FILE.tum (or NAME=BAG:/topic)"
            )
        if self.odometry == "real" and self.odometry_from:
            raise ConfigError("odometry: real and odometry_from both name the odometry: give one")
        for spec in self.odometry_from:
            parse_odometry_spec(spec)
        for name in ("sightings_as_closures", "keyframes_at_sightings"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ConfigError(f"{name}: expected true or false, got {value!r}", option=name)
            if value and get_source(self.source).sightings is None:
                raise ConfigError(f"{name}: {self.source} has no robot-to-robot sightings (mrclam has)", option=name)
        if self.sightings_as_closures and not self.options.planar:
            raise ConfigError(
                "sightings_as_closures: a range and a bearing are planar: the closures need planar records "
                "(add --planar)",
                option="sightings_as_closures",
            )
        if self.split != 0 and not (
            not isinstance(self.split, bool) and isinstance(self.split, int) and 2 <= self.split <= MAX_SPLIT_ROBOTS
        ):
            raise ConfigError(
                f"split: expected 0 (off) or an integer in 2..{MAX_SPLIT_ROBOTS}, got {self.split!r}", option="split"
            )
        check_option("heading_window_m", self.heading_window_m, allow_zero=False)
        check_option("overlap_s", self.overlap_s)
        for spec in self.body_frames:
            name, sep, code = spec.partition("=")
            if not sep or not name:
                raise ConfigError(f"body_frames: {spec!r}: expected NAME=CODE (e.g. robotA=ufl)", option="body_frames")
            body_frame_rotation(code)
