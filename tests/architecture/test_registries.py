"""The registries are the one place a plug-in is declared: the CLI's choices and help lists, the
solve defaults and bench's per-method options come from them, and the recipes of
docs/architecture.md ("Where new things go") hold: a dummy method and a dummy source, each one
registry entry registered for the test only, reach the CLI, the pipelines and bench with nothing
else changed; a dummy generator mode reaches the config parser and ``studio synth``."""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import importlib
import json
import re
from collections.abc import Iterator, MutableMapping
from pathlib import Path
from typing import Any, get_args

import numpy as np
import pytest
import typer.main
from typer.testing import CliRunner

import studio.cli
from studio.bench import bench_spec_from_dict
from studio.convert_config import accepted_options, convert_options
from studio.converters.options import OPTION_NEEDS
from studio.converters.registry import SOURCES, Source, guess_source
from studio.converters.tum import read_tum_sources
from studio.core.comms import Always, parse_comms
from studio.core.comms_registry import COMMS_MODELS, CommsModelEntry
from studio.core.errors import ConfigError
from studio.generator.extended import WALK_MODES, WalkMode
from studio.io.synth_config import parse_synth_config
from studio.solvers import METHODS, SolveMethod, solve_flag
from studio.solvers.options import DgsOptions, SolveOptions
from studio.solvers.problem import Init, Optimizer, Solution
from tests.converters.synthetic import loop_trajectory, write_tum_file

REPO = Path(__file__).resolve().parents[2]
DATA = REPO / "tests" / "data"


def _params(app: typer.Typer, command: str) -> dict[str, Any]:
    return {p.name: p for p in typer.main.get_command(app).commands[command].params}  # type: ignore[attr-defined]


def _help(app: typer.Typer, command: str) -> str:
    """The command's help without white space (help text wraps lines, also at hyphens)."""
    res = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "300"})
    assert res.exit_code == 0, res.output
    return re.sub(r"\s+", "", res.output)


def _bare(text: str) -> str:
    return re.sub(r"\s+", "", text)


@contextlib.contextmanager
def _registered(registry: MutableMapping[str, Any], name: str, entry: Any) -> Iterator[typer.Typer]:
    """``entry`` in ``registry`` under ``name``, and the CLI built anew from the registries; both
    restored afterwards (the CLI module is reloaded, since typer reads the choices when it is built)."""
    assert name not in registry
    registry[name] = entry
    try:
        yield importlib.reload(studio.cli).app
    finally:
        del registry[name]
        importlib.reload(studio.cli)


# ------------------------------------------------------------------------------------ the CLI's lists


def test_solve_choices_and_help_are_the_method_registry():
    params = _params(studio.cli.app, "solve")
    assert tuple(params["method"].type.choices) == tuple(METHODS)
    assert tuple(params["optimizer"].type.choices) == get_args(Optimizer)
    assert tuple(params["init"].type.choices) == get_args(Init)
    text = _help(studio.cli.app, "solve")
    for name, entry in METHODS.items():
        assert _bare(f"{name} ({entry.help})") in text
    assert "g2o:10" in text  # g2o's own default, declared on its entry


def test_convert_help_lists_the_source_registry():
    text = _help(studio.cli.app, "convert")
    for name, src in SOURCES.items():
        assert _bare(f"{name}: {src.help}") in text
        assert _bare(f"{name}: {src.inputs}") in text


def test_the_cli_and_pipelines_name_no_method_or_source():
    """Choices are not copied: no method or source name is written in the CLI, and the pipelines do
    not switch on one (``== "g2o"``, ``== "airmuseum"``)."""
    cli = (REPO / "studio" / "cli.py").read_text(encoding="utf-8")
    for name in (*METHODS, *SOURCES):
        assert not re.search(rf'(?<![\w-])"{re.escape(name)}"', cli), name
    for module in ("solve.py", "bench.py", "convert.py", "sweep.py"):
        text = (REPO / "studio" / module).read_text(encoding="utf-8")
        for name in (*METHODS, *SOURCES):
            assert not re.search(rf'[=!]= *"{re.escape(name)}"', text), (module, name)


