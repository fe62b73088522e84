"""``studio convert`` as a library function: sources in, a multi-g2o dataset out (atomically).

The dataset folder ``OUT`` holds::

    OUT/
    ├── agentK/posegraph.g2o, agentK/agentK_GT.tum     # 3D records (2D with planar=True); real stamps
    ├── agents.json                                    # agentK -> robot name and source file
    ├── inter_agent_lc.dat                             # full precision (%.17g)
    ├── convert.json                                   # every option and the seed: --config reproduces OUT
    ├── report.json                                    # origin, agents, gaps, counts, warnings
    └── outliers.txt                                   # the loop closures that are outliers (ground truth)

Between reading and building, trajectories may be re-expressed in FLU body axes (``body_frames``;
by default the source entry's ``body_frames``: AirMuseum's robots), given headings from their motion when their orientation carries no
information (``orientation``: S3E's RTK ground truth), and split into several agents (``split``,
``overlap_s``). Agent folders are ``agent1..agentN`` (kollagen's reader needs them) with the robots'
names in ``agents.json``, or named after the robots with ``folder_names="robots"``.

Everything is written in a staging folder beside ``OUT`` and renamed into place at the end; an
existing ``OUT`` is replaced only with ``force``.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from studio.convert_config import ConvertConfig, check_source_options
from studio.converters.build import OUTLIER_KIND, BuildResult, GraphOptions, build_graph
from studio.converters.heading_choice import HeadingChoice, choose_heading_method
from studio.converters.odometry_source import (
    OdometryFit,
    apply_odometry_sources,
    parse_odometry_spec,
    read_odometry_sources,
)
from studio.converters.options import GraphImportOptions
from studio.converters.registry import check_inputs, get_reader, get_source, guess_source, source_names
from studio.converters.sightings import (
    Sightings,
    SightingsFit,
    resolve_sightings,
    sighting_closures,
    sighting_stamps,
    with_sighting_closures,
)
from studio.converters.transforms import (
    apply_body_frame,
    derive_orientation,
    orientation_is_uninformative,
    split_trajectory,
)
from studio.core.errors import ConfigError, FormatError, OutputError
from studio.core.model import PoseGraph, RangeBearing
from studio.core.option_values import check_option
from studio.core.trajectory import Trajectory
from studio.core.types import PathLike
from studio.core.units import DEFAULT_MAX_MEMORY_GB
from studio.graph_import import ImportResult, import_graph
from studio.io.atomic import check_not_overlapping, staged_outputs
from studio.io.input_files import read_input_bytes
from studio.io.multig2o import write_multi_g2o
from studio.io.outliers_txt import write_outliers_txt
from studio.io.range_bearing import RANGE_BEARING_NAME, write_range_bearing
from studio.io.strict_json import dumps_strict, unique_keys
from studio.io.textfmt import write_text
from studio.runtime.progress import Progress

__all__ = [
    "ConvertConfig",
    "ConvertResult",
    "convert",
    "convert_with_options",
    "read_convert_config",
    "convert_config_to_json",
    "pipeline_flags",
    "CONFIG_NAME",
]

CONFIG_NAME = "convert.json"
_FORMAT = "studio-convert/1"
_OPTION_FIELDS = [f.name for f in dataclasses.fields(GraphOptions)]


@dataclass(frozen=True, eq=False)
class ConvertResult:
    config: ConvertConfig
    dataset_dir: Path
    trajectories: tuple[Trajectory, ...]
    build: BuildResult
    warnings: tuple[str, ...]
    rrd_path: Path | None = None
    """``OUT/<name>.rrd`` inside the dataset folder, or None when no recording was asked for."""
    orientation: dict[str, str] = field(default_factory=dict)
    """Agents whose headings were derived from their motion (value ``"derived from motion"``)."""
    odometry_fits: tuple[OdometryFit, ...] = ()
    """The noise model fitted to each agent's real odometry (empty: synthetic odometry)."""
    range_bearing: RangeBearing | None = None
    """Agent-to-agent sightings (``range_bearing.txt``), where the source has them."""
    sightings_fit: SightingsFit | None = None
    heading_choices: dict[str, HeadingChoice] = field(default_factory=dict)
    """Per trajectory whose headings ``heading_method="auto"`` derived, the method it chose and why."""


