"""The ``studio`` command line: a thin typer layer over the library functions.

This is the only module that imports typer. Every :class:`~studio.core.errors.StudioError` becomes one line
on stderr and exit code 2; heavy imports happen inside the commands so ``studio --help`` stays fast.
"""

from __future__ import annotations

import copy
import enum
import functools
import re
import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any, get_args

import typer

from studio.converters.registry import SOURCES
from studio.core.alignment import Alignment
from studio.core.comms_registry import DEFAULT_COMMS, comms_help
from studio.core.conventions import DEFAULT_CONVENTION, Convention
from studio.core.errors import StudioError
from studio.core.plugins import SOLVE_METHODS, plugin_names
from studio.core.preset_names import PRESET_NAMES
from studio.core.units import DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_OUTPUT_GB
from studio.runtime.progress import terminal_progress
from studio.solvers import DEFAULT_METHOD, METHODS, solve_flag
from studio.solvers.isam_settings import IsamSettings
from studio.solvers.options import Init, Optimizer, SolveOptions

#: Widest help text: click's own cap is 80 columns, whatever the terminal's width.
HELP_MAX_WIDTH = 10_000

app = typer.Typer(
    name="studio",
    rich_markup_mode=None,  # help text is plain: units such as [m] and [rad] stay as written
    help="cslam-studio: collaborative-SLAM pose-graph datasets (kollagen-exact synthesis and more).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # click caps help at 80 columns by default; it measures the terminal (or $COLUMNS) when it
    # formats, so a cap no terminal reaches lets --help use the whole width of the one it is in
    context_settings={"max_content_width": HELP_MAX_WIDTH},
)


def _choice_metavar(values: Iterable[str]) -> str:
    """``<a|b|c>``: a word option's choices (a registry's names), as ``--help`` shows them."""
    return "<" + "|".join(values) + ">"


def _choices(name: str, values: Iterable[str]) -> type[enum.Enum]:
    """A str enum of ``values`` (a registry's names) for a typer option's choices."""
    return enum.Enum(name, [(v, v) for v in values], type=str)  # type: ignore[return-value]


class RecordKind(str, enum.Enum):
    d2 = "2d"
    d3 = "3d"


def _print_version(value: bool) -> None:
    if value:
        from studio.runtime.version import installed_version

        typer.echo(f"studio {installed_version()}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """cslam-studio: collaborative-SLAM pose-graph datasets."""


#: Library options whose flag is not their name in kebab case (``overlap_s`` -> ``--overlap``).
_FLAGS: dict[str, str] = {"max_iterations": solve_flag("max_iterations")[2:]}


def _as_flags(err: StudioError) -> str:
    """The error's text, with the library option it names (``lc_radius: ...``, ``raise it with
    max_memory_gb``, ``pass force=True``) written as the flag the user typed (``--lc-radius: ...``,
    ``--max-memory-gb``, ``use --force``)."""
    text = str(err)
    option = getattr(err, "option", None)
    if not option:
        return text
    for name in (option, *getattr(err, "also", ())):
        flag = "--" + _FLAGS.get(name, name).replace("_", "-")
        text = text.replace(f"pass {name}=True", f"use {flag}")  # a switch: the flag alone
        text = re.sub(rf"(?<![\w./-]){re.escape(name)}(?![\w/-])", flag, text)  # not a path's part
    return text


#: The warnings of the running command, held until it ends (a stack: one list per command).
_HELD_WARNINGS: list[list[str]] = []


def _n(count: int, phrase: str) -> str:
    """``_n(3, "{n} agents")`` is ``3 agents``, ``_n(1, "{n} agents")`` is ``1 agent``: a count in
    its phrase, the phrase's last word singular for one."""
    text = phrase.format(n=count)
    return text[:-1] if count == 1 and text.endswith("s") else text


def _one_line(text: str) -> str:
    """``text`` with its line breaks, NUL and other control characters escaped (``\\n``): a
    message quoting a value the user gave (an option, a name from data) stays one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _output_not_cwd(out: Path) -> None:
    """Refuse ``-o`` naming the current folder or one of its parents (``-o .``) in one line that
    names the option, before the command reads anything (the guard refuses it too, naming only
    the resolved folder)."""
    import os

    from studio.core.errors import OutputError

    here, target = Path(os.path.realpath(os.getcwd())), Path(os.path.realpath(os.path.abspath(out)))
    if target == here or target in here.parents:
        raise OutputError(f"-o {out}: is the current folder or one of its parents; name a new folder inside it")


def cli_errors(func):
    """Turn a StudioError into one line on stderr and exit code 2 (no traceback). The command's
    warnings are held until it ends: printed after it succeeds, dropped when it fails on bad input,
    so that bad input is one line (a reader that warned of skipped records before it met the error
    would otherwise print two)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        held: list[str] = []
        _HELD_WARNINGS.append(held)
        try:
            return func(*args, **kwargs)
        except StudioError as err:
            held.clear()
            typer.echo(f"error: {_one_line(_as_flags(err))}", err=True)
            raise typer.Exit(2) from None
        finally:
            _HELD_WARNINGS.pop()
            for msg in held:
                _warn(msg)

    return wrapper


def _output_columns() -> int | None:
    """The width to fit text tables to: ``$COLUMNS`` where set, a terminal's width, else none (pipes
    and files get the wide table whole)."""
    import os
    import shutil
    import sys

    if os.environ.get("COLUMNS", "").isdigit():
        return int(os.environ["COLUMNS"])
    return shutil.get_terminal_size().columns if sys.stdout.isatty() else None


def _warn(msg: str) -> None:
    """One warning line on stderr; inside a command, held until the command ends (``cli_errors``)."""
    if _HELD_WARNINGS:
        _HELD_WARNINGS[-1].append(msg)
    else:
        typer.echo(f"warning: {msg}", err=True)


