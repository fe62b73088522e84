"""``studio sweep`` as a library function: a parameter grid of datasets (and steps on each) fanned out
over a Dask cluster, collected into one table.

A sweep spec (TOML or JSON) names

* ``base``: a preset (``multi3500x8``), a kollagen JSON file, or a converted dataset's
  ``convert.json``;
* ``grid``: parameter -> list of values; every combination is a cell. For a kollagen base a parameter
  is a dotted JSON path (``number_of_agents``, ``inter_agent_loop_closure_parameters.loop_closure_radius``,
  ``agent_parameters.agent_specific.std_dev_position``, which sets every agent's entry); for a
  ``convert.json`` base it is an option name (``lc_radius``, ``outlier_fraction``...). ``seed`` is a
  replicate number: for kollagen every ``random_number_generator_seed`` becomes
  ``(seed_in_base + 1000003 * seed) mod (2^31 - 1)``; for convert it is the ``seed`` option;
* ``cells``: an optional list of parameter tables, run besides the grid's;
* ``steps``: what to run on each dataset: ``evaluate`` (APE of the dead reckoning), ``solve`` (then
  the APE of the estimate), ``check`` (chi2 factors), ``record`` (the ``.rrd``), ``replay``
  (``studio replay``: the final team APE and SVE), or ``module:function`` (a function
  ``(cell_dir, dataset, row) -> dict`` of extra columns);
* ``options``: per step, keyword options (``[options.solve] method = "g2o"``); a grid key
  ``STEP.OPTION`` naming a built-in step of the spec (``replay.comms``) sets that option per cell
  instead of a dataset parameter.

Each cell gets a deterministic name (``<sweep>-<hash of its parameters>``) and its effective config
in ``OUT/configs/<cell>.json``, so any cell can be made alone with the command the table lists
(``studio synth OUT/configs/<cell>.json -o DIR``). Cells run on Dask workers (a local cluster by
default, or ``scheduler``'s): each writes ``OUT/cells/<cell>/`` (the dataset is staged and renamed
by ``studio synth``/``convert``) and last ``result.json``, the completion marker. A finished cell is
never recomputed; a cell whose worker dies is retried (the retry removes what the dead one left);
a cell that fails records its one-line error in the table, leaves no files, and the sweep goes on.
The client writes ``OUT/sweep.parquet``, ``OUT/sweep.csv``, ``OUT/sweep.md``, a plot per swept
parameter in ``OUT/plots/`` and ``OUT/sweep.rrd`` (the summary series over the cells).
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import hashlib
import importlib
import itertools
import json
import logging
import math
import os
import shutil
import time
import warnings
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

__all__ = [
    "SweepSpec",
    "SweepResult",
    "CellTask",
    "load_sweep_spec",
    "sweep_spec_from_dict",
    "expand",
    "sweep",
    "run_cell",
    "STEPS",
]

_KEYS = {"name", "base", "grid", "cells", "steps", "options"}
RESULT = "result.json"


@dataclass(frozen=True)
class SweepSpec:
    name: str
    base: str
    grid: Mapping[str, Sequence[Any]]
    cells: tuple[Mapping[str, Any], ...] = ()
    steps: tuple[str, ...] = ("evaluate",)
    options: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    source: str = "<spec>"


@dataclass(frozen=True)
class CellTask:
    """Everything a worker needs for one cell (plain data: it travels to the worker)."""

    name: str
    kind: str
    """``synth`` or ``convert``."""
    config: dict[str, Any]
    params: dict[str, Any]
    out_root: str
    steps: tuple[str, ...]
    options: dict[str, dict[str, Any]]
    group: str = ""
    """A synth cell among others that differ from it only in ``seed``: the name of their group, whose
    datasets are made together by :func:`studio.synth.synthesize_seeds` in ``OUT/seeds/<group>/``
    (:func:`run_seed_cells`); empty for a cell made alone."""
    group_config: dict[str, Any] | None = None
    """The group's config at replicate 0 (kollagen JSON): each member's config is its replicate."""


@dataclass(frozen=True, eq=False)
class SweepResult:
    out_dir: Path
    rows: tuple[dict[str, Any], ...]
    computed: int
    """Cells run now (the others were finished by an earlier run)."""
    failed: int
    table_path: Path
    markdown_path: Path
    plot_paths: tuple[Path, ...]
    rrd_path: Path | None


# ------------------------------------------------------------------------------------------- the spec


def sweep_spec_from_dict(data: Any, source: str) -> SweepSpec:
    check_spec_keys(data, _KEYS, source, "sweep spec")
    if "base" not in data:
        raise ConfigError(f"{source}: base: missing key (a preset, a kollagen JSON or a convert.json)")
    base = data["base"]
    if not isinstance(base, str) or not base:
        raise ConfigError(f"{source}: base: expected a preset name or a path")
    grid = data.get("grid", {})
    if not isinstance(grid, Mapping):
        raise ConfigError(f"{source}: grid: expected a table of parameter = [values]")
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{source}: grid.{key}: expected a non-empty list of values")
    cells = data.get("cells", [])
    if not isinstance(cells, list) or not all(isinstance(c, Mapping) for c in cells):
        raise ConfigError(f"{source}: cells: expected a list of parameter tables")
    steps = data.get("steps", ["evaluate"])
    if isinstance(steps, str):
        steps = [steps]
    if not isinstance(steps, list) or not all(isinstance(s, str) for s in steps):
        raise ConfigError(f"{source}: steps: expected a list of step names")
    for s in steps:
        if s not in STEPS and ":" not in s:
            raise ConfigError(f"{source}: steps: unknown step {s!r} (known: {', '.join(STEPS)}, or module:function)")
    options = data.get("options", {})
    if not isinstance(options, Mapping) or not all(isinstance(v, Mapping) for v in options.values()):
        raise ConfigError(f"{source}: options: expected a table per step ([options.solve] ...)")
    for s in options:
        if s not in steps:
            raise ConfigError(f"{source}: options.{s}: not one of the spec's steps ({', '.join(steps)})")
    name = data.get("name", Path(source).stem if source != "<spec>" else "sweep")
    if not isinstance(name, str) or not name or not all(ch.isalnum() or ch in "-_." for ch in name):
        raise ConfigError(f"{source}: name: expected letters, digits, '-', '_' or '.'")
    return SweepSpec(
        name,
        base,
        {k: list(v) for k, v in grid.items()},
        tuple(dict(c) for c in cells),
        tuple(steps),
        {k: dict(v) for k, v in options.items()},
        source,
    )


def load_sweep_spec(path: PathLike) -> SweepSpec:
    path = Path(path)
    spec = sweep_spec_from_dict(read_spec_file(path, what="sweep spec"), str(path))
    base = spec.base
    if not Path(base).is_absolute() and (path.parent / base).is_file():
        spec = SweepSpec(
            spec.name, str(path.parent / base), spec.grid, spec.cells, spec.steps, spec.options, spec.source
        )
    return spec


# ------------------------------------------------------------------------------------------- cells


def _base(spec: SweepSpec) -> tuple[str, dict[str, Any]]:
    """``(kind, JSON)`` of the base: a kollagen config (presets written out) or a convert.json."""
    from studio.generator.presets import PRESETS, preset
    from studio.io.synth_config import synth_config_to_json
    from studio.synth import shadowed_preset

    shadowed = shadowed_preset(spec.base)
    if shadowed is not None:
        warnings.warn(f"{spec.source}: base: {shadowed}", stacklevel=2)
    if spec.base.lower() in PRESETS and not Path(spec.base).exists():
        return "synth", synth_config_to_json(preset(spec.base))
    path = Path(spec.base)
    if not path.is_file():
        raise ConfigError(
            f"{spec.source}: base: {spec.base}: no such file, and not a preset (presets: {', '.join(sorted(PRESETS))})"
        )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"{path}: not a readable JSON file ({err})") from None
    if isinstance(data, dict) and "source" in data and "inputs" in data:
        return "convert", data
    return "synth", data


def _set_path(doc: dict[str, Any], key: str, value: Any, where: str) -> None:
    parts = key.split(".")
    targets: list[Any] = [doc]
    for k, part in enumerate(parts):
        last = k == len(parts) - 1
        nxt: list[Any] = []
        for t in targets:
            if not isinstance(t, dict) or part not in t:
                raise ConfigError(f"{where}: {key}: no such key in the base config")
            if last:
                t[part] = value
            elif isinstance(t[part], list):
                nxt.extend(t[part])  # a list of objects (agent_specific): set the key in every entry
            else:
                nxt.append(t[part])
        targets = nxt


def _apply(kind: str, base: dict[str, Any], params: Mapping[str, Any], where: str) -> dict[str, Any]:
    doc = copy.deepcopy(base)
    for key, value in params.items():
        if kind == "convert":
            from studio.converters.build import GraphOptions

            names = sorted(GraphOptions.__dataclass_fields__)
            if key not in names:
                raise ConfigError(f"{where}: {key}: not a convert option (known: {', '.join(names)})")
            doc[key] = value
            continue
        if key == "seed":
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{where}: seed: expected a non-negative integer, got {value!r}")
            continue
        _set_path(doc, key, value, where)
    if kind == "synth":
        seed = int(params.get("seed", 0))
        entries = doc.get("agent_parameters", {}).get("agent_specific", [])
        n = doc.get("number_of_agents")
        if isinstance(entries, list) and entries and isinstance(n, int) and 1 < len(entries) != n:
            # a cell that changes the number of agents cycles through the base's agent entries
            doc["agent_parameters"]["agent_specific"] = [copy.deepcopy(entries[k % len(entries)]) for k in range(n)]
        if seed:
            from studio.generator.config import replicate_seed

            for entry in doc["agent_parameters"]["agent_specific"]:
                entry["random_number_generator_seed"] = replicate_seed(entry["random_number_generator_seed"], seed)
            inter = doc["inter_agent_loop_closure_parameters"]
            inter["random_number_generator_seed"] = replicate_seed(inter["random_number_generator_seed"], seed)
    return doc


def cell_name(spec_name: str, params: Mapping[str, Any], identity: Mapping[str, Any] | None = None) -> str:
    """``<sweep>-<hash>``: the hash covers the cell's parameters and, given ``identity``, everything
    else its row depends on (the effective config, the steps and their options), so that a changed
    base or option makes a new cell instead of reusing the old one's results."""
    whole = {"params": params, **({"identity": identity} if identity is not None else {})}
    text = json.dumps(whole if identity is not None else params, sort_keys=True, default=str)
    return f"{safe_file_name(spec_name, fallback='sweep')}-{hashlib.sha256(text.encode()).hexdigest()[:10]}"


