"""``studio bench`` as a library function: datasets x cases x methods -> one table, like the kollagen
paper's Tables I and II.

A bench spec (TOML or JSON, or the built-in name ``paper``) names

* ``datasets``: presets (``multi3500x8``), kollagen JSON files, or existing multi-g2o folders;
* ``cases``: ``diagonal`` and/or ``exact`` (kollagen's ``exact_information_matrix``; it changes the
  single g2o only, which is why the paper's optimizers read the single g2o); folders are taken as
  they are (case ``as-is``);
* ``methods``: solver methods of :mod:`studio.solvers` (its registry: ``gtsam``, ``g2o``, ...);
* ``input``: ``single-g2o`` (kollagen's single file, as the paper) or ``multi-g2o``;
* ``alignments``: the ``studio evaluate`` alignments to score every estimate under;
* ``options``: per-method solver options, those the method's registry entry reads, and ``dimension``
  (``[options.command] command = "..."``).

Each cell (dataset, case, method) runs in a fresh process so its peak memory is its own; its results
are written to ``OUT/runs/<cell>/cell.json`` and a finished cell is never recomputed. Synthetic
datasets are generated once into ``OUT/datasets/``. The table goes to ``OUT/bench.csv``,
``OUT/bench.md`` (the paper's layout: one row per dataset and case, one APE column per method, and
the dead-reckoning row) and, when pyarrow is installed, ``OUT/bench.parquet``; a plot of APE per
method and dataset to ``OUT/bench.png``.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import hashlib
import json
import math
import multiprocessing
import os
import resource
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from studio.core.errors import ConfigError, StudioError
from studio.core.types import PathLike
from studio.io.atomic import check_workspace, output_workspace, write_replacing
from studio.io.names import safe_file_name
from studio.io.spec_file import check_spec_keys, read_spec_file
from studio.io.strict_json import dumps_strict, non_finite_path
from studio.runtime.progress import Progress, report

__all__ = ["BenchSpec", "BenchResult", "Cell", "load_bench_spec", "bench", "PAPER_SPEC", "format_paper_table"]

CASES = ("diagonal", "exact")
INPUTS = ("single-g2o", "multi-g2o")
DEFAULT_ALIGNMENTS = ("none", "first-pose", "se3")

#: The built-in spec ``paper``: the kollagen paper's two datasets, both cases, the methods we have,
#: read from the single g2o as the paper's optimizers did.
PAPER_SPEC: dict[str, Any] = {
    "name": "paper",
    "datasets": ["multi3500x8", "multi10000x5"],
    "cases": ["diagonal", "exact"],
    "methods": ["gtsam", "g2o"],
    "input": "single-g2o",
    "alignments": ["first-pose", "se3", "none"],
}

#: The kollagen paper's published figures (its Table I: APE translation mean [m]; g2o: spanning tree +
#: Gauss-Newton, 10 iterations). The dead-reckoning figures are
#: unaligned evo on the single files (first-pose alignment changes nothing there: every agent starts
#: on its ground truth); the g2o figures are reproduced by first-pose alignment, so they are shown
#: beside those tables only (:data:`PAPER_ALIGNMENTS`).
PAPER_FIGURES = {
    ("multi3500x8", "diagonal", "odometry"): 14.883697,
    ("multi10000x5", "diagonal", "odometry"): 17.427713,
    ("multi3500x8", "diagonal", "g2o"): 0.385161,
    ("multi10000x5", "diagonal", "g2o"): 1.019478,
    ("multi3500x8", "exact", "g2o"): 0.390065,
    ("multi10000x5", "exact", "g2o"): 1.426272,
}
#: The alignments under which each method's paper figure is comparable.
PAPER_ALIGNMENTS = {"odometry": ("none", "first-pose"), "g2o": ("first-pose",)}


@dataclass(frozen=True)
class BenchSpec:
    name: str
    datasets: tuple[str, ...]
    cases: tuple[str, ...] = ("diagonal",)
    methods: tuple[str, ...] = ("gtsam",)
    input: str = "single-g2o"
    alignments: tuple[str, ...] = DEFAULT_ALIGNMENTS
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    source: str = "<built-in>"


@dataclass(frozen=True)
class Cell:
    dataset: str
    case: str
    method: str

    @property
    def label(self) -> str:
        """The readable part of the cell's folder name (not its identity: see :func:`cell_key`)."""
        stem = Path(self.dataset).name if os.sep in self.dataset or self.dataset.endswith(".json") else self.dataset
        return safe_file_name(f"{stem.removesuffix('.json')}-{self.case}-{self.method}", fallback="cell")