#: The pipeline's own keys of convert.json (besides the source, inputs, agents and graph options).
_PIPELINE_FIELDS = tuple(f.name for f in dataclasses.fields(ConvertConfig) if "help" in f.metadata)


def pipeline_flags() -> dict[str, str]:
    """Each pipeline field's command-line flag without the dashes' prefix (``overlap_s`` -> ``overlap``)."""
    return {f.name: f.metadata["flag"] or f.name for f in dataclasses.fields(ConvertConfig) if "help" in f.metadata}


#: Pipeline fields that are lists in convert.json.
_TUPLE_FIELDS = ("body_frames", "odometry_from")
#: Pipeline keys written to convert.json only when they differ from their default (so the files of
#: a conversion that does not use them stay as they were).
_OMITTED_AT_DEFAULT: dict[str, Any] = {
    "odometry": "synthetic",
    "odometry_from": (),
    "heading_method": "auto",
    "sightings_as_closures": False,
    "keyframes_at_sightings": False,
}


def convert_config_to_json(cfg: ConvertConfig) -> dict[str, Any]:
    out: dict[str, Any] = {
        "format": _FORMAT,
        "source": cfg.source,
        "inputs": list(cfg.inputs),
        "agents": list(cfg.agents),
    }
    out.update(dataclasses.asdict(cfg.options))
    for key in _PIPELINE_FIELDS:
        value = getattr(cfg, key)
        if key in _OMITTED_AT_DEFAULT and value == _OMITTED_AT_DEFAULT[key]:
            continue  # keys added later: files of conversions that do not use them stay as they were
        out[key] = list(value) if isinstance(value, tuple) else value
    return out


def config_from_mapping(data: Mapping[str, Any], where: str = "config") -> ConvertConfig:
    """A config from a JSON object; unknown keys are rejected with a hint."""
    known = {"format", "source", "inputs", "agents", *_OPTION_FIELDS, *_PIPELINE_FIELDS}
    for key in data:
        if key not in known:
            hint = difflib.get_close_matches(key, sorted(known), n=1)
            raise ConfigError(f"{where}: unknown key {key!r}" + (f" (did you mean {hint[0]!r}?)" if hint else ""))
    if data.get("format", _FORMAT) != _FORMAT:
        raise ConfigError(f"{where}: format {data['format']!r} is not {_FORMAT!r}")
    if "source" not in data:
        raise ConfigError(f"{where}: missing key 'source'")
    for key in ("inputs", "agents", *_TUPLE_FIELDS):
        if not isinstance(data.get(key, []), list) or not all(isinstance(x, str) for x in data.get(key, [])):
            raise ConfigError(f"{where}: {key!r} must be a list of strings")
    opts = {k: data[k] for k in _OPTION_FIELDS if k in data}
    try:
        options = GraphOptions(**opts)
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None
    extra: dict[str, Any] = {
        k: (tuple(data[k]) if k in _TUPLE_FIELDS else data[k]) for k in _PIPELINE_FIELDS if k in data
    }
    try:
        return ConvertConfig(
            str(data["source"]), tuple(data.get("inputs", [])), tuple(data.get("agents", [])), options, **extra
        )
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None


def read_convert_config(path: PathLike) -> ConvertConfig:
    path = Path(path)
    try:
        text = read_input_bytes(path).decode("utf-8")  # a FIFO or device: refused, never waited on
    except FormatError as err:
        raise ConfigError(str(err)) from None
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: cannot read ({err})") from None
    try:
        data = json.loads(text, object_pairs_hook=unique_keys)
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    except ValueError as err:  # a key given twice: the decoder would keep the last silently
        raise ConfigError(f"{path}: not valid JSON ({err})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a JSON object")
    return config_from_mapping(data, str(path))


def _resolve_inputs(cfg: ConvertConfig) -> ConvertConfig:
    inputs = []
    for p in cfg.inputs:
        path = Path(p)
        if not path.exists():
            raise FormatError(f"{p}: no such file or folder")
        inputs.append(str(path.resolve()))
    odometry_from = []
    for spec in cfg.odometry_from:
        name, path_text, bag_spec = parse_odometry_spec(spec)
        path = Path(path_text)
        if not path.exists():
            raise FormatError(f"{path_text}: no such file or folder (--odometry-from {spec})")
        odometry_from.append(f"{name}={path.resolve()}" + (f":{bag_spec}" if bag_spec else ""))
    return dataclasses.replace(cfg, inputs=tuple(inputs), odometry_from=tuple(odometry_from))