@app.command()
@cli_errors
def synth(
    config: str = typer.Argument(
        ...,
        metavar="CONFIG.json|PRESET",
        help=f"A kollagen JSON config, or a built-in preset: {', '.join(PRESET_NAMES)}.",
    ),
    out: Path = typer.Option(..., "-o", "--out", help="Parent folder of the outputs (kollagen's DEST)."),
    force: bool = typer.Option(False, "--force", help="Replace existing outputs."),
    multi_records: RecordKind = typer.Option(
        RecordKind.d3, "--multi-records", help="g2o records of the multi-g2o posegraph files (kollagen: 3d)."
    ),
    single_records: RecordKind = typer.Option(
        RecordKind.d2, "--single-records", help="g2o records of the single g2o file (kollagen: 2d)."
    ),
    jobs: int = typer.Option(
        0, "--jobs", "-j", help="Processes to use (0: the cores not busy with other work, at least 1)."
    ),
    max_memory_gb: float = typer.Option(
        DEFAULT_MAX_MEMORY_GB, "--max-memory-gb", help="Refuse configs estimated to need more memory. [GB]"
    ),
    max_output_gb: float = typer.Option(
        DEFAULT_MAX_OUTPUT_GB, "--max-output-gb", help="Refuse configs estimated to write more. [GB]"
    ),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing on success."),
    rrd: bool = typer.Option(True, "--rrd/--no-rrd", help="Also write the Rerun recording OUT/<name>.rrd."),
    seeds: str | None = typer.Option(
        None,
        "--seeds",
        metavar="FIRST..LAST|SEED,...",
        help="Replicates (sweep's seeds) into OUT/seed<k>/ each, in one process; a killed batch resumes "
        "(finished seed folders are kept). Example: --seeds 0..999",
    ),
) -> None:
    """Generate a multi-agent pose graph exactly as kollagen's `generate CONFIG OUT` does.

    Example: studio synth multi3500x8 -o out/
    """
    _tune_allocator()
    from studio.synth import load_synth_config, parse_seeds, synthesize, synthesize_seeds

    t0 = time.perf_counter()
    cfg = load_synth_config(config, warn=_warn)
    if Path(config).exists():  # a config over the limits is named by its file, not its name alone
        from studio.core.errors import ConfigError
        from studio.core.option_values import check_option
        from studio.synth import check_resources

        check_option("max_memory_gb", max_memory_gb, allow_zero=False)
        check_option("max_output_gb", max_output_gb, allow_zero=False)
        try:
            check_resources(cfg, max_memory_gb=max_memory_gb, max_output_gb=max_output_gb)
        except ConfigError as err:
            raise ConfigError(f"{config}: {str(err).removeprefix(cfg.name + ': ')}", option=err.option) from None
    options: dict[str, Any] = {
        # the config file is an input: an output being replaced may not hold it
        "inputs": [Path(config)] if Path(config).exists() else [],
        "force": force,
        "multi_records": multi_records.value,
        "single_records": single_records.value,
        "jobs": jobs or None,
        "max_memory_gb": max_memory_gb,
        "max_output_gb": max_output_gb,
        "rrd": rrd,
    }
    if seeds is not None:
        with terminal_progress(not quiet) as progress:
            batch = synthesize_seeds(cfg, out, parse_seeds(seeds), progress=progress, **options)
        if not quiet:
            typer.echo(
                f"{cfg.name}: {_n(len(batch.written), '{n} seeds')} written, {len(batch.kept)} kept (finished before) "
                f"in {time.perf_counter() - t0:.2f} s\n  {batch.out_dir}/seed<k>"
            )
        return
    with terminal_progress(not quiet) as progress:
        res = synthesize(cfg, out, progress=progress, **options)
    if not quiet:
        counts = res.output.graph.edge_counts()
        typer.echo(
            f"{cfg.name}: {_n(cfg.number_of_agents, '{n} agents')}, {_n(res.output.graph.num_poses, '{n} poses')}, "
            f"{_n(sum(counts.values()), '{n} constraints')} ({counts['odometry']} odometry, "
            f"{counts['intra_loop_closures']} intra-agent and {counts['inter_loop_closures']} inter-agent "
            f"loop closures"
            + (f", {len(res.outliers.rows)} of them outliers" if res.outliers is not None else "")
            + f") in {time.perf_counter() - t0:.2f} s\n"
            f"  {res.dataset_dir}" + "".join(f"\n  {p}" for p in (res.single_dir, res.rrd_path) if p)
        )