def _step_key(spec: SweepSpec, key: str) -> tuple[str, str] | None:
    """``(step, option)`` of a grid key ``STEP.OPTION`` naming one of the spec's built-in steps
    (``replay.comms``), None for a dataset parameter."""
    step, dot, option = key.partition(".")
    return (step, option) if dot and step in spec.steps and step in STEPS else None


def _dataset_params(spec: SweepSpec, params: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters that make the cell's dataset (not a step's option)."""
    return {k: v for k, v in params.items() if _step_key(spec, k) is None}


def _cell_options(spec: SweepSpec, params: Mapping[str, Any], where: str) -> dict[str, dict[str, Any]]:
    """Each step's options for one cell: the spec's ``[options.STEP]`` with the cell's ``STEP.OPTION``
    parameters over them, checked by the step's checker (:data:`STEP_CHECKS`) before any work."""
    options = {s: dict(o) for s, o in spec.options.items()}
    for key, value in params.items():
        got = _step_key(spec, key)
        if got is not None:
            options.setdefault(got[0], {})[got[1]] = value
    for step, opts in options.items():
        if step in STEP_CHECKS:
            STEP_CHECKS[step](opts, f"{where}: options.{step}")
    return options


def expand(spec: SweepSpec, out: PathLike) -> list[CellTask]:
    """Every cell of the spec (grid combinations, then the explicit cells), validated."""
    kind, base = _base(spec)
    keys = list(spec.grid)
    combos = [dict(zip(keys, values)) for values in itertools.product(*(spec.grid[k] for k in keys))] if keys else []
    combos += [dict(c) for c in spec.cells]
    if not combos:
        combos = [{}]
    tasks, seen = [], set()
    for k, params in enumerate(combos):
        where = f"{spec.source}: cell {k + 1}"
        doc = _apply(kind, base, _dataset_params(spec, params), where)
        options = _cell_options(spec, params, where)
        identity = {"kind": kind, "config": doc, "steps": list(spec.steps), "options": options}
        name = cell_name(spec.name, params, identity)
        if name in seen:
            continue
        seen.add(name)
        # a bad value fails here, before any work
        if kind == "synth":
            from studio.io.synth_config import parse_synth_config

            parse_synth_config(doc, source=where, name=name)
        else:
            from studio.convert import config_from_mapping

            config_from_mapping(doc, where)
        tasks.append(CellTask(name, kind, doc, params, str(Path(out)), spec.steps, options))
    return _seed_groups(spec, kind, base, tasks)