def cell_identity(cell: Cell, spec: BenchSpec) -> dict[str, Any]:
    """Everything a cell's row depends on: the dataset (a file or folder by its resolved path and,
    for a file, a hash of its bytes; a preset by name), the case, the method, the input, the
    alignments and the method's options. Two cells share results only when all of it is equal."""
    path = Path(cell.dataset)
    dataset: dict[str, Any] = {"name": cell.dataset}
    if path.exists():
        dataset = {"path": os.path.realpath(path)}
        if path.is_file():
            dataset["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    return {
        "dataset": dataset,
        "case": cell.case,
        "method": cell.method,
        "input": spec.input,
        "alignments": list(spec.alignments),
        "options": dict(spec.options.get(cell.method, {})) if cell.method != "odometry" else {},
    }


def cell_key(cell: Cell, spec: BenchSpec) -> str:
    """The cell's folder name under ``OUT/runs``: its label and a hash of :func:`cell_identity`."""
    text = json.dumps(cell_identity(cell, spec), sort_keys=True, default=str)
    return f"{cell.label}-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


@dataclass(frozen=True, eq=False)
class BenchResult:
    spec: BenchSpec
    out_dir: Path
    rows: tuple[dict[str, Any], ...]
    """One dict per cell (and one ``odometry`` row per dataset and case), the table's rows."""
    computed: int
    """Cells run now (the others were finished by an earlier run)."""
    csv_path: Path
    markdown_path: Path
    plot_path: Path | None
    parquet_path: Path | None


_KEYS = {"name", "datasets", "cases", "methods", "input", "alignments", "options"}
#: Keywords of :func:`studio.solve.solve` a spec may set for every method, besides the options the
#: method's registry entry reads (:meth:`studio.solvers.SolveMethod.option_names`: the shared ones
#: it names and the fields of its own options class).
SOLVE_KEYWORDS = ("dimension",)


def solve_options(method: str) -> tuple[str, ...]:
    """The solve options a spec may set for ``method`` (``[options.<method>]``)."""
    from studio.solvers import method_entry

    return (*method_entry(method).option_names(), *SOLVE_KEYWORDS)


def _as_list(value: Any, where: str) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
        raise ConfigError(f"{where}: expected a non-empty list of names")
    return tuple(value)


def bench_spec_from_dict(data: Mapping[str, Any], source: str) -> BenchSpec:
    """Validate a spec read from TOML/JSON; errors name ``source: key``."""
    from studio.evaluate import Alignment
    from studio.solvers import method_names

    check_spec_keys(data, _KEYS, source, "bench spec")
    if "datasets" not in data:
        raise ConfigError(f"{source}: datasets: missing key")
    datasets = _as_list(data["datasets"], f"{source}: datasets")
    cases = _as_list(data.get("cases", ["diagonal"]), f"{source}: cases")
    for c in cases:
        if c not in CASES:
            raise ConfigError(f"{source}: cases: unknown case {c!r} (known: {', '.join(CASES)})")
    methods = _as_list(data.get("methods", ["gtsam"]), f"{source}: methods")
    known = method_names()
    for m in methods:
        if m not in known:
            raise ConfigError(f"{source}: methods: unknown method {m!r} (known: {', '.join(known)})")
    inp = data.get("input", "single-g2o")
    if inp not in INPUTS:
        raise ConfigError(f"{source}: input: expected one of {', '.join(INPUTS)}, got {inp!r}")
    alignments = _as_list(data.get("alignments", list(DEFAULT_ALIGNMENTS)), f"{source}: alignments")
    for a in alignments:
        try:
            Alignment(a)
        except ValueError:
            raise ConfigError(
                f"{source}: alignments: unknown alignment {a!r} (known: {', '.join(x.value for x in Alignment)})"
            ) from None
    options = data.get("options", {})
    if not isinstance(options, Mapping) or not all(isinstance(v, Mapping) for v in options.values()):
        raise ConfigError(f"{source}: options: expected a table per method ([options.gtsam] ...)")
    for m, opts in options.items():
        if m not in methods:
            raise ConfigError(f"{source}: options.{m}: not one of the spec's methods ({', '.join(methods)})")
        known_options = solve_options(m)
        for key in opts:
            if key not in known_options:
                raise ConfigError(
                    f"{source}: options.{m}.{key}: unknown solve option of method {m} "
                    f"(known: {', '.join(known_options)})"
                )
    name = data.get("name", Path(source).stem if source != "<built-in>" else "bench")
    if not isinstance(name, str) or not name or "/" in name:
        raise ConfigError(f"{source}: name: expected a plain name")
    return BenchSpec(name, datasets, cases, methods, inp, alignments, {k: dict(v) for k, v in options.items()}, source)