def _strings(node: ast.AST) -> set[str]:
    """The string constants under ``node``, but for subscripts (``counts['odometry']`` reads a
    result's key, it declares nothing)."""
    keys = {id(n) for sub in ast.walk(node) if isinstance(sub, ast.Subscript) for n in ast.walk(sub.slice)}
    return {
        n.value
        for n in ast.walk(node)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in keys
    }


def test_the_cli_copies_no_comms_model_or_convert_option_name():
    """The CLI names no communication model (its help, choices and default come from COMMS_MODELS)
    and the convert command names none of its options: their flags, help and which source takes
    them come from convert_options() and the source registry (the hand-written list of options a
    graph source refused had drifted: it named `body_frame`, the parameter is `body_frames`)."""
    tree = ast.parse((REPO / "studio" / "cli.py").read_text(encoding="utf-8"))
    models = set(COMMS_MODELS) | {e.grammar for e in COMMS_MODELS.values()}
    assert not models & _strings(tree)
    options = set()
    for o in convert_options():
        options |= {o.name, o.flag, "--" + o.flag.replace("_", "-")}
    convert = [n for n in tree.body if isinstance(n, ast.FunctionDef) and "convert" in n.name]
    assert {n.name for n in convert} >= {"convert", "_with_convert_options"}
    for node in convert:
        assert not options & _strings(node), node.name
    text = _help(studio.cli.app, "convert")
    for o in convert_options():
        assert "--" + o.flag.replace("_", "-") in text


def test_replay_help_and_errors_are_the_comms_registry():
    text = _help(studio.cli.app, "replay")
    for entry in COMMS_MODELS.values():
        assert _bare(f"{entry.grammar}: {entry.help}") in text
    entry = CommsModelEntry("radio:P", "the test's radio, always up", lambda arg, spec: Always())
    with _registered(COMMS_MODELS, "radio", entry) as app:
        assert _bare("radio:P: the test's radio, always up") in _help(app, "replay")
        assert parse_comms("radio:1") == Always()
    with pytest.raises(ConfigError, match=r"unknown model 'radio:1' \(known: always \| never"):
        parse_comms("radio:1")


def _table(doc: str, header: str) -> list[str]:
    """The lines of the markdown table of ``doc`` that starts with ``header``."""
    lines = (REPO / "docs" / doc).read_text(encoding="utf-8").splitlines()
    start = lines.index(header)
    end = next((k for k in range(start, len(lines)) if not lines[k].startswith("|")), len(lines))
    return lines[start:end]


def test_the_docs_tables_are_the_registries():
    """docs/replay.md's table of communication models and docs/converters.md's table of which source
    takes which option say what the registries declare."""
    models = ["| `--comms` | who can talk |", "| --- | --- |"]
    models += [f"| `{e.grammar}` | {e.help} |" for e in COMMS_MODELS.values()]
    assert _table("replay.md", models[0]) == models
    trajectory = [n for n, s in SOURCES.items() if s.read_graph is None]
    flag = {o.name: "`--" + o.flag.replace("_", "-") + "`" for o in convert_options()}
    groups: dict[tuple[str, ...], list[str]] = {}
    for o in convert_options():
        takers = tuple(n for n in SOURCES if o.name in accepted_options(n, synthesize=False))
        needs = f" (with {flag[OPTION_NEEDS[o.name]]})" if o.name in OPTION_NEEDS else ""
        groups.setdefault(takers, []).append(flag[o.name] + needs)
    rows = ["| option | sources that take it |", "| --- | --- |"]
    for takers, flags in groups.items():
        rest = [n for n in takers if n not in trajectory]
        if set(trajectory) <= set(takers):
            who = "every trajectory source" + (f" and {', '.join(rest)}" if rest else "")
        else:
            who = ", ".join(takers)
        rows.append(f"| {', '.join(flags)} | {who} |")
    assert _table("converters.md", rows[0]) == rows


def test_an_entry_may_only_name_solve_options():
    with pytest.raises(ConfigError, match="'iters' is not a SolveOptions field"):
        SolveMethod("bad", METHODS["gtsam"].solve, "", ("iters",))
    with pytest.raises(ConfigError, match="'robots' is not a SolveOptions field"):  # dgs's own option
        SolveMethod("bad", METHODS["gtsam"].solve, "", ("robots",))
    with pytest.raises(ConfigError, match="a default for 'init', which it does not read"):
        SolveMethod("bad", METHODS["gtsam"].solve, "", ("max_iterations",), {"init": "odometry"})
    with pytest.raises(ConfigError, match="its own option 'init' is a SolveOptions field"):
        SolveMethod("bad", METHODS["gtsam"].solve, "", (), method_options=_ClashingOptions)


