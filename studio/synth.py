"""``studio synth`` as a library function: kollagen config in, kollagen's files out (atomically)."""

from __future__ import annotations

import functools
import json
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from studio.core.errors import ConfigError
from studio.core.model import PoseGraph
from studio.core.option_values import check_option
from studio.core.types import PathLike
from studio.core.units import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_OUTPUT_GB
from studio.generator.config import SynthConfig, aliasing_bytes, estimate_resources
from studio.generator.extended import STUDIO, walk_mode
from studio.generator.kollagen import SingleG2oView
from studio.generator.outliers import PlantedOutliers
from studio.generator.presets import PRESETS, preset, preset_names
from studio.generator.seam import Extra, GeneratedDataset, Generator
from studio.io.atomic import staged_outputs
from studio.io.multig2o import Records, multi_g2o_parts
from studio.io.outliers_txt import write_outliers_txt
from studio.io.singleg2o import write_single_g2o, write_single_tum
from studio.io.strict_json import dumps_strict
from studio.io.synth_config import parse_synth_config, read_synth_config, synth_config_to_json
from studio.runtime.parallel import default_jobs, parallel_map, run_team
from studio.runtime.progress import Progress, report

__all__ = [
    "EXTRA_WRITERS",
    "SynthResult",
    "SeedsResult",
    "parse_seeds",
    "seed_folder_name",
    "synthesize_seeds",
    "load_synth_config",
    "shadowed_preset",
    "synthesize",
    "write_outputs",
    "generate",
    "generate_many",
]


@dataclass(frozen=True, eq=False)
class SynthResult:
    config: SynthConfig
    output: GeneratedDataset
    dataset_dir: Path
    """``OUT/<name>``: the multi-g2o folder."""
    single_dir: Path | None
    """``OUT/<name>_singleg2o``: the single g2o file and the two TUM files (kollagen's extra), or None."""
    config_path: Path
    """``OUT/<name>.config.json``: the effective config (kollagen JSON)."""
    rrd_path: Path | None = None
    """``OUT/<name>.rrd``: the Rerun recording, or None with ``rrd=False``."""
    outliers: PlantedOutliers | None = None
    """The planted outliers (``OUT/<name>/outliers.txt``), when the config's studio block asks for them."""


def shadowed_preset(name: PathLike) -> str | None:
    """When ``name`` is both a preset's name and a file or folder here, the warning saying which is
    used (the file: a path is what the user typed); else None."""
    text = str(name)
    if text.lower() not in PRESETS or not Path(text).exists():
        return None
    return (
        f"{text}: using the file {Path(text).absolute()}, not the preset of that name "
        "(run from another folder, or rename the file, to get the preset)"
    )


def load_synth_config(source: PathLike, *, warn: Callable[[str], None] | None = None) -> SynthConfig:
    """A preset name (``multi3500x8``, ``multi10000x5``) or the path of a kollagen JSON file. A file
    named like a preset is read, never silently: ``warn`` (else Python's warnings) says so."""
    text = str(source)
    shadowed = shadowed_preset(text)
    if shadowed is not None:
        if warn is not None:
            warn(shadowed)
        else:
            warnings.warn(shadowed, stacklevel=2)
    if text.lower() in PRESETS and not Path(text).exists():
        return preset(text)
    path = Path(text)
    if not path.exists():
        raise ConfigError(f"{text}: no such file, and not a preset (presets: {', '.join(preset_names())})")
    return read_synth_config(path, warn=warn)


def _single_g2o_view_parts(
    graph: PoseGraph, view: Extra, folder: Path, name: str, records: Records
) -> list[Callable[[], None]]:
    assert isinstance(view, SingleG2oView)

    def g2o_file() -> None:
        write_single_g2o(
            graph,
            folder / f"{name}.g2o",
            records=records,
            connector_information=view.connector_information,
            odometry_information=view.exact_odometry_information,
        )

    return [
        g2o_file,
        lambda: write_single_tum(graph, folder / f"{name}_GT.tum", ground_truth=True),
        lambda: write_single_tum(graph, folder / f"{name}.tum", ground_truth=False),
    ]


ExtraWriter = Callable[[PoseGraph, Extra, Path, str, Records], list[Callable[[], None]]]
"""``(graph, extra, OUT/<name><suffix>, name, records)``: the independent writes of one extra a
generator offers, into that folder (which exists by then)."""