def _report(
    result_build: BuildResult, trajs: Sequence[Trajectory], warnings: Sequence[str], orientation: Mapping[str, str]
) -> dict[str, Any]:
    g = result_build.graph
    return {
        "origin_xyz": [float(v) for v in result_build.origin_xyz],
        "agents": [
            {
                "name": a.name,
                "folder": f"agent{k + 1}",
                "source": t.source,
                "poses_in": len(t),
                "keyframes": a.num_poses,
                "orientation": orientation.get(a.name, "as given"),
                "first_stamp_ns": int(a.stamps_ns[0]),
                "last_stamp_ns": int(a.stamps_ns[-1]),
                "odometry": len(a.odometry),
                "intra_loop_closures": len(a.loop_closures),
            }
            for k, (a, t) in enumerate(zip(g.agents, trajs))
        ],
        "gaps": [
            {
                "agent": gap.agent,
                "vertex": gap.vertex,
                "start_ns": gap.start_ns,
                "end_ns": gap.end_ns,
                "seconds": gap.seconds,
                "metres": gap.metres,
            }
            for gap in result_build.gaps
        ],
        "counts": {**g.edge_counts(), **result_build.candidates},
        "warnings": list(warnings),
    }


DERIVED = "derived from motion"
#: How report.json names each way of deriving headings.
HEADING_METHOD_TEXT = {
    "smoothed": "smoothed: yaw of central differences of positions box-filtered twice over +-0.5 s; "
    "below 0.02 m/s turning evenly from the heading before the stop to the one after it",
    "turns": "turns: smoothed, and in stops of 1.5 s or more turns on the spot decoded from the tracked "
    "point's motion (its signatures learned from the path; stops without one turn evenly)",
    "chord": "chord: yaw of the chord over {w:g} m of path, held while moving less than a quarter of it",
    "auto": "auto: turns or chord and its window chosen per agent from its positions (heading_choice)",
}


def prepare_trajectories(
    cfg: ConvertConfig, trajs: Sequence[Trajectory]
) -> tuple[list[Trajectory], dict[str, str], dict[str, HeadingChoice]]:
    """Body frames, derived headings and the split, in that order (see the module docstring).

    Returns the trajectories to build, per agent whose headings were derived ``DERIVED``, and per
    trajectory whose headings ``auto`` derived (before the split) what it chose."""
    defaults = get_source(cfg.source).body_frames  # the source's own (AirMuseum's robots)
    frames = {t.name: defaults[t.name.lower()] for t in trajs if t.name.lower() in defaults}
    if cfg.options.planar:  # body frames the datasets state (EuRoC's IMU), for the yaw of the heading
        from studio.converters.planar_checks import default_planar_body_frame

        frames.update({t.name: code for t in trajs if (code := default_planar_body_frame(cfg.source, t))})
    names = {t.name for t in trajs}
    for spec in cfg.body_frames:
        name, _, code = spec.partition("=")
        if name not in names:
            raise ConfigError(
                f"body_frames: {spec}: no agent {name!r} (agents: {', '.join(sorted(names))})", option="body_frames"
            )
        frames[name] = code
    out = [apply_body_frame(t, frames[t.name]) if t.name in frames and frames[t.name] != "flu" else t for t in trajs]
    orientation = {}
    choices = {}
    derived = []
    for t in out:
        if cfg.orientation == "derive" or (cfg.orientation == "auto" and orientation_is_uninformative(t)):
            method, window_m, smooth_s = cfg.heading_method, cfg.heading_window_m, 0.0
            if method == "auto":
                choice = choices[t.name] = choose_heading_method(t, cfg.heading_window_m)
                method, window_m, smooth_s = choice.method, choice.window_m, choice.smooth_s
            t = derive_orientation(t, window_m, method, smooth_s=smooth_s)
            orientation[t.name] = DERIVED
        derived.append(t)
    if cfg.split:
        split = []
        for t in derived:
            parts = split_trajectory(t, cfg.split, cfg.overlap_s)
            split += parts
            if t.name in orientation:
                orientation.update({p.name: DERIVED for p in parts})
        derived = split
    return derived, orientation, choices