@dataclasses.dataclass(frozen=True)
class _ClashingOptions:
    init: str = "odometry"


def test_each_method_declares_its_own_options_and_reads_no_other():
    """A method's own options are the fields of the class its entry names (not one shared bag): no
    field is a shared option or another method's, every field is a `studio solve` flag with the
    field's default, the CLI names none of them, and a back-end's module names no other method's
    options class."""
    shared = {f.name for f in dataclasses.fields(SolveOptions)}
    owners: dict[str, str] = {}
    classes = {e.method_options: name for name, e in METHODS.items() if e.method_options is not None}
    assert set(classes.values()) == {"dgs", "command"}
    params = _params(studio.cli.app, "solve")
    for name, entry in METHODS.items():
        own = entry.own_option_names()
        assert entry.option_names() == (*entry.options, *own)
        for key in own:
            assert key not in shared and owners.setdefault(key, name) == name, key
            field = next(f for f in dataclasses.fields(entry.method_options) if f.name == key)
            assert params[key].default == field.default and solve_flag(key) in params[key].opts
        module = (REPO / (entry.solve.module.replace(".", "/") + ".py")).read_text(encoding="utf-8")
        for cls, owner in classes.items():
            assert owner == name or cls.__name__ not in module, (name, cls.__name__)
    solve = next(
        n
        for n in ast.parse((REPO / "studio" / "cli.py").read_text(encoding="utf-8")).body
        if isinstance(n, ast.FunctionDef) and n.name == "solve"
    )
    assert not set(owners) & _strings(solve)
    assert solve_flag("max_iterations") in params["iterations"].opts and solve_flag("coarse_size") == "--coarse"
    # each default written once: the registry's and the back-end's come from studio/solvers/options.py
    from studio.solvers import dgs

    assert dgs.dgs_rounds.__kwdefaults__["coarse_size"] is DgsOptions.coarse_size
    assert dgs.dgs_rounds.__kwdefaults__["rotation_tol"] is DgsOptions.rotation_tol


# ------------------------------------------------------------------------- a dummy method, one entry


def _dead_reckoning(problem, options, on_iteration=None):
    """A method that returns the initial values after ``options.max_iterations`` do-nothing steps,
    noting its own option ``label``."""
    label = options.own_options(_DummyOptions).label
    return Solution(problem.initial.copy(), options.max_iterations, notes={"dummy": True, "label": label})


@dataclasses.dataclass(frozen=True)
class _DummyOptions:
    label: str = dataclasses.field(default="none", metadata={"help": "a word noted in solve.json."})


def test_a_new_method_is_one_registry_entry(tmp_path):
    from studio.synth import load_synth_config, synthesize

    ds = synthesize(load_synth_config(DATA / "configs" / "tiny_single.json"), tmp_path, rrd=False, jobs=1)
    entry = SolveMethod(
        "dead-reckoning",
        _dead_reckoning,
        "keeps the initial values",
        ("max_iterations",),
        {"max_iterations": 3},
        method_options=_DummyOptions,
    )
    with _registered(METHODS, "dead-reckoning", entry) as app:
        assert "dead-reckoning" in _params(app, "solve")["method"].type.choices
        text = _help(app, "solve")
        assert _bare("dead-reckoning (keeps the initial values)") in text and "dead-reckoning:3" in text
        assert _bare("--label <str> dead-reckoning: a word noted in solve.json.") in text  # its own option's flag
        out = tmp_path / "solved"
        res = CliRunner().invoke(
            app, ["solve", str(ds.dataset_dir), "-o", str(out), "-m", "dead-reckoning", "--label", "x"]
        )
        assert res.exit_code == 0, res.output
        info = json.loads((out / "solve.json").read_text())
        assert info["method"] == "dead-reckoning" and info["iterations"] == 3  # the entry's own default
        assert info["notes"] == {"dummy": True, "label": "x"} and info["options"]["label"] == "x"
        assert info["chi2_final"] == pytest.approx(info["chi2_dataset"])
        res = CliRunner().invoke(app, ["solve", str(ds.dataset_dir), "-o", str(tmp_path / "g"), "--label", "x"])
        assert res.exit_code == 2 and "--label: method gtsam does not read it" in res.stderr
        # bench takes it, with the options its entry reads and no other
        spec = {
            "datasets": ["x"],
            "methods": ["dead-reckoning"],
            "options": {"dead-reckoning": {"max_iterations": 5, "label": "y"}},
        }
        assert bench_spec_from_dict(spec, "spec.toml").methods == ("dead-reckoning",)
        spec["options"] = {"dead-reckoning": {"init": "odometry"}}
        with pytest.raises(ConfigError, match=r"options\.dead-reckoning\.init: unknown solve option"):
            bench_spec_from_dict(spec, "spec.toml")
    assert "dead-reckoning" not in _params(studio.cli.app, "solve")["method"].type.choices
    assert "label" not in _params(studio.cli.app, "solve")