#: The writer of each kind of extra (see :mod:`studio.generator.seam`).
EXTRA_WRITERS: dict[type, ExtraWriter] = {SingleG2oView: _single_g2o_view_parts}


def write_outputs(
    out: GeneratedDataset,
    parent: Path,
    name: str,
    *,
    multi_records: Records = "3d",
    single_records: Records = "2d",
    jobs: int | None = None,
    progress: Progress | None = None,
) -> None:
    """Write the multi-g2o folder of ``out`` and each extra it offers under ``parent`` (no staging;
    see :func:`synthesize`). ``single_records`` are the g2o records of the extras' files.

    The files are independent writes (each file of an extra, an agent's folder, the inter-agent file),
    shared between processes when ``jobs`` allows. Within a team (:func:`~studio.runtime.parallel.run_team`)
    every process makes the folders (they may come first to them) and writes the files it claims.
    """
    tasks: list[Callable[[], None]] = []
    # the extras' files first: each holds every agent (kollagen's single g2o file is the biggest file),
    # so the processes share out the long writes first and end together on the short ones
    for extra in out.extras:
        folder = parent / f"{name}{extra.suffix}"
        folder.mkdir(exist_ok=True)
        tasks += EXTRA_WRITERS[type(extra)](out.graph, extra, folder, name, single_records)
    multi = parent / name
    multi.mkdir(exist_ok=True)
    tasks += multi_g2o_parts(out.graph, multi, records=multi_records)
    parallel_map(
        lambda k: tasks[k](),
        len(tasks),
        jobs,
        on_done=lambda d, n: report(progress, "synth: writing files", d, n, "files"),
    )


def check_resources(
    config: SynthConfig, *, max_memory_gb: float = DEFAULT_MAX_MEMORY_GB, max_output_gb: float = DEFAULT_MAX_OUTPUT_GB
) -> None:
    """Refuse, before any work, a config whose estimated memory or output size is over the limits."""
    memory, output = estimate_resources(config)
    poses = config.number_of_agents * config.poses_per_agent
    if memory > max_memory_gb * 1e9:
        cause = "loop-closure radii"
        if 2 * aliasing_bytes(config) > memory:  # mostly the aliasing outliers' pattern windows
            side = 2 * config.studio.outliers.aliasing_window * config.step_fragment + 1  # type: ignore[union-attr]
            cause = f"aliasing windows ({side}x{side} cells per pose)"
        raise ConfigError(
            f"{config.name}: {poses:.3g} poses and their {cause} would need about "
            f"{memory / 1e9:.3g} GB of memory, over the {max_memory_gb:g} GB limit (raise it with max_memory_gb)",
            option="max_memory_gb",
        )
    if output > max_output_gb * 1e9:
        raise ConfigError(
            f"{config.name}: {poses:.3g} poses would write about {output / 1e9:.3g} GB, over the "
            f"{max_output_gb:g} GB limit (raise it with max_output_gb)",
            option="max_output_gb",
        )


SMALL_POSES = 2_000
"""A config of fewer poses runs in this process when the caller does not say how many to use:
forking a team and its fresh heap costs more than such a dataset's work (a 723-pose dataset
takes 20-50 ms of CPU time in all)."""


def _small_jobs(config: SynthConfig, jobs: int | None) -> int | None:
    poses = config.number_of_agents * config.poses_per_agent
    return 1 if jobs is None and poses < SMALL_POSES else jobs