def convert(
    cfg: ConvertConfig,
    out: PathLike,
    *,
    force: bool = False,
    warn: Callable[[str], None] | None = None,
    progress: Progress | None = None,
    recorder: Callable[[PoseGraph, Path], None] | None = None,
    rrd: bool = True,
    max_memory_gb: float = DEFAULT_MAX_MEMORY_GB,
    inputs: Iterable[PathLike] = (),
) -> ConvertResult:
    """Read ``cfg``'s sources, build the graph and write the dataset folder ``out``.

    Nothing is written when an input is bad, and an existing ``out`` is replaced only with ``force``.
    ``recorder(graph, folder)``, if given, writes extra files (the ``.rrd`` recording) into the
    dataset while it is still in the staging folder, so they appear atomically with the rest; the
    keyframes' real stamps are ``graph.agents[k].stamps_ns``. With ``rrd`` (the default) the Rerun
    recording ``OUT/<name>.rrd`` is written inside the dataset folder the same way. A loop-closure
    search estimated to need more than ``max_memory_gb`` is refused before it starts. ``inputs``:
    files read besides ``cfg``'s (the ``convert.json`` it came from), which ``out`` may not hold.
    """
    out = Path(out).absolute()
    if out.name in ("", ".", ".."):
        raise OutputError(f"{out}: -o must name the dataset folder itself")
    if (out.exists() or out.is_symlink()) and not force:
        raise OutputError(f"{out} already exists (use --force to overwrite)")
    check_option("max_memory_gb", max_memory_gb, allow_zero=False)
    cfg = _resolve_inputs(cfg)
    odometry_inputs = [parse_odometry_spec(spec)[1] for spec in cfg.odometry_from]
    read: list[PathLike] = [*cfg.inputs, *odometry_inputs, *inputs]
    check_not_overlapping([out], read)
    warnings: list[str] = []

    def _warn(msg: str) -> None:
        warnings.append(msg)
        if warn is not None:
            warn(msg)

    check_inputs(cfg.source, cfg.inputs, cfg.agents)
    built = _read_and_build(cfg, _warn, progress, max_memory_gb)
    with staged_outputs(out.parent, [out.name], force=force, inputs=read) as staging:
        ds = staging / out.name
        ds.mkdir()
        _write_dataset(cfg, built, ds, warnings, progress)
        if recorder is not None:
            recorder(built.build.graph, ds)
        if rrd:
            _record_dataset(cfg, built, ds / f"{out.name}.rrd", out.name, progress)
    return ConvertResult(
        cfg,
        out,
        tuple(built.trajectories),
        built.build,
        tuple(warnings),
        out / f"{out.name}.rrd" if rrd else None,
        built.orientation,
        tuple(built.fits),
        built.range_bearing,
        built.sightings_fit,
        heading_choices=built.heading_choices,
    )


@dataclass(frozen=True, eq=False)
class _Built:
    """What :func:`convert` writes: the trajectories built and the graph with its real measurements."""

    trajectories: list[Trajectory]
    orientation: dict[str, str]
    build: BuildResult
    fits: list[OdometryFit]
    range_bearing: RangeBearing | None
    sightings_fit: SightingsFit | None
    heading_choices: dict[str, HeadingChoice]


def _read_and_build(
    cfg: ConvertConfig, warn: Callable[[str], None], progress: Progress | None, max_memory_gb: float
) -> _Built:
    """Read the sources, prepare the trajectories, build the graph and put the real measurements on it."""
    reader = get_reader(cfg.source)
    # numbers that leave the finite range (a quaternion component of 1e200 in a bag) are an error
    # naming the input, never a numpy warning on the terminal; underflow (far loop-closure candidates'
    # acceptance probability) is harmless
    try:
        with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
            read = reader(cfg.inputs, agents=cfg.agents, warn=warn, progress=progress)
            trajs, orientation, choices = prepare_trajectories(cfg, read)
            if cfg.options.planar:
                from studio.converters.planar_checks import planar_warnings

                for t in trajs:
                    for line in planar_warnings(t):
                        warn(line)
            src = get_source(cfg.source)
            held: list[str] = []  # the sightings' warnings wait for the odometry: bad input prints one line
            raw = src.sightings(cfg.inputs, warn=held.append) if src.sightings is not None else None
            forced = (
                sighting_stamps(raw, [t.name for t in trajs])
                if raw is not None and cfg.keyframes_at_sightings
                else None
            )
            build = build_graph(
                trajs, cfg.options, progress=progress, max_memory_gb=max_memory_gb, keyframe_stamps=forced
            )
            build, fits, rb, sight_fit = _real_measurements(cfg, build, read, trajs, (raw, held), warn)
    except FloatingPointError as err:
        raise FormatError(
            f"{', '.join(Path(p).name for p in cfg.inputs)}: numbers out of the finite range "
            f"while reading or building ({err}): a value in the input is absurd"
        ) from None
    return _Built(trajs, orientation, build, fits, rb, sight_fit, choices)