# ------------------------------------------------------------------------- a dummy source, one entry


def _read_walker(inputs, *, agents=(), warn=None, progress=None):
    """A ``.walk`` file is a TUM file under another suffix (the test's stand-in for a new format)."""
    return read_tum_sources(inputs, agents=agents, warn=warn, progress=progress)


def test_a_new_source_is_one_registry_entry(tmp_path):
    s, p, q = loop_trajectory(300)
    walk = write_tum_file(tmp_path / "walker.walk", s, p, q)
    tum = write_tum_file(tmp_path / "walker.tum", s, p, q)
    entry = Source(
        _read_walker,
        "walk files",
        "their files",
        "the test's walk files",
        detect=lambda path: path.suffix == ".walk",
        body_frames={"walker": "ufl"},
    )
    with _registered(SOURCES, "walk", entry) as app:
        text = _help(app, "convert")
        assert _bare("walk: the test's walk files") in text and "walk:walkfiles" in text
        assert guess_source([walk]) == "walk"

        def convert(*args: object) -> dict[str, bytes]:
            out = tmp_path / f"ds{len(list(tmp_path.glob('ds*')))}"
            res = CliRunner().invoke(app, ["convert", *map(str, args), "-o", str(out), "--no-rrd"])
            assert res.exit_code == 0, res.output
            return {p.name: p.read_bytes() for p in sorted((out / "agent1").iterdir())}

        guessed = convert(walk)  # no FORMAT: the entry's detect claims the path
        assert guessed == convert("walk", walk)
        # the entry's default body frame is applied (the TUM source has none) and --body-frame wins
        assert guessed != convert("tum", tum)
        assert convert("walk", walk, "--body-frame", "walker=flu") == convert("tum", tum)
    with pytest.raises(ConfigError, match="cannot tell the source"):
        guess_source([walk])


def test_a_path_two_sources_claim_is_ambiguous(tmp_path):
    path = tmp_path / "x.tum"
    path.write_text("1 0 0 0 0 0 0 1\n")
    entry = Source(_read_walker, "files", "their files", "", detect=lambda p: p.suffix == ".tum")
    with _registered(SOURCES, "also-tum", entry):
        with pytest.raises(ConfigError, match="the inputs look like also-tum, tum: name it"):
            guess_source([path])