def _write_dataset(
    config: SynthConfig,
    folder: Path,
    *,
    multi_records: Records,
    single_records: Records,
    jobs: int | None,
    rrd: bool,
    generator: Generator[SynthConfig],
    progress: Progress | None,
) -> GeneratedDataset:
    """Generate ``config`` and write all its outputs into ``folder`` (a staging folder), as
    :func:`synthesize` describes."""
    name = config.name
    config_name, rrd_name = f"{name}.config.json", f"{name}.rrd"

    def job(leader: bool) -> GeneratedDataset:
        # every process of the team generates the dataset (sharing the parallel steps) and shares
        # out the writes; only this one reports progress
        heard = progress if leader else None
        out = generator.generate(config, jobs=jobs, progress=heard)
        write_outputs(
            out, folder, name, multi_records=multi_records, single_records=single_records, jobs=jobs, progress=heard
        )
        return out

    output = run_team(job, jobs)
    outliers = output.outliers
    if outliers is not None:
        write_outliers_txt(folder / name / "outliers.txt", outliers.rows, outliers.kinds)
    config_json = synth_config_to_json(config)
    with open(folder / config_name, "w", encoding="utf-8") as f:
        f.write(dumps_strict(config_json, config_name, indent=4))
        f.write("\n")
    if rrd:
        from studio.recording.dataset import record_graph

        record_graph(
            output.graph,
            folder / rrd_name,
            name=name,
            config_json=json.dumps(config_json, sort_keys=True),
            outliers=None if outliers is None else outliers.rows,
            progress=progress,
        )
    return output


def _check_request(
    config: SynthConfig, jobs: int | None, max_memory_gb: float, max_output_gb: float, multi_records: Records
) -> None:
    """Refuse bad options and configs over the limits, before any work."""
    check_option("max_memory_gb", max_memory_gb, allow_zero=False)
    check_option("max_output_gb", max_output_gb, allow_zero=False)
    if jobs is not None and (isinstance(jobs, bool) or not 0 <= jobs <= 4096):
        raise ConfigError(f"jobs: expected 0 (the idle cores) .. 4096, got {jobs!r}", option="jobs")
    check_resources(config, max_memory_gb=max_memory_gb, max_output_gb=max_output_gb)
    walk = None if config.studio is None else walk_mode(config.studio.walk)
    if walk is not None and not walk.planar and multi_records == "2d":
        raise ConfigError(
            f"{config.name}: walk {walk.name} is 3D; multi_records 2d cannot hold it", option="multi_records"
        )


def synthesize(
    config: SynthConfig,
    out_dir: PathLike,
    *,
    force: bool = False,
    multi_records: Records = "3d",
    single_records: Records = "2d",
    jobs: int | None = None,
    max_memory_gb: float = DEFAULT_MAX_MEMORY_GB,
    max_output_gb: float = DEFAULT_MAX_OUTPUT_GB,
    rrd: bool = True,
    generator: Generator[SynthConfig] = STUDIO,
    progress: Progress | None = None,
    inputs: Iterable[PathLike] = (),
) -> SynthResult:
    """Generate ``config`` and write it as kollagen's ``generate CONFIG OUT`` does.

    Writes ``OUT/<name>/`` (multi-g2o), ``OUT/<name>_singleg2o/`` and ``OUT/<name>.config.json``,
    and (unless ``rrd`` is false) the Rerun recording ``OUT/<name>.rrd``, all staged and renamed
    into place at the end. Existing outputs are replaced only with ``force``.
    ``jobs`` caps the processes used (default: the idle cores, see
    :func:`~studio.runtime.parallel.default_jobs`); the bytes do not depend on it.
    Configs estimated to need more memory or disk than the limits are refused before any work.
    ``progress`` hears of each agent, agent pair, written part and recorded agent. ``inputs``: the
    files the config came from (its JSON), which no output may hold, even with ``force``.
    """
    config = checked_config(config)  # what the JSON reader refuses, the library refuses too
    _check_request(config, jobs, max_memory_gb, max_output_gb, multi_records)
    out_dir = Path(out_dir)
    name = config.name
    extras = [f"{name}{suffix}" for suffix in generator.extra_suffixes(config)]
    config_name, rrd_name = f"{name}.config.json", f"{name}.rrd"
    names = [name, *extras, config_name] + ([rrd_name] if rrd else [])
    with staged_outputs(out_dir, names, force=force, inputs=inputs) as staging:
        output = _write_dataset(
            config,
            staging,
            multi_records=multi_records,
            single_records=single_records,
            jobs=_small_jobs(config, jobs),
            rrd=rrd,
            generator=generator,
            progress=progress,
        )
    outliers = output.outliers
    single = f"{name}_singleg2o"
    return SynthResult(
        config,
        output,
        out_dir / name,
        out_dir / single if single in extras else None,
        out_dir / config_name,
        out_dir / rrd_name if rrd else None,
        outliers=outliers,
    )