def _seed_groups(spec: SweepSpec, kind: str, base: dict[str, Any], tasks: list[CellTask]) -> list[CellTask]:
    """Mark the synth cells that differ only in ``seed`` (two or more) as one group each: their
    datasets are one config's replicates, made together by ``synthesize_seeds``."""
    if kind != "synth":
        return tasks
    members: dict[str, list[int]] = {}
    for k, t in enumerate(tasks):
        if "seed" in t.params:
            rest = {p: v for p, v in t.params.items() if p != "seed"}
            members.setdefault(json.dumps(rest, sort_keys=True, default=str), []).append(k)
    out = list(tasks)
    for key, indices in members.items():
        if len(indices) < 2:
            continue
        rest = json.loads(key)
        doc = _apply(kind, base, _dataset_params(spec, rest), f"{spec.source}: seeds of {key}")
        options = tasks[indices[0]].options
        identity = {"seeds": {"kind": kind, "config": doc, "steps": list(spec.steps), "options": options}}
        group = cell_name(spec.name, rest, identity)
        for k in indices:
            out[k] = dataclasses.replace(tasks[k], group=group, group_config=doc)
    return out


# ------------------------------------------------------------------------------------------- one cell


def _evaluate(dataset: Path, row: dict[str, Any], prefix: str, estimate: Path | None = None) -> None:
    from studio.evaluate import evaluate

    for align in ("none", "se3"):
        ev = evaluate(dataset, estimate=estimate, align=align)
        row[f"{prefix}_{align}_m"] = ev.overall.ape_translation_m.mean


StepFn = Callable[[CellTask, Path, Path, dict[str, Any], dict[str, Any]], None]
"""A step: ``(task, cell_dir, dataset, row, options)``; it adds columns to ``row`` in place."""


def _step_evaluate(task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any], opts: dict[str, Any]) -> None:
    _evaluate(dataset, row, "ape_initial")


def _step_solve(task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any], opts: dict[str, Any]) -> None:
    from studio.solve import solve

    res = solve(dataset, cell_dir / "solved", **opts)
    row.update(solve_method=res.method, solve_iterations=res.iterations, chi2_final=res.chi2_final, solve_s=res.seconds)
    _evaluate(dataset, row, "ape_solved", res.estimate_path)


def _step_check(task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any], opts: dict[str, Any]) -> None:
    from studio.check import check

    report = check(dataset, **opts)
    for c in report.classes:
        if c.agent == "all":
            factor = c.total.factor  # NaN: a class without degrees of freedom, no value (None)
            row[f"check_{c.name.replace(' ', '_')}_factor"] = factor if math.isfinite(factor) else None


def _step_record(task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any], opts: dict[str, Any]) -> None:
    """The ``.rrd`` is written with the dataset (``rrd=True`` when this step is asked for)."""


def _replay_backends(opts: dict[str, Any]) -> list[str] | None:
    """``backends`` of the replay step's options: a list, or one name or ``a,b`` as a string."""
    value = opts.get("backends")
    if value is None:
        return None
    return [b.strip() for b in value.split(",")] if isinstance(value, str) else list(value)