def _write_dataset(
    cfg: ConvertConfig, built: _Built, ds: Path, warnings: Sequence[str], progress: Progress | None
) -> None:
    """The dataset's files in the staged folder ``ds``: the multi-g2o graph, ``convert.json``,
    ``report.json``, the range-bearing measurements (if any) and ``outliers.txt``."""
    build, trajs, orientation = built.build, built.trajectories, built.orientation
    if progress:
        progress("writing", 0, 2, "parts")
    write_multi_g2o(
        build.graph,
        ds,
        records="2d" if cfg.options.planar else "3d",
        precision="full",
        folder_names=cfg.folder_names,  # type: ignore[arg-type]
        sources={t.name: Path(t.source).name for t in trajs},
    )
    if progress:
        progress("writing", 1, 2, "parts")
    write_text(
        ds / CONFIG_NAME,
        (dumps_strict(convert_config_to_json(cfg), f"{ds.name}/{CONFIG_NAME}", indent=2) + "\n").encode(),
    )
    report = _report(build, trajs, warnings, orientation)
    if orientation:
        report["heading_method"] = HEADING_METHOD_TEXT[cfg.heading_method].format(w=cfg.heading_window_m)
    if built.heading_choices:
        report["heading_choice"] = {name: c.to_dict() for name, c in built.heading_choices.items()}
    fits = built.fits
    report["odometry"] = {
        "kind": "real" if fits else "synthetic",
        "source": cfg.odometry if cfg.odometry == "real" else ("odometry_from" if fits else "ground truth"),
        "fits": [f.to_dict() for f in fits],
    }
    rb, sight_fit = built.range_bearing, built.sightings_fit
    if rb is not None and sight_fit is not None:
        write_range_bearing(ds / RANGE_BEARING_NAME, rb)
        report["counts"]["range_bearing"] = len(rb)
        if cfg.sightings_as_closures:
            report["counts"]["sighting_closures"] = len(rb)
        report["range_bearing"] = sight_fit.to_dict()
    write_text(ds / "report.json", (dumps_strict(report, f"{ds.name}/report.json", indent=2) + "\n").encode())
    write_outliers_txt(ds / "outliers.txt", build.outliers, [OUTLIER_KIND] * len(build.outliers))
    if progress:
        progress("writing", 2, 2, "parts")


def _record_dataset(cfg: ConvertConfig, built: _Built, path: Path, name: str, progress: Progress | None) -> None:
    """The dataset's Rerun recording at ``path`` (inside the staged dataset)."""
    from studio.recording.dataset import record_graph

    # input paths reduced to file names: the recording must not depend on where it was made
    shown = convert_config_to_json(cfg)
    shown["inputs"] = [Path(p).name for p in cfg.inputs]
    record_graph(
        built.build.graph,
        path,
        name=name,
        config_json=json.dumps(shown, sort_keys=True),
        outliers=built.build.outliers,
        progress=progress,
        range_bearing=built.range_bearing,
    )