def test_detection_sees_each_source(tmp_path):
    """Each entry's detect recognises its own layout and no other's."""
    (tmp_path / "seq" / "mav0" / "state_groundtruth_estimate0").mkdir(parents=True)
    (tmp_path / "seq" / "mav0" / "state_groundtruth_estimate0" / "data.csv").write_text("#t\n")
    (tmp_path / "s3e").mkdir()
    (tmp_path / "s3e" / "alpha_gt.txt").write_text("1 0 0 0 0 0 0 1\n")
    (tmp_path / "am" / "data" / "robotA").mkdir(parents=True)
    (tmp_path / "am" / "data" / "robotA" / "body_stamped_groundtruth.txt").write_text("# t\n")
    (tmp_path / "kimera").mkdir()
    (tmp_path / "kimera" / "acl_jackal_gt_odom.csv").write_text("t\n")
    (tmp_path / "ros2").mkdir()
    (tmp_path / "ros2" / "metadata.yaml").write_text("x\n")
    (tmp_path / "poses.txt").write_text(" ".join(["0"] * 12) + "\n")
    (tmp_path / "traj.txt").write_text("# comment\n" + " ".join(["0"] * 8) + "\n")
    (tmp_path / "m.jrl").write_text("{}\n")
    (tmp_path / "m.g2o").write_text("VERTEX_SE2 0 0 0 0\n")
    (tmp_path / "dgs").mkdir()
    (tmp_path / "dgs" / "fullGraph.g2o").write_text("VERTEX_SE2 0 0 0 0\n")
    (tmp_path / "dpgo" / "robot0").mkdir(parents=True)
    (tmp_path / "dpgo" / "robot0" / "measurements.csv").write_text("robot_src\n")
    (tmp_path / "MRCLAM_Dataset1").mkdir()
    (tmp_path / "MRCLAM_Dataset1" / "Robot1_Groundtruth.dat").write_text("# Time [s]\n")
    expected = {
        "seq": "euroc",
        "s3e": "s3e",
        "am": "airmuseum",
        "kimera": "kimera-multi",
        "ros2": "bag",
        "poses.txt": "kitti",
        "traj.txt": "tum",
        "m.jrl": "jrl",
        "m.g2o": "g2o",
        "dgs": "symbols",
        "dpgo": "dpgo",
        "MRCLAM_Dataset1": "mrclam",
    }
    for name, source in expected.items():
        assert guess_source([tmp_path / name]) == source, name
    np.testing.assert_equal(sorted(expected.values()), sorted(SOURCES))


# ------------------------------------------------------------------------- a dummy mode, one entry


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_new_generator_mode_is_one_registry_entry(tmp_path):
    from studio.synth import load_synth_config, synthesize

    data = json.loads((DATA / "configs" / "small3x100.json").read_text())
    data["exact_information_matrix"] = False
    calls: list[str] = []

    def again(name: str) -> Any:
        def run(cfg, seeds, *, jobs, progress):  # another walk's, counted
            calls.append(cfg.name)
            return WALK_MODES[name].run(cfg, seeds, jobs=jobs, progress=progress)

        return run

    data["studio"] = {"version": 1, "walk": "again"}
    with pytest.raises(ConfigError, match=r"studio\.walk.*'again'"):
        parse_synth_config(data, name="again")
    with _registered(WALK_MODES, "again", WalkMode("again", "kollagen's walk, counted", again("kollagen"), True)):
        res = synthesize(parse_synth_config(data, name="again"), tmp_path / "a", rrd=False, jobs=1)
    assert calls == ["again"]
    plain = synthesize(load_synth_config(DATA / "configs" / "small3x100.json"), tmp_path / "b", rrd=False, jobs=1)
    assert res.single_dir is not None and res.single_dir.is_dir()  # a planar mode offers the single-g2o view
    assert _files(res.dataset_dir) == _files(plain.dataset_dir)  # the same walk: the same bytes
    assert json.loads(res.config_path.read_text())["studio"]["walk"] == "again"

    # a spatial mode: no single-g2o view, and neither Exact information nor 2D records
    data["studio"] = {"version": 1, "walk": "tower"}
    with _registered(WALK_MODES, "tower", WalkMode("tower", "grid3d's walk, counted", again("grid3d"), False)):
        res = synthesize(parse_synth_config(data, name="tower"), tmp_path / "c", rrd=False, jobs=1)
        assert res.single_dir is None and res.output.graph.kind.name == "SE3"
        with pytest.raises(ConfigError, match="walk tower is 3D"):
            synthesize(parse_synth_config(data, name="tower"), tmp_path / "d", multi_records="2d", rrd=False)
        with pytest.raises(ConfigError, match='Exact information is planar; walk "tower"'):
            parse_synth_config({**data, "exact_information_matrix": True}, name="tower")
        with pytest.raises(ConfigError, match='studio.grid3d.*applies to walk "grid3d" only'):
            parse_synth_config({**data, "studio": {**data["studio"], "grid3d": {"vertical_step": 2.0}}}, name="t")
    assert calls == ["again", "tower"]