def checked_config(config: object) -> SynthConfig:
    """``config`` as the JSON reader accepts it, so the library refuses what ``studio synth``
    refuses, with the same one-line :class:`ConfigError` naming the field (``config:
    agent_parameters.stepsize: must be positive, got 0.0``): a :class:`SynthConfig` is checked
    field by field as its JSON document; a ``dict`` is read as one, a path as a config file."""
    if isinstance(config, SynthConfig):
        try:
            doc = synth_config_to_json(config)
        except (AttributeError, TypeError) as err:  # a field of the wrong kind, built by hand
            raise ConfigError(f"config: not a valid SynthConfig ({err})") from None
        return parse_synth_config(doc, source="config", name=config.name)
    if isinstance(config, dict):
        return parse_synth_config(config, source="config")
    if isinstance(config, (str, Path)):
        return load_synth_config(config)
    raise ConfigError(
        f"config: expected a SynthConfig, a kollagen JSON document (dict) or a config file's path, "
        f"got {type(config).__name__}"
    )


def _check_jobs(jobs: object) -> None:
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or not 0 <= jobs <= 4096):
        raise ConfigError(f"jobs: expected None or 0 (the idle cores) .. 4096, got {jobs!r}", option="jobs")


def _check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 1 << 63:
        raise ConfigError(f"seed: expected a non-negative integer, got {seed!r}", option="seed")
    return seed


def generate(config: SynthConfig, *, seed: int = 0, jobs: int | None = 1) -> PoseGraph:
    """The dataset of ``config`` as arrays (a :class:`~studio.core.model.PoseGraph`), nothing
    written: the graph ``synthesize`` would write, byte for byte once written. ``seed`` picks a
    replicate (0: the config's own seeds; others as ``studio sweep``'s ``seed``, see
    :func:`~studio.generator.config.replicate_config`). ``jobs=1`` (the default) keeps it in this
    process, which is fastest for small datasets."""
    config = checked_config(config)
    _check_jobs(jobs)
    check_resources(config, max_output_gb=float("inf"))  # nothing is written; memory still counts
    return _generate(config, _check_seed(seed), jobs)


def _generate(config: SynthConfig, seed: int, jobs: int | None) -> PoseGraph:
    from studio.generator.config import replicate_config

    return STUDIO.generate(replicate_config(config, seed), jobs=jobs).graph


def _generate_one(config: SynthConfig, seeds: list[int], k: int) -> PoseGraph:
    return _generate(config, seeds[k], 1)


def generate_many(config: SynthConfig, seeds: Iterable[int], *, jobs: int | None = None) -> Iterator[PoseGraph]:
    """:func:`generate` for each of ``seeds``, in order, lazily: a batch of replicates for a learning
    pipeline (docs/synth.md has a PyTorch-style ``IterableDataset`` over it). With ``jobs`` above 1
    (default: the idle cores) the replicates are made in blocks shared by forked processes; each
    graph does not depend on it."""
    config = checked_config(config)  # every argument checked at the call, not at the first next()
    _check_jobs(jobs)
    check_resources(config, max_output_gb=float("inf"))
    if seeds is None or isinstance(seeds, (str, bytes)) or not hasattr(seeds, "__iter__"):
        raise ConfigError(f"seeds: expected an iterable of non-negative integers, got {seeds!r}", option="seeds")
    seeds = [_check_seed(s) for s in seeds]
    return _generate_many(config, seeds, jobs)


def _generate_many(config: SynthConfig, seeds: list[int], jobs: int | None) -> Iterator[PoseGraph]:
    workers = default_jobs() if jobs is None else jobs
    block = max(1, 4 * workers)
    for start in range(0, len(seeds), block):
        chunk = seeds[start : start + block]
        if workers <= 1 or len(chunk) == 1:
            yield from (_generate(config, s, 1) for s in chunk)
        else:
            yield from parallel_map(functools.partial(_generate_one, config, chunk), len(chunk), workers)


# --------------------------------------------------------------------------------------------------
# Many seeds, one folder each


MAX_SEEDS = 1_000_000
"""The most seeds one ``synthesize_seeds`` call takes."""

SYNC_EVERY = 100
"""``synthesize_seeds`` makes the seeds written so far durable after every this many."""