def _check_replay(opts: dict[str, Any], where: str) -> None:
    """The replay step's options: names of :func:`studio.replay.replay`'s keywords, a comms model its
    registry parses, back-ends its registry knows (a ConfigError naming ``where`` otherwise)."""
    import inspect

    from studio.core.comms import parse_comms
    from studio.replay.pipeline import replay

    known = sorted(set(inspect.signature(replay).parameters) - {"dataset", "out", "progress", "warn", "force", "rrd"})
    for key in opts:
        if key not in known:
            raise ConfigError(f"{where}: {key}: not a replay option (known: {', '.join(known)})")
    try:
        if "comms" in opts:
            parse_comms(str(opts["comms"]))
        if _replay_backends(opts) is not None:
            from studio.replay.registry import get_backend

            for name in _replay_backends(opts) or []:
                get_backend(name)
    except StudioError as err:
        raise ConfigError(f"{where}: {one_line_error(err)}") from None


def _step_replay(task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any], opts: dict[str, Any]) -> None:
    """``studio replay`` of the cell's dataset into ``replay/``: per back-end the final team APE
    (se3 and first-pose), SVE (None for a back-end that keeps no other robot's poses), messages,
    bytes and seconds; with one back-end the columns are ``replay_*``, with several
    ``replay_<backend>_*``."""
    from studio.replay.pipeline import replay

    kwargs: dict[str, Any] = dict(opts)
    backends = _replay_backends(opts)
    if backends is not None:
        kwargs["backends"] = backends
    res = replay(dataset, cell_dir / "replay", **kwargs)
    got = res.schedule.delivered_tick >= 0
    row.update(replay_comms=res.schedule.model, replay_delivered=float(got.mean()) if len(got) else None)
    for run in res.runs:
        prefix = "replay" if len(res.runs) == 1 else f"replay_{run.name}"
        sve = run.sve[-1] if run.sve is not None and not math.isnan(run.sve[-1, 0]) else (None, None)
        row.update(
            {
                f"{prefix}_ape_se3_m": float(run.ape_team_se3_m[-1]),
                f"{prefix}_ape_first_pose_m": float(run.ape_team_first_pose_m[-1]),
                f"{prefix}_sve_t_m": None if sve[0] is None else float(sve[0]),
                f"{prefix}_sve_r_rad": None if sve[1] is None else float(sve[1]),
                f"{prefix}_messages": int(run.messages.sum()),
                f"{prefix}_bytes": int(run.bytes.sum()),
                f"{prefix}_s": run.seconds,
            }
        )


#: The step registry: a new per-dataset step is one entry here (its name is then valid in a spec).
STEPS: dict[str, StepFn] = {
    "evaluate": _step_evaluate,
    "solve": _step_solve,
    "check": _step_check,
    "record": _step_record,
    "replay": _step_replay,
}

#: Per step, a check of its options (the spec's and the cells' ``STEP.OPTION``) before any work.
STEP_CHECKS: dict[str, Callable[[dict[str, Any], str], None]] = {"replay": _check_replay}


def _step(step: str, task: CellTask, cell_dir: Path, dataset: Path, row: dict[str, Any]) -> None:
    opts = task.options.get(step, {})
    if step in STEPS:
        STEPS[step](task, cell_dir, dataset, row, opts)
        return
    module, _, func = step.partition(":")  # a user's step: (cell_dir, dataset, row) -> dict of columns
    row.update(getattr(importlib.import_module(module), func)(cell_dir, dataset, dict(row)) or {})


def one_line_error(err: BaseException) -> str:
    """A StudioError's own first line; any other exception's type and first line."""
    lines = str(err).strip().splitlines()
    first = lines[0] if lines else ""
    if isinstance(err, StudioError):
        return first
    return f"{type(err).__name__}: {first}" if first else type(err).__name__


def run_cell(task: CellTask) -> dict[str, Any]:
    """Make one cell's dataset and run its steps (on a worker). Returns the cell's table row.

    A cell with ``result.json`` is done; anything else in its folder is what a killed attempt left,
    removed first. A StudioError becomes the row's ``error`` and the cell's files are removed.
    """
    out = Path(task.out_root)
    cell_dir = out / "cells" / task.name
    done = cell_dir / RESULT
    if done.is_file():
        return dict(json.loads(done.read_text(encoding="utf-8")), reused=True)
    if cell_dir.exists():
        shutil.rmtree(cell_dir)
    row = _row(task)
    t0 = time.perf_counter()
    try:
        cell_dir.mkdir(parents=True)
        if task.kind == "synth":
            from studio.io.synth_config import parse_synth_config
            from studio.synth import synthesize

            config = parse_synth_config(task.config, source=str(out / "configs" / f"{task.name}.json"), name=task.name)
            res = synthesize(config, cell_dir, jobs=1, rrd="record" in task.steps)
            dataset = res.dataset_dir
            g = res.output.graph
        else:
            from studio.convert import config_from_mapping, convert

            res_c = convert(
                config_from_mapping(task.config, str(out / "configs" / f"{task.name}.json")),
                cell_dir / task.name,
                rrd="record" in task.steps,
            )
            dataset = res_c.dataset_dir
            g = res_c.build.graph
        row["make_s"] = time.perf_counter() - t0
        row.update(agents=len(g.agents), poses=g.num_poses, **g.edge_counts())
        for step in task.steps:
            _step(step, task, cell_dir, dataset, row)
    except Exception as err:  # any failure is the cell's one-line error; the sweep goes on
        shutil.rmtree(cell_dir, ignore_errors=True)
        row["error"] = one_line_error(err)
        return row
    row["cell_s"] = time.perf_counter() - t0
    row["dataset"] = str(dataset.relative_to(out))
    return _finish(row, done, lambda: shutil.rmtree(cell_dir, ignore_errors=True))


