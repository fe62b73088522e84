"""``studio convert``'s own options: :class:`ConvertConfig`, each pipeline field's default, help,
flag and choices declared once in its metadata, and :func:`convert_options`, every option of the
command (the pipeline's, :class:`GraphOptions`', :class:`GraphImportOptions`' and the run's) with
what a source must be to take it: the command line builds its flags from them, and
:func:`check_source_options` refuses an option the source would ignore.

Kept apart from :mod:`studio.convert` (which re-exports it) and free of numpy at import, so that
declaring the command line's options loads no reader; the checks that need a reader's or a
transform's rules import them when a config is made.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from studio.converters.options import HEADING_METHODS, OPTION_NEEDS, GraphImportOptions, GraphOptions, option_help
from studio.converters.registry import get_reader, get_source
from studio.core.errors import ConfigError
from studio.core.option_values import check_option
from studio.core.units import DEFAULT_MAX_MEMORY_GB, MAX_SPLIT_ROBOTS

__all__ = ["ConvertConfig", "ConvertOption", "convert_options", "accepted_options", "check_source_options"]


def _pipeline(
    default: Any,
    help: str,
    *,
    flag: str = "",
    metavar: str = "",
    choices: tuple[str, ...] = (),
    source_has: str = "",
) -> Any:
    """A pipeline field of :class:`ConvertConfig`: its default, help text, command-line flag
    (``--split``; the field's name unless given), for a word option its ``choices`` (checked by
    :class:`ConvertConfig`, listed by ``studio convert --help``) and, for an option only some sources
    take, the attribute of their registry entry that says so (``sightings``), declared once (the CLI
    builds its options from them)."""
    meta = {"help": help, "flag": flag, "metavar": metavar, "choices": choices, "source_has": source_has}
    return field(default=default, metadata=meta)


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
        "Also add an inter-agent loop closure per robot sighting: position from range and "
        "bearing, relative heading from the ground truth with --lc-sigma-rad noise.",
        source_has="sightings",
    )
    """Also turn every robot-to-robot sighting into an inter-agent loop closure
    (:func:`studio.converters.sightings.sighting_closures`): its position is the range and bearing
    measured, its relative heading (unobserved) the ground truth's with ``lc_sigma_rad`` noise."""
    keyframes_at_sightings: bool = _pipeline(
        False,
        "Put a keyframe where each robot sighting was made, on both robots, so each "
        "sighting's keyframes are at its time.",
        source_has="sightings",
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


@dataclass(frozen=True)
class ConvertOption:
    """One option of ``studio convert``: the CLI's flag is built from it, and a source that does not
    take it refuses it (:func:`check_source_options`)."""

    name: str
    """The library's name (a field of a config dataclass, or a keyword of :func:`studio.convert.convert`)."""
    flag: str
    """The flag without its dashes, underscores for hyphens (``body_frame``)."""
    default: Any
    help: str
    metavar: str = ""
    choices: tuple[str, ...] = ()
    synthesize: bool = True
    """Taken when measurements are synthesized along trajectories (a trajectory source, or a config)."""
    graph_import: bool = False
    """Taken by a graph source whose entry names it in ``Source.graph_options``."""
    source_has: str = ""
    """The attribute of the source's registry entry that must be set for the source to take it."""


def convert_options() -> tuple[ConvertOption, ...]:
    """Every option of ``studio convert`` besides its inputs, ``-o``, ``--config``, ``--force``,
    ``--rrd`` and ``--quiet`` (which every source takes), each declared once in its dataclass."""
    imported = {f.name: f for f in dataclasses.fields(GraphImportOptions)}
    out = [
        ConvertOption(
            "agents",
            "agent",
            (),
            "Bag agents: NAME=/odom, NAME=/fix+/heading or NAME=/tf:PARENT:CHILD.",
            "NAME=SPEC",
            source_has="takes_agents",
        )
    ]
    for f in dataclasses.fields(ConvertConfig):
        if "help" in f.metadata:
            m = f.metadata
            out.append(
                ConvertOption(
                    f.name,
                    m["flag"] or f.name,
                    f.default,
                    m["help"],
                    m["metavar"],
                    m["choices"],
                    graph_import=f.name in imported,
                    source_has=m["source_has"],
                )
            )
    out += [ConvertOption(f.name, f.name, f.default, option_help(f.name)) for f in dataclasses.fields(GraphOptions)]
    taken = {o.name for o in out}
    for name, f in imported.items():
        if name not in taken:
            meta = f.metadata
            out.append(ConvertOption(name, name, f.default, meta["help"], "", meta["choices"], False, True))
    help_memory = "Refuse a loop-closure search estimated to need more memory."
    out.append(ConvertOption("max_memory_gb", "max_memory_gb", DEFAULT_MAX_MEMORY_GB, help_memory))
    return tuple(out)


def accepted_options(source: str, *, synthesize: bool) -> frozenset[str]:
    """The options source ``source`` takes: a trajectory source (or any source read through a config)
    the synthesis options its registry entry allows; a graph source the ones its entry names in
    ``graph_options``."""
    src = get_source(source)
    if synthesize or src.read_graph is None:
        return frozenset(
            o.name for o in convert_options() if o.synthesize and (not o.source_has or getattr(src, o.source_has))
        )
    return frozenset(o.name for o in convert_options() if o.graph_import and o.name in src.graph_options)


def _why_not(source: str, name: str, *, synthesize: bool) -> str:
    """Why ``source`` refuses option ``name``: which sources take it."""
    from studio.converters.registry import source_names

    takers = [s for s in source_names() if name in accepted_options(s, synthesize=False)]
    trajectory = [s for s in source_names() if get_source(s).read_graph is None]
    if get_source(source).read_graph is not None and not synthesize and set(takers) <= set(trajectory):
        some = "" if set(takers) == set(trajectory) else f" ({', '.join(takers)})"
        return f"{source} inputs hold their own measurements; {name} is for trajectory sources{some}"
    if not takers:
        return f"no source takes {name}"
    return f"only {', '.join(takers)} {'takes' if len(takers) == 1 else 'take'} {name}"


def check_source_options(
    source: str, given: Mapping[str, Any], *, synthesize: bool, base: Mapping[str, Any] | None = None
) -> None:
    """Refuse an option the source would ignore and an option given without the one it needs
    (``OPTION_NEEDS``: a partition without a split); ``given``: the options the user set, by name,
    ``base``: the values of a config they build on. ConfigError naming the option and the source."""
    accepted = accepted_options(source, synthesize=synthesize)
    for name in given:
        if name not in accepted:
            why = _why_not(source, name, synthesize=synthesize)
            raise ConfigError(f"{name}: studio convert {source} does not take it ({why})", option=name)
    values = {**(base or {}), **given}
    for name, needed in OPTION_NEEDS.items():
        if name in given and name in accepted and not values.get(needed):
            raise ConfigError(
                f"{name}: studio convert {source} takes it only with {needed}", option=name, also=(needed,)
            )