def parse_seeds(text: str) -> list[int]:
    """``"0..999"`` (both ends included), ``"7"`` or ``"1,5,9"`` as a list of distinct non-negative
    seeds in the order given; anything else is a :class:`ConfigError` naming the option."""
    seeds: list[int] = []
    try:
        for part in text.split(","):
            lo, sep, hi = part.strip().partition("..")
            first, last = int(lo), int(hi) if sep else int(lo)
            if first < 0 or last < first or len(seeds) + last - first + 1 > MAX_SEEDS:
                raise ValueError
            seeds += range(first, last + 1)
    except ValueError:
        raise ConfigError(
            f"seeds: expected FIRST..LAST (0 <= FIRST <= LAST), SEED or SEED,SEED,... with at most "
            f"{MAX_SEEDS:,} of them, got {text!r}",
            option="seeds",
        ) from None
    if len(set(seeds)) != len(seeds):
        raise ConfigError(f"seeds: {text!r} names a seed twice", option="seeds")
    return seeds


def seed_folder_name(seed: int) -> str:
    """``seed0042``: the folder of one seed's outputs (at least four digits, so they sort)."""
    return f"seed{seed:04d}"


@dataclass(frozen=True)
class SeedsResult:
    out_dir: Path
    written: tuple[int, ...]
    """The seeds generated and written by this call."""
    kept: tuple[int, ...]
    """The seeds whose finished folders were already there (a resumed batch) and were kept."""


def synthesize_seeds(
    config: SynthConfig,
    out_dir: PathLike,
    seeds: Sequence[int],
    *,
    force: bool = False,
    multi_records: Records = "3d",
    single_records: Records = "2d",
    jobs: int | None = None,
    max_memory_gb: float = DEFAULT_MAX_MEMORY_GB,
    max_output_gb: float = DEFAULT_MAX_OUTPUT_GB,
    rrd: bool = True,
    generator: Generator[SynthConfig] = STUDIO,
    progress: Progress | None = None,
    inputs: Iterable[PathLike] = (),
) -> SeedsResult:
    """:func:`synthesize` of each replicate in ``seeds`` (see :func:`generate`), in this process,
    into ``OUT/seed<k>/`` (:func:`seed_folder_name`): the same files, byte for byte, as
    ``synthesize(replicate_config(config, k), OUT/seed<k>)``.

    Each seed's folder is staged and renamed into place through the output guard when it is complete,
    so a batch that was killed is resumed by the same call: the seeds whose folders are there (with
    the guard's marker) are kept, unless ``force``, which writes them again. A seed folder that is
    not a studio output is refused, as :func:`synthesize` refuses one. The seeds' files are made
    durable together (one sync of the file system every :data:`SYNC_EVERY` seeds and at the end)
    instead of a dozen fsyncs per seed. Every seed folder to write is checked before the first is
    written (a folder of the user's, an input inside one), so a refusal leaves nothing behind.
    """
    from studio.generator.config import replicate_config
    from studio.io.atomic import check_outputs, is_studio_output, sync_file_system

    config = checked_config(config)
    _check_request(config, jobs, max_memory_gb, max_output_gb, multi_records)
    out_dir = Path(out_dir)
    inputs = list(inputs)
    todo = {seed for seed in seeds if force or not is_studio_output(out_dir / seed_folder_name(seed))}
    if todo:
        check_outputs(out_dir, [seed_folder_name(seed) for seed in sorted(todo)], force=force, inputs=inputs)
    written: list[int] = []
    kept: list[int] = []
    for done, seed in enumerate(seeds):
        folder = seed_folder_name(seed)
        if seed not in todo:
            kept.append(seed)
        else:
            replicate = replicate_config(config, seed)
            with staged_outputs(out_dir, [folder], force=force, inputs=inputs, durable=False) as staging:
                (staging / folder).mkdir()
                _write_dataset(
                    replicate,
                    staging / folder,
                    multi_records=multi_records,
                    single_records=single_records,
                    jobs=_small_jobs(replicate, jobs),
                    rrd=rrd,
                    generator=generator,
                    progress=None,
                )
            written.append(seed)
            if len(written) % SYNC_EVERY == 0:
                sync_file_system(out_dir)
        report(progress, "synth: seeds", done + 1, len(seeds), "seeds")
    if written:
        sync_file_system(out_dir)
    return SeedsResult(out_dir, tuple(written), tuple(kept))