def load_bench_spec(source: PathLike) -> BenchSpec:
    """``paper`` (the built-in spec) or the path of a ``.toml`` / ``.json`` spec."""
    text = str(source)
    if text == "paper" and not Path(text).exists():
        return bench_spec_from_dict(PAPER_SPEC, "<built-in paper>")
    path = Path(text)
    if not path.is_file():
        raise ConfigError(f"{text}: no such spec file, and not a built-in spec (built-in: paper)")
    return bench_spec_from_dict(read_spec_file(path, what="bench spec"), str(path))


# ------------------------------------------------------------------------------------------- datasets


def _is_folder_dataset(name: str) -> bool:
    return Path(name).is_dir()


def _prepare_dataset(name: str, case: str, datasets_dir: Path) -> tuple[Path, Path | None]:
    """``(multi-g2o folder, single g2o file or None)`` of a dataset in a case, generated once."""
    if _is_folder_dataset(name):
        folder = Path(name)
        return folder, None
    from studio.synth import load_synth_config, synthesize

    config = load_synth_config(name)
    config = dataclasses.replace(config, exact_information_matrix=(case == "exact"), name=f"{config.name}-{case}")
    dataset = datasets_dir / config.name
    single = datasets_dir / f"{config.name}_singleg2o" / f"{config.name}.g2o"
    if not (dataset.is_dir() and single.is_file()):
        synthesize(config, datasets_dir, rrd=False, force=True)
    return dataset, single


# ------------------------------------------------------------------------------------------- one cell