def _real_measurements(
    cfg: ConvertConfig,
    build: BuildResult,
    read: Sequence[Trajectory],
    trajs: Sequence[Trajectory],
    sightings_read: tuple[Sightings | None, list[str]],
    warn: Callable[[str], None],
) -> tuple[BuildResult, list[OdometryFit], RangeBearing | None, SightingsFit | None]:
    """Real odometry (``odometry``, ``odometry_from``) and the source's sightings (read before the
    build, with the warnings their reading gave, said after the odometry's), on the built graph."""
    sightings, held = sightings_read
    src = get_source(cfg.source)
    sources: dict[str, Trajectory] = {}
    if cfg.odometry == "real":
        sources = src.odometry(cfg.inputs, read, warn=warn)
    elif cfg.odometry_from:
        sources = read_odometry_sources(cfg.odometry_from, warn=warn)
        names = {t.name for t in read}
        for name in sources:
            if name not in names:
                raise ConfigError(
                    f"odometry_from: no agent {name!r} (agents: {', '.join(t.name for t in read)})",
                    option="odometry_from",
                )
    fits: list[OdometryFit] = []
    if sources:
        graph, fits = apply_odometry_sources(build.graph, sources)
        build = dataclasses.replace(build, graph=graph)
    for line in held:
        warn(line)
    rb = sight_fit = None
    if sightings is not None:
        rb, sight_fit = resolve_sightings(build.graph, sightings, trajs)
        if cfg.sightings_as_closures and len(rb):
            closures = sighting_closures(
                build.graph, rb, trajs, sigma_heading_rad=cfg.options.lc_sigma_rad, seed=cfg.options.seed
            )
            build = dataclasses.replace(build, graph=with_sighting_closures(build.graph, closures))
    return build, fits, rb, sight_fit


def _merged_config(
    source: str | None, inputs: Sequence[PathLike], given: Mapping[str, Any], base: ConvertConfig | None
) -> ConvertConfig:
    """``base`` (a config read from a file, or the defaults of ``source``) with the options given
    winning: source, inputs and agents where given, each graph and pipeline option by name."""
    if base is None:
        if not source:
            raise ConfigError(
                f"give a FORMAT ({', '.join(source_names())}), inputs whose format can be guessed, or --config"
            )
        base = ConvertConfig(source, ())
    graph = {k: v for k, v in given.items() if k in _OPTION_FIELDS}
    pipeline = {k: v for k, v in given.items() if k in _PIPELINE_FIELDS}
    return dataclasses.replace(
        base,
        source=source or base.source,
        inputs=tuple(str(p) for p in inputs) if inputs else base.inputs,
        agents=tuple(given["agents"]) if "agents" in given else base.agents,
        options=dataclasses.replace(base.options, **graph),
        **pipeline,
    )


def convert_with_options(
    source: str | None,
    inputs: Sequence[PathLike],
    out: PathLike,
    *,
    given: Mapping[str, Any] | None = None,
    config: PathLike | None = None,
    force: bool = False,
    rrd: bool = True,
    warn: Callable[[str], None] | None = None,
    progress: Progress | None = None,
) -> ConvertResult | ImportResult:
    """``studio convert`` as one call. ``source``: a source's name, or None to guess it from the
    inputs (or take it from ``config``); a name that is no source is the first input. ``given``: the
    options the user set, by the names of :func:`studio.convert_config.convert_options` (each refused
    where the source would ignore it, or without the option it needs); ``config``: a convert.json they
    win over. A graph source without a config writes its graph as it is
    (:func:`studio.graph_import.import_graph`); anything else is synthesized (:func:`convert`)."""
    inputs = list(inputs)
    if source is not None and source not in source_names():
        inputs = [source, *inputs]
        source = guess_source(inputs)
    options: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in (given or {}).items()}
    if config is None and source and get_source(source).read_graph is not None:
        check_source_options(source, options, synthesize=False)
        imported = GraphImportOptions(**options)
        return import_graph(source, inputs, out, options=imported, force=force, rrd=rrd, warn=warn, progress=progress)
    base = None if config is None else read_convert_config(config)
    name = source or (base.source if base is not None else None)
    if name:
        values = {} if base is None else {**vars(base), **dataclasses.asdict(base.options)}
        check_source_options(name, options, synthesize=True, base=values)
    memory = options.pop("max_memory_gb", DEFAULT_MAX_MEMORY_GB)
    cfg = _merged_config(source, inputs, options, base)
    # the convert.json read is an input too: an output being replaced may not hold it
    read = [config] if config is not None else []
    return convert(cfg, out, force=force, warn=warn, progress=progress, rrd=rrd, max_memory_gb=memory, inputs=read)