@app.command()
@cli_errors
def record(
    dataset: Path = typer.Argument(..., metavar="DATASET", help="A multi-g2o folder (ours or kollagen's)."),
    out: Path = typer.Option(..., "-o", "--out", help="The recording to write (FILE.rrd)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing recording."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing on success."),
) -> None:
    """Log a multi-g2o dataset with its ground truth to a Rerun recording (open it with `rerun FILE.rrd`).

    Example: studio record out/multi3500x8 -o multi.rrd
    """
    from studio.recording.dataset import record_dataset

    t0 = time.perf_counter()
    with terminal_progress(not quiet) as progress:
        res = record_dataset(dataset, out, force=force, progress=progress)
    if not quiet:
        counts = res.edge_counts
        typer.echo(
            f"{res.path}: {_n(res.num_poses, '{n} poses')}, {counts['odometry']} odometry, "
            f"{counts['intra_loop_closures']} intra-agent and {counts['inter_loop_closures']} inter-agent "
            f"loop closures in {time.perf_counter() - t0:.2f} s"
        )


@app.command()
@cli_errors
def evaluate(
    dataset: Path = typer.Argument(
        ...,
        metavar="DATASET",
        help="A multi-g2o folder with <agent>_GT.tum ground truth, or a single g2o file NAME.g2o with "
        "NAME_GT.tum beside it (kollagen's single view, scored as one agent).",
    ),
    estimate: Path | None = typer.Option(
        None,
        "--estimate",
        "-e",
        help="An optimizer's output: the folder studio solve wrote (or its solve.json), a JRL results file "
        "FILE.jrr (scored with jrl's metrics into FILE.jrm: docs/evaluation.md), a single g2o file "
        "(ids as in the dataset's single g2o), a multi-g2o folder, or a folder of <agent>.tum / "
        "<agent>_*.tum files. Default: the dataset's initial estimate.",
    ),
    align: Alignment = typer.Option(
        Alignment.none,
        "--align",
        help="Alignment before scoring: none, first-pose (each agent's first pose on its "
        "ground truth), se3 or sim3 (Umeyama). See docs/evaluation.md.",
    ),
    align_per_agent: bool = typer.Option(False, "--align-per-agent", help="One alignment per agent, not one for all."),
    rpe_delta_m: float = typer.Option(1.0, "--rpe-delta-m", help="RPE distance in metres of ground-truth path."),
    rpe_delta_nodes: int = typer.Option(1, "--rpe-delta-nodes", help="RPE distance in nodes."),
    tum_max_diff: float = typer.Option(
        0.01, "--tum-max-diff", help="Largest time difference in seconds when matching TUM poses to the ground truth."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
    markdown: bool = typer.Option(False, "--markdown", help="Print a Markdown table."),
    rrd: Path | None = typer.Option(
        None, "--rrd", help="Also write the per-node APE series into this new Rerun recording (.rrd)."
    ),
    force: bool = typer.Option(False, "--force", help="Replace an existing --rrd or .jrm file."),
    jrm: Path | None = typer.Option(
        None,
        "--jrm",
        help="With a .jrr estimate: where to write JRL's metrics (default: beside the .jrr, FILE.jrm).",
    ),
    partial: bool = typer.Option(
        False,
        "--partial",
        help="With a .jrr estimate: score each robot's ATE over the ground-truth poses its solution holds "
        "(jrl's partial results; a replay's robots hold copies only of the poses they were sent).",
    ),
) -> None:
    """Score an estimate against the ground truth with evo: APE and RPE per agent and over all agents.

    Unaligned by default (the kollagen paper's convention: all agents share one frame).

    Example: studio evaluate out/multi3500x8 --estimate out/solved-multi3500x8
    """
    from studio.core.errors import ConfigError
    from studio.evaluate import evaluate as evaluate_dataset
    from studio.evaluate import format_markdown, format_table

    if as_json and markdown:
        raise ConfigError("--json and --markdown exclude each other")
    if estimate is not None and estimate.suffix == ".jrr":
        from studio.jrl_evaluate import evaluate_jrr, format_summary

        scored = evaluate_jrr(dataset, estimate, jrm=jrm, force=force, partial=partial)
        if scored.skipped:
            kinds = ", ".join(f"{n} {t}" for t, n in sorted(scored.skipped.items()))
            _warn(f"{dataset}: the mean residual leaves out factors the studio does not evaluate: {kinds}")
        if as_json:
            import json

            from studio.io.jrm import jrm_document

            typer.echo(json.dumps(jrm_document(scored.summary), indent=2))
        else:
            typer.echo(format_summary(scored.summary) + f"wrote {scored.jrm_path}")
        return
    with terminal_progress() as progress:
        ev = evaluate_dataset(
            dataset,
            estimate=estimate,
            align=align.value,
            align_per_agent=align_per_agent,
            rpe_delta_m=rpe_delta_m,
            rpe_delta_nodes=rpe_delta_nodes,
            tum_max_diff_s=tum_max_diff,
            progress=progress,
        )
        if rrd is not None:
            from studio.evaluate import write_evaluation_recording

            write_evaluation_recording(ev, rrd, force=force, progress=progress)
    for msg in ev.warnings:
        _warn(msg)
    if as_json:
        typer.echo(ev.to_json())
    else:
        typer.echo(format_markdown(ev) if markdown else format_table(ev, width=_output_columns()), nl=False)


@app.command()
@cli_errors
def view(
    rrd: Path = typer.Argument(..., metavar="FILE.rrd", help="A recording (studio record / studio synth)."),
    web: bool = typer.Option(False, "--web", help="Serve the web viewer on 127.0.0.1 instead of a window."),
    port: int = typer.Option(
        None,
        "--port",
        help="Port of the web viewer page (with --web; default 9090, or a free port when 9090 is taken).",
    ),
) -> None:
    """Open a recording in the Rerun viewer (native window, or the web viewer with --web).

    Example: studio view out/multi3500x8.rrd --web
    """
    from studio.recording.viewer import run_viewer, view_command, view_web_command

    if web:
        served = view_web_command(rrd, port=port)
        cmd = served.command
        typer.echo(f"web viewer: open {served.address} in a browser (Ctrl+C stops it)")
        typer.echo(
            f"from another machine: ssh -L {served.web_port}:127.0.0.1:{served.web_port} "
            f"-L {served.grpc_port}:127.0.0.1:{served.grpc_port} THIS_HOST, then open the same address there"
        )
    else:
        cmd = view_command(rrd)
    raise typer.Exit(run_viewer(cmd))


class ThemeChoice(str, enum.Enum):
    dark = "dark"
    light = "light"


@app.command()
@cli_errors
def snapshot(
    rrd: Path = typer.Argument(..., metavar="FILE.rrd", help="A recording (studio record / studio synth)."),
    out: Path = typer.Option(..., "-o", "--out", help="The picture to write (PNG)."),
    node: int = typer.Option(
        None,
        "--node",
        help="Put the time cursor here on the recording's node, iteration, cell or tick timeline (default: the end).",
    ),
    size: str = typer.Option("1400x900", "--size", help="Window size WIDTHxHEIGHT."),
    theme: ThemeChoice = typer.Option(
        ThemeChoice.dark,
        "--theme",
        help="dark, or light: the views on the light theme's white background (the viewer's panels stay dark).",
    ),
    views_only: bool = typer.Option(
        False, "--views-only", help="Only the views: no menu, time panel, side panels or notifications."
    ),
    force: bool = typer.Option(False, "--force", help="Replace an existing picture."),
) -> None:
    """Render a recording to a PNG without a display (needs a Vulkan driver, e.g. mesa-vulkan-drivers).

    Example: studio snapshot out/multi3500x8.rrd -o multi.png --node 400 --views-only
    """
    from studio.recording.viewer import snapshot as render

    with terminal_progress() as progress:
        res = render(
            rrd,
            out,
            node=node,
            window_size=size,
            progress=progress,
            force=force,
            theme=theme.value,
            views_only=views_only,
        )
    typer.echo(f"{res.path}: {res.timeline} {res.time}")


# --- studio convert -----------------------------------------------------------------------------
# Every option of studio.convert_config.convert_options() is a kebab-case flag, with its default,
# help and the sources that take it declared there (GraphOptions in converters/options.py).


@app.command()
@cli_errors
def convert(
    ctx: typer.Context,
    source: str = typer.Argument(
        None,
        metavar="[SOURCE]",
        show_default=False,
        help="Source: "
        + "; ".join(f"{name}: {src.help}" for name, src in SOURCES.items())
        + "; guessed from the inputs when left out and unambiguous.",
    ),
    inputs: list[Path] = typer.Argument(
        None,
        metavar="INPUT...",
        show_default=False,
        help="Per source: " + "; ".join(f"{name}: {src.inputs}" for name, src in SOURCES.items()) + ".",
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The dataset folder to write."),
    config: Path = typer.Option(
        None,
        "--config",
        help="A convert.json: reproduce its dataset (options given here win).",
    ),
    force: bool = typer.Option(False, "--force", help="Replace an existing dataset folder."),
    rrd: bool = typer.Option(True, "--rrd/--no-rrd", help="Also write the Rerun recording OUT/<name>.rrd."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing on success."),
    **options: Any,
) -> None:
    """Turn real trajectories into a multi-g2o dataset with synthetic odometry and loop closures, or
    write a graph source's graph as it is. A source refuses an option it would not use.

    Examples: studio convert tum alpha.txt bob.txt -o out/ds ;
    studio convert s3e S3E_Square_1/ -o out/s3e ;
    studio convert bag run.bag --agent alpha=/alpha/odom --agent bob=/tf:odom:bob/base_link -o out/ds ;
    studio convert --config out/ds/convert.json -o out/ds2
    """
    _output_not_cwd(out)
    _tune_allocator()
    from studio.convert import convert_with_options

    # options typed on the command line win over the --config file, and only they are checked
    # against the source (compared by name: typer may vendor click, so its ParameterSource enum is
    # not imported)
    typed = ("COMMANDLINE", "ENVIRONMENT")
    given = {k: v for k, v in options.items() if getattr(ctx.get_parameter_source(k), "name", "") in typed}
    t0 = time.perf_counter()
    with terminal_progress(not quiet) as progress:
        res = convert_with_options(
            source, inputs or [], out, given=given, config=config, force=force, rrd=rrd, warn=_warn, progress=progress
        )
    if not quiet:
        _print_converted(res, time.perf_counter() - t0)


def _print_converted(res: Any, seconds: float) -> None:
    """What ``studio convert`` made: a graph source's graph, or a synthesized dataset."""
    if not hasattr(res, "build"):
        g = res.graph
        counts = g.edge_counts()
        sightings = f", {len(res.range_bearing)} range-bearing sightings" if res.range_bearing is not None else ""
        typer.echo(
            f"{res.dataset_dir.name}: {_n(len(g.agents), '{n} agents')}, {_n(g.num_poses, '{n} poses')}, "
            f"{_n(counts['odometry'], '{n} odometry edges')}, {counts['intra_loop_closures']} intra-agent and {counts['inter_loop_closures']} inter-agent "
            f"loop closures ({len(res.outliers)} labelled outliers){sightings} from {res.source}, in "
            f"{seconds:.2f} s\n  {res.dataset_dir}" + (f"\n  {res.rrd_path}" if res.rrd_path else "")
        )
        return
    g = res.build.graph
    counts = g.edge_counts()
    typer.echo(
        f"{res.dataset_dir.name}: {_n(len(g.agents), '{n} agents')}, {_n(g.num_poses, '{n} keyframes')}, "
        f"{_n(counts['odometry'], '{n} odometry edges')}, {counts['intra_loop_closures']} intra-agent and "
        f"{counts['inter_loop_closures']} inter-agent loop closures ({res.build.candidates['outliers']} "
        f"outliers), {_n(len(res.build.gaps), '{n} gaps')}, in {seconds:.2f} s\n  {res.dataset_dir}"
        + (f"\n  {res.rrd_path}" if res.rrd_path else "")
    )
    if res.orientation:
        typer.echo(
            f"  headings derived from motion (the orientation carried no information): "
            f"{', '.join(sorted(res.orientation))}"
        )
    for name, choice in sorted(res.heading_choices.items()):
        window = f" over {choice.window_m:.3g} m" if choice.method == "chord" else ""
        typer.echo(f"  heading method for {name}: auto chose {choice.method}{window}: {choice.reason}")
    for gap in res.build.gaps:
        typer.echo(f"  gap: {gap.agent} vertex {gap.vertex}: {gap.seconds:.3f} s, {gap.metres:.2f} m bridged")
    for fit in res.odometry_fits:
        typer.echo(
            f"  real odometry {fit.agent}: drift {fit.drift_m_per_m:.3g} m/m; sigma {fit.sigma_min_m:.3g} m "
            f"+ {fit.sigma_m_per_m:.3g} m/m, {fit.sigma_min_rad:.3g} rad + {fit.sigma_rad_per_m:.3g} rad/m "
            f"+ {fit.sigma_rad_per_rad:.3g} rad/rad (fitted on {fit.edges} edges)"
        )
    if res.sightings_fit is not None:
        sf = res.sightings_fit
        typer.echo(
            f"  range-bearing sightings: {sf.sightings} (sigma {sf.sigma_range_m:.3g} m, "
            f"{sf.sigma_bearing_rad:.3g} rad; {sf.dropped_outside_time_span} outside the ground truth dropped)"
            + (" and as many inter-agent loop closures" if res.config.sightings_as_closures else "")
        )


def _convert_option_help(option: Any) -> str:
    """An option's help, with the sources that take it where not every trajectory source does."""
    from studio.convert_config import accepted_options

    takers = [name for name in SOURCES if option.name in accepted_options(name, synthesize=False)]
    trajectory = [name for name, src in SOURCES.items() if src.read_graph is None]
    return option.help if set(trajectory) <= set(takers) else f"{option.help} (sources: {', '.join(takers)})"


def _with_convert_options(command: Any) -> Any:
    """Give ``command`` one typer option per option of ``studio convert``
    (:func:`studio.convert_config.convert_options`: flag, default, help and choices declared once,
    with the dataclass field they set); the parameter is the library's name, so an error naming it
    (``ConfigError.option``) is shown as its flag."""
    import inspect

    from studio.convert_config import convert_options

    sig = inspect.signature(command)
    params = [p for p in sig.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    hints = dict(getattr(command, "__annotations__", {}))
    for o in convert_options():
        _FLAGS[o.name] = o.flag
        many = isinstance(o.default, tuple)
        annotation: Any = list[str] if many else type(o.default)
        option = typer.Option(
            list(o.default) if many else o.default,
            "--" + o.flag.replace("_", "-"),
            help=_convert_option_help(o),
            metavar=o.metavar or (_choice_metavar(o.choices) if o.choices else None),
        )
        params.append(inspect.Parameter(o.name, inspect.Parameter.KEYWORD_ONLY, default=option, annotation=annotation))
        hints[o.name] = annotation
    command.__signature__ = sig.replace(parameters=params)
    command.__annotations__ = hints
    return command


_with_convert_options(convert)


# --- studio export ------------------------------------------------------------------------------
# The formats are the entries of studio.export_formats.EXPORT_FORMATS (choices and help built from them).


def _export_format_metavar() -> str:
    from studio.export_formats import EXPORT_FORMATS

    return _choice_metavar(EXPORT_FORMATS)


def _export_format_help() -> str:
    from studio.export_formats import EXPORT_FORMATS

    return "; ".join(f"{name}: {spec.help}" for name, spec in EXPORT_FORMATS.items())


@app.command()
@cli_errors
def export(
    dataset: Path = typer.Argument(..., metavar="DATASET", help="A multi-g2o folder (ours or kollagen's)."),
    format: str = typer.Option(
        ..., "--format", "-f", metavar=_export_format_metavar(), help=_export_format_help() + " (docs/formats.md)."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The file (jrl) or folder (dpgo, symbols) to write."),
    name: str = typer.Option(None, "--name", help="The dataset's name inside the files (default: DATASET's)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing output."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing on success."),
) -> None:
    """Write a dataset in a distributed back-end's format: jrl (JRL/MESA), dpgo (DPGO's g2o and
    measurements.csv), symbols (GTSAM-Symbol g2o per robot: DGS, Kimera-Multi).

    Example: studio export out/multi3500x8 --format symbols -o out/multi3500x8_symbols
    """
    _output_not_cwd(out)
    from studio.core.errors import ConfigError
    from studio.export import EXPORT_FORMATS, export_dataset

    if format not in EXPORT_FORMATS:
        raise ConfigError(f"--format: expected one of {', '.join(EXPORT_FORMATS)}, got {format!r}")
    t0 = time.perf_counter()
    res = export_dataset(dataset, out, format=format, force=force, name=name, warn=_warn)
    if not quiet:
        typer.echo(f"{res.path}: {format}, {_n(len(res.files), '{n} files')} in {time.perf_counter() - t0:.2f} s")


# --- studio solve -------------------------------------------------------------------------------
# The methods, their help, defaults and the options each reads come from studio.solvers' registry;
# each field of a built-in method's own options class (DgsOptions ...) is a flag (_with_method_options).

#: Solve methods of installed plug-ins (entry-point names; imported only when used).
_SOLVE_PLUGINS = [name for name in plugin_names(SOLVE_METHODS) if name not in METHODS]
MethodChoice = _choices("MethodChoice", [*METHODS, *_SOLVE_PLUGINS])
OptimizerChoice = _choices("OptimizerChoice", get_args(Optimizer))
InitChoice = _choices("InitChoice", get_args(Init))


def _readers_of(option: str) -> str:
    """The methods that read ``option``, for its help text (``gtsam, gnc``)."""
    return ", ".join(name for name, entry in METHODS.items() if option in entry.option_names())


def _iterations_help() -> str:
    default = SolveOptions().max_iterations
    own = [f"{name}: {e.defaults['max_iterations']}" for name, e in METHODS.items() if "max_iterations" in e.defaults]
    return (
        f"Most iterations (default {default}"
        + "".join(f"; {x}" for x in own)
        + f"; methods: {_readers_of('max_iterations')})."
    )


class DimensionChoice(str, enum.Enum):
    auto = "auto"
    d2 = "2d"
    d3 = "3d"


@app.command()
@cli_errors
def solve(
    ctx: typer.Context,
    dataset: Path = typer.Argument(..., metavar="DATASET", help="A multi-g2o folder or a single .g2o file."),
    out: Path = typer.Option(..., "-o", "--out", help="Folder to write: the estimate and solve.json."),
    method: MethodChoice = typer.Option(  # type: ignore[valid-type]
        DEFAULT_METHOD,
        "--method",
        "-m",
        help=", ".join(f"{name} ({entry.help})" for name, entry in METHODS.items())
        + "".join(f", {name} (plug-in)" for name in _SOLVE_PLUGINS)
        + ".",
    ),
    optimizer: OptimizerChoice = typer.Option(  # type: ignore[valid-type]
        SolveOptions().optimizer,
        "--optimizer",
        help=f"{' or '.join(get_args(Optimizer))} (methods: {_readers_of('optimizer')}).",
    ),
    init: InitChoice = typer.Option(  # type: ignore[valid-type]
        SolveOptions().init, "--init", help=f"Initial guess (methods: {_readers_of('init')})."
    ),
    iterations: int | None = typer.Option(None, solve_flag("max_iterations"), help=_iterations_help()),
    dimension: DimensionChoice = typer.Option(
        DimensionChoice.auto, "--dimension", help="auto: planar 3D data is solved in SE(2)."
    ),
    rrd: Path | None = typer.Option(None, "--rrd", help="Also write the run as a Rerun recording (.rrd)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing OUT (and --rrd file)."),
    as_json: bool = typer.Option(False, "--json", help="Print solve.json instead of a summary."),
    **own: Any,
) -> None:
    """Optimize a dataset's pose graph and write the estimate (multi-g2o or g2o) with solve.json.

    Example: studio solve out/multi3500x8 -o out/multi3500x8-solved ; then
    studio evaluate out/multi3500x8 --estimate out/multi3500x8-solved/estimate --align se3
    """
    _output_not_cwd(out)
    from studio.io.strict_json import dumps_strict
    from studio.solve import solve as run_solve

    # a method's own options typed on the command line, and only they: a method refuses another's
    typed = {k: v for k, v in own.items() if getattr(ctx.get_parameter_source(k), "name", "") in _TYPED}
    res = run_solve(
        dataset,
        out,
        method=method.value,  # type: ignore[attr-defined]
        optimizer=optimizer.value,  # type: ignore[attr-defined]
        init=init.value,  # type: ignore[attr-defined]
        max_iterations=iterations,
        dimension=dimension.value,
        force=force,
        rrd=rrd,
        warn=_warn,
        **typed,
    )
    if as_json:
        typer.echo(dumps_strict(res.to_dict(), "--json", indent=2))
        return
    rejected = "" if res.rejected is None else f", {len(res.rejected)} loop closures rejected"
    typer.echo(
        f"{dataset.name}: {res.method}, {_n(res.iterations, '{n} iterations')}, chi2 {res.chi2_initial:.6g} -> "
        f"{res.chi2_final:.6g} (dead reckoning {res.chi2_dataset:.6g}){rejected}, {res.seconds:.2f} s\n"
        f"  {res.estimate_path}" + ("" if res.rrd_path is None else f"\n  {res.rrd_path}")
    )
    if res.gauge is not None:
        typer.echo(f"  gauge: {res.gauge['note']}")
    if res.outliers is not None:
        o = res.outliers
        typer.echo(
            f"  labelled outliers: {o['rejected_labelled']} of {o['labelled']} rejected; precision "
            + ("-" if o["precision"] is None else f"{o['precision']:.3f}")
            + ", recall "
            + ("-" if o["recall"] is None else f"{o['recall']:.3f}")
        )
    if "rounds" in res.solution.notes:  # a method that works in rounds (dgs) says how they went
        notes = res.solution.notes
        typer.echo(
            f"  dgs: {notes['robots']} robots, {notes['rounds']} rounds ({notes['rotation_rounds']} rotation, "
            f"{notes['pose_rounds']} pose), {notes['bytes_total']:,} bytes sent"
            + ("" if notes["converged"] else " (stopped at the round limit before the tolerances)")
        )
        curve = res.ape_per_round
        if curve is not None:
            typer.echo("  round  APE first-pose mean [m]  APE se3 mean [m]")
            for k, fp, s3 in zip(curve["round"], curve["first_pose_mean_m"], curve["se3_mean_m"]):
                typer.echo(f"  {k:5d}  {fp:23.6f}  {s3:16.6f}")


#: Where an option typed by the user comes from (compared by name: typer may vendor click, so its
#: ParameterSource enum is not imported).
_TYPED = ("COMMANDLINE", "ENVIRONMENT")


def _own_solve_options() -> dict[str, tuple[Any, type, list[str]]]:
    """Each field of the built-in methods' own options classes: the field, its class and the
    methods that read it."""
    import dataclasses

    found: dict[str, tuple[Any, type, list[str]]] = {}
    for name, entry in METHODS.items():
        if entry.method_options is not None:
            for f in dataclasses.fields(entry.method_options):
                found.setdefault(f.name, (f, entry.method_options, []))[2].append(name)
    return found


def _with_method_options(command: Any) -> Any:
    """Give ``command`` one typer option per field of a built-in method's own options class (flag,
    default, help and choices declared on the field, :mod:`studio.solvers.options`); the parameter
    is the field's name, so an error naming it (``ConfigError.option``) is shown as its flag."""
    import inspect
    import typing

    from studio.solvers.options import option_flag

    sig = inspect.signature(command)
    params = [p for p in sig.parameters.values() if p.kind is not inspect.Parameter.VAR_KEYWORD]
    hints = dict(getattr(command, "__annotations__", {}))
    for name, (f, cls, methods) in _own_solve_options().items():
        if name in sig.parameters:
            raise StudioError(f"studio solve: a method's own option {name!r} is one of the command's own parameters")
        choices = f.metadata.get("choices", ())
        annotation: Any = str if choices else typing.get_type_hints(cls)[name]
        flag = option_flag(cls, name)
        _FLAGS[name] = flag[2:]
        option = typer.Option(
            f.default,
            flag,
            help=f"{', '.join(methods)}: {f.metadata['help']}",
            metavar=_choice_metavar(choices) if choices else None,
        )
        params.append(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=option, annotation=annotation))
        hints[name] = annotation
    command.__signature__ = sig.replace(parameters=params)
    command.__annotations__ = hints
    return command


_with_method_options(solve)


def _replay_backend_help() -> str:
    from studio.replay.registry import DEFAULT_BACKENDS, backend_names

    return f"Comma-separated back-ends ({', '.join(backend_names())}); default {','.join(DEFAULT_BACKENDS)}."


#: ISAM2's defaults (``--relinearize-skip`` ...), declared once on :class:`IsamSettings`.
_ISAM = IsamSettings()


@app.command()
@cli_errors
def replay(
    dataset: Path = typer.Argument(
        ..., metavar="DATASET", help="A multi-g2o folder with ground truth, or a .g2o file with NAME_GT.tum beside it."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="Folder to write: schedule, metrics, summary, report, plot."),
    comms: str = typer.Option(DEFAULT_COMMS, "--comms", metavar="<model>", help=comms_help()),
    backend: str = typer.Option("", "--backend", "-b", help=_replay_backend_help()),
    bandwidth: str | None = typer.Option(
        None, "--bandwidth", help="Per link: N/s closures or NB/s bytes; the rest waits for the next contact."
    ),
    step: float = typer.Option(1.0, "--step", help="Tick [s] on which contacts are evaluated."),
    every: int = typer.Option(50, "--every", help="Ticks between checkpoints (metrics and solver batches)."),
    period: float | None = typer.Option(
        None, "--period", help="Clock: pose index x this period [s] instead of the dataset's stamps."
    ),
    comms_seed: int = typer.Option(0, "--comms-seed", help="Seed of the contacts' success draws (range with p)."),
    relinearize_skip: int = typer.Option(
        _ISAM.relinearize_skip, "--relinearize-skip", help="ISAM2: relinearize every N updates."
    ),
    relinearize_threshold: float = typer.Option(
        _ISAM.relinearize_threshold, "--relinearize-threshold", help="ISAM2: delta threshold."
    ),
    polish: bool = typer.Option(
        _ISAM.polish, "--polish/--no-polish", help="End with Gauss-Newton to convergence on what each solver holds."
    ),
    rrd: Path | None = typer.Option(None, "--rrd", help="Also write the replay as a Rerun recording (.rrd)."),
    parquet: bool = typer.Option(False, "--parquet", help="Also write each CSV table as Parquet (needs pyarrow)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing OUT (and --rrd file)."),
    time_limit: float | None = typer.Option(
        None, "--time-limit", help="Seconds a command: back-end may take per checkpoint [s] (default 60)."
    ),
) -> None:
    """Replay a dataset in time: each robot's measurements at their times, inter-agent closures when
    the communication model delivers them, through incremental and distributed back-ends.

    Example: studio replay out/multi3500x8 --comms range:20 -o out/replay-range20
    """
    _output_not_cwd(out)
    from studio.core.option_values import check_count
    from studio.replay import DEFAULT_BACKENDS
    from studio.replay import replay as run_replay

    check_count("--comms-seed", comms_seed, low=0, high=2**63 - 1)  # the library's ``seed``
    names = tuple(b.strip() for b in backend.split(",") if b.strip()) or DEFAULT_BACKENDS
    with terminal_progress() as progress:
        res = run_replay(
            dataset,
            out,
            comms=comms,
            backends=names,
            bandwidth=bandwidth,
            step_s=step,
            every=every,
            period_s=period,
            seed=comms_seed,
            relinearize_skip=relinearize_skip,
            relinearize_threshold=relinearize_threshold,
            polish=polish,
            force=force,
            rrd=rrd,
            parquet=parquet,
            time_limit_s=time_limit,
            progress=progress,
            warn=_warn,
        )
    delivered = int((res.schedule.delivered_tick >= 0).sum())
    lines = [
        f"{dataset.name}: {res.schedule.model}, {len(res.schedule.ticks_ns)} ticks, "
        f"{delivered} of {len(res.schedule.measured_ns)} inter-agent closures delivered"
    ]
    for run in res.runs:
        lines.append(
            f"  {run.name}: APE first-pose {run.ape_team_first_pose_m[-1]:.6f} m, se3 {run.ape_team_se3_m[-1]:.6f} m, "
            f"chi2 {run.chi2_final:.6g} (delivered edges {run.chi2_delivered:.6g}), {run.seconds:.1f} s"
        )
    lines.append(f"  {res.out_dir}" + ("" if res.rrd_path is None else f"\n  {res.rrd_path}"))
    typer.echo("\n".join(lines))


ConventionChoice = _choices("ConventionChoice", get_args(Convention))


@app.command()
@cli_errors
def plugins() -> None:
    """List the replay back-ends and solve methods that installed packages declare as entry points
    (groups studio.replay_backends, studio.solve_methods), without importing them.

    Example: studio plugins ; then studio replay DATASET -b NAME -o out/replay-NAME
    """
    from studio.core.plugins import GROUPS
    from studio.core.plugins import plugins as declared
    from studio.replay.registry import BACKENDS
    from studio.solvers import METHODS as BUILT_IN

    built_in = {group: BACKENDS if kind == "replay back-end" else BUILT_IN for group, kind in GROUPS.items()}
    for group in GROUPS:
        found = declared(group)
        typer.echo(f"{group}: {len(found)} plug-in{'s' * (len(found) != 1)}")
        for p in found:
            shadowed = " (shadowed by the built-in of that name)" if p.name in built_in[group] else ""
            typer.echo(f"  {p.name}  {p.value}  from {p.package}{shadowed}")


@app.command()
@cli_errors
def check(
    dataset: Path = typer.Argument(
        ...,
        metavar="DATASET",
        help="A multi-g2o folder with <agent>_GT.tum ground truth, or a single g2o file NAME.g2o (at "
        "NAME_GT.tum beside it, kollagen's single view, else at the file's own poses).",
    ),
    convention: ConventionChoice = typer.Option(  # type: ignore[valid-type]
        DEFAULT_CONVENTION,
        "--convention",
        help="3D rotation error: g2o (quaternion vector part, ~angle/2) or rotvec (rotation vector, GTSAM).",
    ),
    per_agent: bool = typer.Option(False, "--per-agent", help="One row per agent and class."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (every class, agent and candidate)."),
    certify: Path | None = typer.Option(
        None,
        "--certify",
        metavar="ESTIMATE",
        help="Instead: verify ESTIMATE of DATASET with SE-Sync's certificate (certified globally optimal, "
        "or how far above the optimum it is at most). ESTIMATE: studio solve's output, a multi-g2o or TUM "
        "folder, or a g2o file of the vertices of a single-g2o DATASET.",
    ),
) -> None:
    """Check a dataset's noise model at its ground truth: chi2 per degree of freedom per edge class.

    Example: studio check out/multi3500x8; studio check graph.g2o --certify out/solved
    """
    from studio.check import check as run_check
    from studio.check import format_check

    if certify is not None:
        from studio.certify import certify as run_certify

        cert = run_certify(dataset, certify)
        typer.echo(cert.to_json() if as_json else cert.format())
        return
    report = run_check(dataset, convention=convention.value, warn=_warn)  # type: ignore[attr-defined]
    typer.echo(report.to_json() if as_json else format_check(report, per_agent=per_agent), nl=not as_json or True)


@app.command()
@cli_errors
def bench(
    spec: str = typer.Argument(
        ...,
        metavar="SPEC.toml|SPEC.json|paper",
        help="A bench spec, or the built-in 'paper' (the kollagen paper's Tables I-II).",
    ),
    out: Path = typer.Option(..., "-o", "--out", help="Folder of the bench: datasets, runs, tables, plot."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No progress bar and no table."),
) -> None:
    """Run datasets x cases x methods and write one table (CSV, Parquet, Markdown) and a plot.

    Cells already finished in OUT are not run again. Example: studio bench paper -o out/bench
    """
    _output_not_cwd(out)
    from studio.bench import bench as run_bench
    from studio.bench import format_paper_table, load_bench_spec

    parsed = load_bench_spec(spec)
    with terminal_progress(not quiet) as progress:
        res = run_bench(parsed, out, progress=progress)
    if not quiet:
        align = parsed.alignments[0]
        typer.echo(
            f"APE translation mean over all agents [m], alignment {align} (every alignment: {res.markdown_path})"
        )
        typer.echo(format_paper_table(res.rows, parsed, align), nl=False)
        typer.echo(
            f"{_n(res.computed, '{n} cells')} run, {len([r for r in res.rows if r['method'] != 'odometry']) - res.computed} "
            f"reused\n  {res.markdown_path}\n  {res.csv_path}" + (f"\n  {res.plot_path}" if res.plot_path else "")
        )


@app.command()
@cli_errors
def sweep(
    spec: Path = typer.Argument(..., metavar="SPEC.toml|SPEC.json", help="The sweep: base, grid, steps."),
    out: Path = typer.Option(..., "-o", "--out", help="Folder of the sweep (shared by every worker)."),
    scheduler: str | None = typer.Option(
        None, "--scheduler", help="A Dask scheduler, e.g. tcp://host:8786 (default: a local cluster)."
    ),
    workers: int | None = typer.Option(None, "--workers", help="Workers of the local cluster (default: cores).", min=1),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="No progress bar and no summary."),
) -> None:
    """Run a parameter grid of datasets (and solve/evaluate/check on each) on Dask; one table.

    Finished cells are not run again. Example: studio sweep radius.toml -o out/sweep --workers 2
    """
    _output_not_cwd(out)
    from studio.sweep import load_sweep_spec
    from studio.sweep import sweep as run_sweep

    parsed = load_sweep_spec(spec)
    with terminal_progress(not quiet) as progress:
        res = run_sweep(parsed, out, scheduler=scheduler, workers=workers, progress=progress)
    if not quiet:
        typer.echo(
            f"{parsed.name}: {_n(len(res.rows), '{n} cells')} ({res.computed} run now, {res.failed} failed)\n"
            f"  {res.table_path}\n  {res.markdown_path}" + "".join(f"\n  {p}" for p in res.plot_paths)
        )


@app.command()
@cli_errors
def samples(
    folder: Path = typer.Argument(..., metavar="DIR", help="The folder to write (new; replaced only with --force)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing DIR."),
    quiet: bool = typer.Option(False, "-q", "--quiet", help="Print nothing on success."),
) -> None:
    """Write a small simulated sample in every source's layout (TUM, S3E, AirMuseum, bags, EuRoC,
    KITTI, Kimera-Multi, MR.CLAM), a single g2o graph and a kollagen config, to try the commands on.

    Example: studio samples samples/ ; cd samples ; studio convert mrclam MRCLAM_Dataset1 --planar -o out/mrclam
    """
    from studio.samples import write_samples

    names = write_samples(folder, force=force)
    if not quiet:
        typer.echo(f"{folder}: {_n(len(names), '{n} samples')}\n" + "\n".join(f"  {name}" for name in names))


def _tune_allocator() -> None:
    """glibc tuning for the commands that make many short-lived arrays (synth, convert); it keeps
    freed memory for reuse, which raises the peak memory, so the other commands do without it."""
    from studio.runtime.parallel import tune_allocator

    tune_allocator()


def main() -> None:
    from studio.runtime.library_logs import quiet_rerun_writers

    quiet_rerun_writers()  # `python -m studio.cli` too (the console script does it in studio._entry)
    _for_the_command(sys.argv[1:])()


def _for_the_command(argv: list[str]) -> typer.Typer:
    """The app with only the command named first on the command line (when one is): typer builds
    the options of every registered command before it parses, and a command needs only its own.
    The app itself stays whole (``--help``, an unknown name, a test's ``CliRunner``)."""
    chosen = [c for c in app.registered_commands if argv and (c.name or getattr(c.callback, "__name__", "")) == argv[0]]
    if len(chosen) != 1:
        return app
    one = copy.copy(app)
    one.registered_commands = chosen
    return one


if __name__ == "__main__":
    main()