def _run_cell(cell: Cell, spec: BenchSpec, dataset: str, single: str | None, run_dir: str) -> dict[str, Any]:
    """Solve and score one cell (in a fresh process); returns the row, with the process's peak memory."""
    from studio.evaluate import evaluate
    from studio.solve import solve

    source = single if (spec.input == "single-g2o" and single is not None) else dataset
    t0 = time.perf_counter()
    # the shared options and the method's own (dgs's tolerances ...), each by its name
    res = solve(source, run_dir, method=cell.method, force=True, **spec.options.get(cell.method, {}))
    info = {"estimate": str(res.estimate_path), "planar": res.planar}
    wall = time.perf_counter() - t0
    row: dict[str, Any] = {
        "dataset": cell.dataset,
        "case": cell.case,
        "method": cell.method,
        "input": spec.input,
        "iterations": res.iterations,
        "chi2_initial": res.chi2_initial,
        "chi2_final": res.chi2_final,
        "solve_s": res.seconds,
        "wall_s": wall,
        **info,
    }
    for align in spec.alignments:
        ev = evaluate(dataset, estimate=res.estimate_path, align=align)
        row[f"ape_{align}_m"] = ev.overall.ape_translation_m.mean
    row["sesync_f"] = _sesync_f(source, res.estimate_path)
    row["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return row


def _sesync_f(source: str, estimate: Path) -> float:
    """SE-Sync's objective of an estimate of ``source`` (any graph the solve took), the figure the
    gap to the certified optimum is computed from."""
    from studio.certify import read_estimate_poses
    from studio.solve import load_problem
    from studio.solvers.sesync import sesync_objective

    loaded = load_problem(source)
    return sesync_objective(loaded.problem, read_estimate_poses(estimate, loaded))


def _optimum_row(source: str) -> dict[str, Any]:
    """The certified optimum of ``source``'s graph (``f_star`` None without pymanopt, or for a graph
    no back-end can answer, whose cells then fail with the reason)."""
    from studio.solve import load_problem
    from studio.solvers.sesync import certified_optimum
    from studio.solvers.validate import check_problem

    try:
        problem = load_problem(source).problem
        check_problem(problem, source)
        optimum = certified_optimum(problem)
    except StudioError as err:
        return {"f_star": None, "certified": False, "skipped": str(err)}
    return {"f_star": optimum.f_star, "certified": optimum.certified}


def _with_gap(row: dict[str, Any], optimum: Mapping[str, Any]) -> dict[str, Any]:
    """``row`` with ``gap_to_optimum``, ``(f - f*) / f*`` in SE-Sync's objective, where the optimum is
    certified (else left out: a bound is not an optimum)."""
    from studio.solvers.sesync import Optimum

    f, f_star = row.get("sesync_f"), optimum.get("f_star")
    if f is None or f_star is None or "error" in row:
        return row
    return row | {"f_star": f_star, "gap_to_optimum": Optimum(f_star, bool(optimum["certified"])).gap(f)}


def _odometry_row(name: str, case: str, dataset: Path, spec: BenchSpec) -> dict[str, Any]:
    from studio.evaluate import evaluate

    row: dict[str, Any] = {"dataset": name, "case": case, "method": "odometry", "input": spec.input}
    for align in spec.alignments:
        row[f"ape_{align}_m"] = evaluate(dataset, align=align).overall.ape_translation_m.mean
    return row


def _end_with_parent(parent: int) -> None:
    """In a cell's worker: be killed when the bench process dies (Linux ``PR_SET_PDEATHSIG``), so a
    killed bench leaves no worker finishing its cell and then blocking on a pipe nobody reads."""
    import ctypes
    import signal

    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1: PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before the call: nobody is waiting
        os._exit(1)


def _in_fresh_process(func: Callable[..., dict[str, Any]], *args: Any) -> dict[str, Any]:
    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    with concurrent.futures.ProcessPoolExecutor(
        1, mp_context=ctx, initializer=_end_with_parent, initargs=(os.getpid(),)
    ) as pool:
        return pool.submit(func, *args).result()


# ------------------------------------------------------------------------------------------- the bench


def bench(spec: BenchSpec, out_dir: PathLike, *, progress: Progress | None = None, isolate: bool = True) -> BenchResult:
    """Run every cell of ``spec`` not finished yet under ``out_dir`` and write the tables and plot.

    ``isolate`` runs each cell in a fresh process (its own peak memory); tests may turn it off.
    """
    out = Path(out_dir)
    from studio.synth import load_synth_config

    for d in spec.datasets:
        if not _is_folder_dataset(d):
            load_synth_config(d)  # bad names fail before any work
    inputs = bench_inputs(spec)
    check_workspace(out, kind="bench", inputs=inputs)  # refused before any work
    with output_workspace(out, kind="bench", inputs=inputs):
        return _bench(spec, out, progress, isolate)


def bench_inputs(spec: BenchSpec) -> list[Path]:
    """The files and folders a bench reads: its spec file, and its datasets given as paths."""
    paths = [Path(spec.source)] if Path(spec.source).is_file() else []
    return paths + [Path(d) for d in spec.datasets if Path(d).exists()]


def _bench(spec: BenchSpec, out: Path, progress: Progress | None, isolate: bool) -> BenchResult:
    datasets_dir, runs_dir = out / "datasets", out / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    datasets_dir.mkdir(parents=True, exist_ok=True)
    cells = [
        Cell(d, c if not _is_folder_dataset(d) else "as-is", m)
        for d in spec.datasets
        for c in (spec.cases if not _is_folder_dataset(d) else ("as-is",))
        for m in spec.methods
    ]
    cells = list(dict.fromkeys(cells))
    rows: list[dict[str, Any]] = []
    computed = 0
    prepared: dict[tuple[str, str], tuple[Path, Path | None]] = {}
    optima: dict[tuple[str, str], dict[str, Any]] = {}
    total = len(cells)
    for k, cell in enumerate(cells):
        report(progress, "bench cells", k, total, "cells")
        pair = (cell.dataset, cell.case)
        if pair not in prepared:
            prepared[pair] = (
                _prepare_dataset(cell.dataset, cell.case if cell.case != "as-is" else "diagonal", datasets_dir)
                if not _is_folder_dataset(cell.dataset)
                else (Path(cell.dataset), None)
            )
            odo_path = runs_dir / f"{cell_key(Cell(cell.dataset, cell.case, 'odometry'), spec)}.json"
            odo_row = _finished(odo_path)
            if odo_row is not None:
                rows.append(odo_row)
            else:
                row = _odometry_row(cell.dataset, cell.case, prepared[pair][0], spec)
                _write_json(odo_path, row)
                rows.append(row)
        dataset, single = prepared[pair]
        if pair not in optima:
            optima[pair] = _optimum(spec, runs_dir, cell, dataset, single, isolate)
        key = cell_key(cell, spec)
        done = runs_dir / key / "cell.json"
        finished = _finished(done)
        if finished is not None:
            rows.append(_with_gap(finished, optima[pair]))
            continue
        args = (
            cell,
            spec,
            str(dataset),
            None if single is None else str(single),
            str(runs_dir / key / "estimate"),
        )
        try:
            row = _in_fresh_process(_run_cell, *args) if isolate else _run_cell(*args)
        except StudioError as err:
            row = {
                "dataset": cell.dataset,
                "case": cell.case,
                "method": cell.method,
                "input": spec.input,
                "error": str(err),
            }
        computed += 1
        found = non_finite_path(row)
        if found is not None:  # a NaN result fails the cell (written as NaN it would pass)
            row = {k: row[k] for k in ("dataset", "case", "method", "input") if k in row} | {
                "error": f"{done}: {found[0]} is {found[1]!r}, not a finite number (strict JSON)"
            }
        _write_json(done, row)
        rows.append(_with_gap(row, optima[pair]))
    report(progress, "bench cells", total, total, "cells")
    return _write_tables(spec, out, rows, computed)


def _optimum(
    spec: BenchSpec, runs_dir: Path, cell: Cell, dataset: Path, single: Path | None, isolate: bool
) -> dict[str, Any]:
    """The certified optimum of the graph a dataset's cells solve, computed once and kept beside
    its cells (``runs/<dataset>-optimum.json``)."""
    source = str(single if (spec.input == "single-g2o" and single is not None) else dataset)
    path = runs_dir / f"{cell_key(Cell(cell.dataset, cell.case, 'optimum'), spec)}.json"
    row = _finished(path)
    if row is None:
        row = _in_fresh_process(_optimum_row, source) if isolate else _optimum_row(source)
        _write_json(path, row)
    return row


def _finished(path: Path) -> dict[str, Any] | None:
    """The row of a cell an earlier run finished, or None when it must run (again): no file, a file
    that does not read back, or a cell that failed (its spec or data may have been fixed since)."""
    try:
        row = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or "error" in row:
        return None
    return row


def _write_json(path: Path, row: Mapping[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    text = dumps_strict(row, str(path), indent=2, sort_keys=True, default=float) + "\n"
    write_replacing(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


# ------------------------------------------------------------------------------------------- output


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.6f}" if abs(v) < 1e5 else f"{v:.6g}"
    return str(v)


def format_paper_table(rows: Sequence[Mapping[str, Any]], spec: BenchSpec, align: str) -> str:
    """Markdown like the paper's Table I: one row per dataset and case, one APE column per method
    (plus dead reckoning), the paper's figure beside ours where the paper has one."""
    methods = ["odometry", *spec.methods]
    head = ["dataset", "case"] + [f"{m} APE [m]" for m in methods]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join([":---", ":---"] + ["---:"] * len(methods)) + "|"]
    keys = list(dict.fromkeys((r["dataset"], r["case"]) for r in rows))
    for d, c in keys:
        cells = [d, c]
        for m in methods:
            r = next((x for x in rows if x["dataset"] == d and x["case"] == c and x["method"] == m), None)
            v = None if r is None else r.get(f"ape_{align}_m")
            text = r["error"].split(":")[0] if r is not None and "error" in r else _fmt(v)
            paper = PAPER_FIGURES.get((Path(d).name.lower(), c, m))
            if paper is not None and align in PAPER_ALIGNMENTS.get(m, ()):
                text += f" (paper {paper:.6f})"
            cells.append(text)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _write_tables(spec: BenchSpec, out: Path, rows: list[dict[str, Any]], computed: int) -> BenchResult:
    import pandas as pd

    df = pd.DataFrame(rows)
    first = (
        ["dataset", "case", "method", "input"]
        + [f"ape_{a}_m" for a in spec.alignments]
        + [
            "iterations",
            "chi2_initial",
            "chi2_final",
            "sesync_f",
            "f_star",
            "gap_to_optimum",
            "solve_s",
            "wall_s",
            "peak_rss_mb",
            "planar",
            "estimate",
            "error",
        ]
    )
    df = df[[c for c in first if c in df.columns] + sorted(c for c in df.columns if c not in first)]
    csv_path = out / "bench.csv"
    write_replacing(csv_path, lambda tmp: df.to_csv(tmp, index=False))
    parquet_path: Path | None = out / "bench.parquet"
    try:
        write_replacing(parquet_path, lambda tmp: df.to_parquet(tmp, index=False))  # type: ignore[arg-type]
    except ImportError:
        parquet_path = None
    md = [f"# Bench `{spec.name}`", "", f"Input: {spec.input}. APE: evo translation mean over all agents [m].", ""]
    for align in spec.alignments:
        md += [f"## APE, alignment `{align}`", "", format_paper_table(rows, spec, align)]
    cols = [
        c
        for c in (
            "dataset",
            "case",
            "method",
            "iterations",
            "chi2_initial",
            "chi2_final",
            "gap_to_optimum",
            "solve_s",
            "wall_s",
            "peak_rss_mb",
            "error",
        )
        if c in df.columns
    ]
    md += ["## Runs", "", "| " + " | ".join(cols) + " |", "|" + "|".join(["---"] * len(cols)) + "|"]
    for r in rows:
        if r["method"] == "odometry":
            continue
        md.append("| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |")
    markdown_path = out / "bench.md"
    write_replacing(markdown_path, lambda tmp: tmp.write_text("\n".join(md) + "\n", encoding="utf-8"))
    plot_path = _plot(spec, out, rows)
    return BenchResult(spec, out, tuple(rows), computed, csv_path, markdown_path, plot_path, parquet_path)


def _plot(spec: BenchSpec, out: Path, rows: list[dict[str, Any]]) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    keys = list(dict.fromkeys((r["dataset"], r["case"]) for r in rows))
    methods = list(spec.methods)
    fig, axes = plt.subplots(
        1, len(spec.alignments), figsize=(4.5 * len(spec.alignments), 3.6), squeeze=False, layout="tight"
    )
    width = 0.8 / max(1, len(methods))
    for ax, align in zip(axes[0], spec.alignments):
        for k, m in enumerate(methods):
            vals = []
            for d, c in keys:
                r = next((x for x in rows if x["dataset"] == d and x["case"] == c and x["method"] == m), {})
                vals.append(r.get(f"ape_{align}_m", float("nan")))
            ax.bar([i + k * width for i in range(len(keys))], vals, width, label=m)
        ax.set_xticks([i + width * (len(methods) - 1) / 2 for i in range(len(keys))])
        ax.set_xticklabels([f"{Path(d).name}\n{c}" for d, c in keys], fontsize=8)
        ax.set_ylabel("APE translation mean [m]")
        ax.set_title(f"alignment: {align}")
        ax.legend(fontsize=8)
    path = out / "bench.png"
    write_replacing(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))
    plt.close(fig)
    return path