def _row(task: CellTask) -> dict[str, Any]:
    return {"cell": task.name, **{f"param:{k}": v for k, v in task.params.items()}}


def _finish(row: dict[str, Any], done: Path, remove: Callable[[], None]) -> dict[str, Any]:
    """Write the row as the cell's ``result.json`` ``done`` (its completion marker); a non-finite
    result fails the cell instead (written as NaN it would pass) and ``remove`` takes its files."""
    try:
        text = dumps_strict(row, str(done), indent=2, sort_keys=True, default=float) + "\n"
    except StudioError as err:
        remove()
        return {k: v for k, v in row.items() if non_finite_path(v) is None} | {"error": one_line_error(err)}
    write_replacing(done, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return row


def _seed_folder(task: CellTask) -> Path:
    """``OUT/seeds/<group>/seed<k>``: the folder ``synthesize_seeds`` writes the cell's dataset into."""
    from studio.synth import seed_folder_name

    return Path(task.out_root) / "seeds" / task.group / seed_folder_name(int(task.params["seed"]))


def _remove_cell(task: CellTask) -> None:
    """Everything a cell made: its folder and, in a seed group, its seed's folder. The group's
    folder stays: another worker may be writing a seed of the group into it right now (removing it
    when it looked empty raced with that worker's staging); the sweep removes the empty ones when
    every cell has ended (:func:`_remove_empty_groups`)."""
    shutil.rmtree(Path(task.out_root) / "cells" / task.name, ignore_errors=True)
    if task.group:
        shutil.rmtree(_seed_folder(task), ignore_errors=True)


def _remove_empty_groups(out: Path, tasks: Sequence[CellTask]) -> None:
    """The seed groups' folders left empty by failed cells (once no worker writes any more)."""
    for group in sorted({t.group for t in tasks if t.group}):
        with contextlib.suppress(OSError):
            (out / "seeds" / group).rmdir()


def run_cells(tasks: Sequence[CellTask]) -> list[dict[str, Any]]:
    """One Dask task: a cell made alone (:func:`run_cell`), or replicates of one seed group
    (:func:`run_seed_cells`). Returns their rows."""
    if tasks and tasks[0].group:
        return run_seed_cells(tasks)
    return [run_cell(t) for t in tasks]


def run_seed_cells(tasks: Sequence[CellTask]) -> list[dict[str, Any]]:
    """Cells of one seed group (on a worker): their datasets made in one
    :func:`studio.synth.synthesize_seeds` call into ``OUT/seeds/<group>/seed<k>/`` (the bytes of
    ``studio synth OUT/configs/<cell>.json``, one sync of the file system instead of a dozen fsyncs
    per dataset), then each cell's steps and ``result.json`` as :func:`run_cell` does. What a
    killed attempt left of an unfinished cell is removed first; a failure is the cells' error."""
    from studio.io.synth_config import parse_synth_config
    from studio.synth import synthesize_seeds

    group, out = tasks[0].group, Path(tasks[0].out_root)
    rows: dict[str, dict[str, Any]] = {}
    todo = []
    for t in tasks:
        done = out / "cells" / t.name / RESULT
        if done.is_file():
            rows[t.name] = dict(json.loads(done.read_text(encoding="utf-8")), reused=True)
        else:
            _remove_cell(t)
            todo.append(t)
    seeds = [int(t.params["seed"]) for t in todo]
    made_s: dict[int, float] = {}
    clock = [time.perf_counter()]

    def seed_made(step: str, done: int, total: int, unit: str = "") -> None:  # after each seed
        if unit == "seeds":
            now = time.perf_counter()
            made_s[seeds[done - 1]], clock[0] = now - clock[0], now

    try:
        if todo:
            source = str(out / "configs" / f"{group}.json")
            config = parse_synth_config(tasks[0].group_config, source=source, name=group)
            synthesize_seeds(
                config, out / "seeds" / group, seeds, jobs=1, rrd="record" in todo[0].steps, progress=seed_made
            )
    except Exception as err:  # the group's config failed: every unfinished cell's error
        for t in todo:
            _remove_cell(t)
            rows[t.name] = _row(t) | {"error": one_line_error(err)}
        todo = []
    for t in todo:
        rows[t.name] = _seed_cell(t, made_s[int(t.params["seed"])])
    return [rows[t.name] for t in tasks]


def _seed_cell(task: CellTask, make_s: float) -> dict[str, Any]:
    """The steps of a seed group's cell whose dataset ``synthesize_seeds`` made in ``make_s``."""
    from studio.io.multig2o import read_multi_g2o

    cell_dir = Path(task.out_root) / "cells" / task.name
    dataset = _seed_folder(task) / task.group
    row = _row(task)
    t0 = time.perf_counter()
    try:
        cell_dir.mkdir(parents=True)
        g = read_multi_g2o(dataset)
        row["make_s"] = make_s
        row.update(agents=len(g.agents), poses=g.num_poses, **g.edge_counts())
        for step in task.steps:
            _step(step, task, cell_dir, dataset, row)
    except Exception as err:  # any failure is the cell's one-line error; the sweep goes on
        _remove_cell(task)
        row["error"] = one_line_error(err)
        return row
    row["cell_s"] = make_s + time.perf_counter() - t0
    row["dataset"] = str(dataset.relative_to(task.out_root))
    return _finish(row, cell_dir / RESULT, lambda: _remove_cell(task))


# ------------------------------------------------------------------------------------------- the sweep


def _client(scheduler: str | None, workers: int | None) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("studio sweep needs Dask: pip install 'cslam-studio[sweep]'") from None
    # Dask's own logs and warnings never reach the user's terminal: the sweep reports what matters
    for name in (
        "distributed",
        "distributed.worker",
        "distributed.scheduler",
        "distributed.nanny",
        "distributed.core",
        "distributed.comm",
        "distributed.client",
        "tornado",
    ):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if scheduler:
            try:
                return Client(scheduler, timeout="20s"), None
            except (OSError, TimeoutError, ValueError) as err:
                raise ConfigError(f"scheduler: cannot connect to {scheduler} ({err})") from None
        from studio.runtime.parallel import available_cores

        n = workers or available_cores()
        # no dashboard; the scheduler's small HTTP server (health, metrics) on a free loopback port, not
        # on 8787 (whose 'already in use' warning would otherwise print when another cluster runs)
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            silence_logs=logging.CRITICAL + 1,
        )
        return Client(cluster), cluster


def sweep(
    spec: SweepSpec,
    out: PathLike,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Progress | None = None,
    retries: int = 2,
) -> SweepResult:
    """Run every cell of ``spec`` not finished yet (see the module docstring); returns the table."""
    out = Path(os.path.abspath(out))
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"workers: expected a positive integer, got {workers!r}")
    if scheduler:
        check_scheduler(scheduler)
    inputs = sweep_inputs(spec)
    check_workspace(out, kind="sweep", inputs=inputs)  # every refusal before any work
    tasks = expand(spec, out)
    with output_workspace(out, kind="sweep", inputs=inputs):
        return _sweep(spec, out, tasks, scheduler, workers, progress, retries)


def _write_text(tmp: Path, *, text: str) -> None:
    tmp.write_text(text, encoding="utf-8")


def sweep_inputs(spec: SweepSpec) -> list[Path]:
    """The files a sweep reads: its spec file and its base (a kollagen JSON or a convert.json), and
    for a convert.json base the inputs it names."""
    paths = [Path(p) for p in (spec.source, spec.base) if Path(p).is_file()]
    if Path(spec.base).is_file():
        try:
            doc = json.loads(Path(spec.base).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            doc = None
        if isinstance(doc, dict) and isinstance(doc.get("inputs"), list):
            paths += [Path(i) for i in doc["inputs"] if isinstance(i, str) and i]
    return paths


#: Seconds to wait for a scheduler's port to answer before the sweep is refused (a closed port
#: answers at once; a slow network may need more: the ``STUDIO_SCHEDULER_TIMEOUT_S`` variable).
SCHEDULER_CONNECT_TIMEOUT_S = 5.0


def check_scheduler(scheduler: str) -> None:
    """Refuse, in one line and before any work, a scheduler address the sweep cannot use: not
    ``tcp://host:port`` (``tls://`` needs certificates, which the sweep does not take), a port out
    of range, or a port that does not answer within the timeout (a closed port: at once)."""
    import socket
    from urllib.parse import urlsplit

    where = f"scheduler: {scheduler}"
    try:
        parts = urlsplit(scheduler)
        port = parts.port
    except ValueError as err:
        raise ConfigError(f"{where}: not an address tcp://HOST:PORT ({err})") from None
    if parts.scheme == "tls":
        raise ConfigError(f"{where}: TLS schedulers need certificates, which studio sweep does not take; use tcp://")
    if parts.scheme != "tcp" or not parts.hostname or port is None or parts.path not in ("", "/"):
        raise ConfigError(f"{where}: not an address tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")
    try:
        timeout = float(os.environ.get("STUDIO_SCHEDULER_TIMEOUT_S", SCHEDULER_CONNECT_TIMEOUT_S))
    except ValueError:
        raise ConfigError("STUDIO_SCHEDULER_TIMEOUT_S: expected a number of seconds") from None
    if not (math.isfinite(timeout) and 0 < timeout <= 3600):
        raise ConfigError("STUDIO_SCHEDULER_TIMEOUT_S: expected a number of seconds in (0, 3600]")
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout):
            pass
    except OSError as err:
        cause = "no answer" if isinstance(err, TimeoutError) else (err.strerror or str(err) or type(err).__name__)
        raise ConfigError(f"{where}: cannot connect ({cause})") from None


def _sweep(
    spec: SweepSpec,
    out: Path,
    tasks: list[CellTask],
    scheduler: str | None,
    workers: int | None,
    progress: Progress | None,
    retries: int,
) -> SweepResult:
    (out / "configs").mkdir(parents=True, exist_ok=True)
    groups = {t.group: t.group_config for t in tasks if t.group}  # a seed group's config at replicate 0
    for name, config in [(t.name, t.config) for t in tasks] + list(groups.items()):
        path = out / "configs" / f"{name}.json"
        text = dumps_strict(config, str(path), indent=4) + "\n"
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            write_replacing(path, functools.partial(_write_text, text=text))
    rows: dict[str, dict[str, Any]] = {}
    todo = []
    for t in tasks:
        done = out / "cells" / t.name / RESULT
        if done.is_file():
            rows[t.name] = json.loads(done.read_text(encoding="utf-8"))
        else:
            todo.append(t)
    report(progress, "sweep cells", len(rows), len(tasks), "cells")
    if todo:
        client, cluster = _client(scheduler, workers)
        try:
            from distributed import as_completed

            batches = _batches(todo, sum(client.nthreads().values()) or 1)
            keys = [f"studio-cells-{batch[0].name}" for batch in batches]
            by_key = dict(zip(keys, batches))
            futures = client.map(run_cells, batches, key=keys, retries=retries, pure=False)
            for fut in as_completed(futures):
                try:
                    got = fut.result()
                except Exception as err:  # the cells' worker died on every attempt (KilledWorker), ...
                    got = []
                    for task in by_key[fut.key]:
                        _remove_cell(task)
                        error = f"no attempt finished ({retries + 1} tried): {one_line_error(err)}"
                        got.append(_row(task) | {"error": error})
                for row in got:
                    rows[row["cell"]] = row
                report(progress, "sweep cells", len(rows), len(tasks), "cells")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        _remove_empty_groups(out, todo)
    ordered = [dict(rows[t.name], command=_command(t, out, spec)) for t in tasks]
    return _write_outputs(spec, out, ordered, computed=len(todo))


def _batches(todo: list[CellTask], slots: int) -> list[list[CellTask]]:
    """The Dask tasks: each cell made alone is one; a seed group's unfinished cells are cut into runs
    of consecutive cells, about two per worker thread (``slots``), so that one ``synthesize_seeds``
    call makes many datasets and every worker still has work."""
    batches: list[list[CellTask]] = []
    groups: dict[str, list[CellTask]] = {}
    for t in todo:
        if t.group:
            groups.setdefault(t.group, []).append(t)
        else:
            batches.append([t])
    for members in groups.values():
        size = max(1, math.ceil(len(members) / (2 * slots)))
        batches += [members[k : k + size] for k in range(0, len(members), size)]
    return batches


#: The replay step's options whose ``studio replay`` flag is not the option's name.
_REPLAY_FLAGS = {"step_s": "--step", "period_s": "--period", "seed": "--comms-seed"}


def _replay_flag(key: str, value: Any) -> list[str]:
    """The ``studio replay`` words of one replay option (``polish=False``: ``--no-polish``)."""
    flag = _REPLAY_FLAGS.get(key, f"--{key.replace('_', '-')}")
    if isinstance(value, bool):
        return [flag if value else flag.replace("--", "--no-", 1)] if key == "polish" else ([flag] if value else [])
    return [flag, str(value)]


def _command(task: CellTask, out: Path, spec: SweepSpec) -> str:
    """The shell line that remakes the cell alone (``DIR``: a folder of the user's choice); every
    word is quoted (:func:`shlex.join`), so a pasted line runs the cell's own values and no more."""
    import shlex

    cfg = str(out / "configs" / f"{task.name}.json")
    dataset = f"DIR/{task.name}"
    if task.kind == "synth":
        words = ["studio", "synth", cfg, "-o", "DIR"] + ([] if "record" in task.steps else ["--no-rrd"])
    else:
        words = ["studio", "convert", "--config", cfg, "-o", dataset]
    cmd = shlex.join(words)
    if "solve" in task.steps:
        from studio.solvers import solve_flag

        opts = task.options.get("solve", {})
        flags = [w for k, v in sorted(opts.items()) for w in (solve_flag(k), str(v))]
        cmd += " && " + shlex.join(["studio", "solve", dataset, "-o", "DIR/solved", *flags])
    if "replay" in task.steps:
        opts = dict(task.options.get("replay", {}))
        backends = _replay_backends(opts)
        opts.pop("backends", None)
        flags = [w for k, v in sorted(opts.items()) for w in _replay_flag(k, v)]
        flags += [] if backends is None else ["--backend", ",".join(backends)]
        cmd += " && " + shlex.join(["studio", "replay", dataset, "-o", "DIR/replay", *flags])
    return cmd


def _write_outputs(spec: SweepSpec, out: Path, rows: list[dict[str, Any]], computed: int) -> SweepResult:
    import pandas as pd

    df = pd.DataFrame(rows)
    for col in df.columns:
        if df[col].dtype == object:
            df[col] = df[col].map(lambda v: v if v is None or isinstance(v, str) else json.dumps(v))
    table = out / "sweep.parquet"
    write_replacing(table, lambda tmp: df.to_parquet(tmp, index=False))
    write_replacing(out / "sweep.csv", lambda tmp: df.to_csv(tmp, index=False))
    failed = int(df["error"].notna().sum()) if "error" in df.columns else 0
    md = [
        f"# Sweep `{spec.name}`",
        "",
        f"Base: `{spec.base}`; steps: {', '.join(spec.steps)}; "
        f"{len(rows)} cell{'' if len(rows) == 1 else 's'} ({computed} run now, {failed} failed).",
        "",
    ]
    cols = [c for c in df.columns if c not in ("command", "dataset")]
    md += ["| " + " | ".join(cols) + " |", "|" + "|".join(["---"] * len(cols)) + "|"]
    for _, r in df.iterrows():
        md.append("| " + " | ".join(_fmt(r[c]) for c in cols) + " |")
    md += ["", "Re-run a cell alone (DIR: any folder):", ""]
    md += [f"* `{r['cell']}`: `{r['command']}`" for r in rows]
    markdown = out / "sweep.md"
    write_replacing(markdown, lambda tmp: tmp.write_text("\n".join(md) + "\n", encoding="utf-8"))
    plots = _plots(spec, out, df)
    rrd = None
    try:
        from studio.recording.sweep import write_sweep_recording

        rrd = write_sweep_recording(out / "sweep.rrd", spec.name, df)
    except ImportError:
        rrd = None
    return SweepResult(out, tuple(rows), computed, failed, table, markdown, tuple(plots), rrd)


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


#: Columns plotted against each swept parameter, when present: each panel's title and the unit of
#: its axis. The cells' timings stay in the table and the recording: they depend on the machine and
#: its load, not on the parameter, and would read as a trend (docs/performance.md has the figures).
PLOTTED: dict[str, tuple[str, str]] = {
    "odometry": ("odometry edges", "count"),
    "intra_loop_closures": ("intra-agent loop closures", "count"),
    "inter_loop_closures": ("inter-agent loop closures", "count"),
    "ape_initial_none_m": ("mean APE, initial, unaligned", "m"),
    "ape_initial_se3_m": ("mean APE, initial, SE(3)-aligned", "m"),
    "ape_solved_none_m": ("mean APE, solved, unaligned", "m"),
    "ape_solved_se3_m": ("mean APE, solved, SE(3)-aligned", "m"),
    "chi2_final": ("chi2 after solving", "chi2"),
}


#: The replay step's columns plotted (``replay_<what>`` or ``replay_<backend>_<what>``): team APE,
#: SVE; each suffix with its panel's title and unit.
REPLAY_PLOTTED: dict[str, tuple[str, str]] = {
    "_ape_se3_m": ("team APE, SE(3)-aligned", "m"),
    "_ape_first_pose_m": ("team APE, first-pose", "m"),
    "_sve_t_m": ("SVE, translation", "m"),
    "_sve_r_rad": ("SVE, rotation", "rad"),
}


def _panel(column: str) -> tuple[str, str]:
    """A plotted column's panel title and unit (a replay column named with its back-end)."""
    if column in PLOTTED:
        return PLOTTED[column]
    suffix = next(s for s in REPLAY_PLOTTED if column.endswith(s))
    title, unit = REPLAY_PLOTTED[suffix]
    backend = column.removeprefix("replay").removesuffix(suffix).strip("_")
    return (f"{backend}: {title}" if backend else title), unit


def _save_png(fig: Any, tmp: Path) -> None:
    fig.savefig(tmp, dpi=90, format="png")


def _plotted(df: Any) -> tuple[list[str], list[str]]:
    """The swept parameters worth a plot (varying, not the replicate ``seed``) and the metrics worth
    a panel (present, numeric, not constant)."""
    params = [c for c in df.columns if c.startswith("param:") and c != "param:seed" and df[c].nunique() > 1]
    replayed = [c for c in df.columns if c.startswith("replay_") and c.endswith(tuple(REPLAY_PLOTTED))]
    metrics = [
        c
        for c in [*PLOTTED, *replayed]
        if c in df.columns and df[c].dtype.kind in "fiu" and df[c].dropna().nunique() > 1
    ]
    return params, metrics


def _plots(spec: SweepSpec, out: Path, df: Any) -> list[Path]:
    """One PNG per swept parameter: small multiples, one panel per metric, every cell a point at
    its parameter value (replicates side by side) and the mean over replicates as a line; numeric
    parameters on a numeric axis, others in their order of first appearance."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    params, metrics = _plotted(df)
    if not metrics:
        return []
    paths = []
    (out / "plots").mkdir(exist_ok=True)
    cols = min(3, len(metrics))
    rows = -(-len(metrics) // cols)
    for p in params:
        label = p.removeprefix("param:")
        numeric = df[p].dtype.kind in "fiu"
        order = sorted(df[p].unique()) if numeric else list(dict.fromkeys(df[p].astype(str)))
        x = df[p].to_numpy(dtype=float) if numeric else df[p].astype(str).map(order.index).to_numpy(dtype=float)
        fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 2.6 * rows), squeeze=False, layout="tight")
        for ax in axes.ravel()[len(metrics) :]:
            ax.set_visible(False)
        for ax, m in zip(axes.ravel(), metrics):
            y = df[m].to_numpy(dtype=float)
            ax.plot(x, y, "o", markersize=3, alpha=0.5, color="#0072B2", label="cells")
            means = df.assign(_x=x).groupby("_x")[m].mean()
            ax.plot(means.index, means.to_numpy(), "-", color="#D55E00", linewidth=1.5, label="mean")
            title, unit = _panel(m)
            ax.set_title(title, fontsize=9)
            ax.set_ylabel(f"[{unit}]" if unit != "count" else unit, fontsize=8)
            ax.set_xlabel(label.split(".")[-1], fontsize=8)
            ax.tick_params(labelsize=7)
            if not numeric:
                ax.set_xticks(range(len(order)), order, rotation=30, ha="right")
            ax.grid(alpha=0.3)
        axes.ravel()[0].legend(fontsize=7, frameon=False)
        fig.suptitle(f"{spec.name}: metrics against {label} ({len(df)} cells)", fontsize=10)
        path = out / "plots" / f"{safe_file_name(label.replace('.', '_'), fallback='parameter')}.png"
        write_replacing(path, functools.partial(_save_png, fig))
        plt.close(fig)
        paths.append(path)
    return paths
