"""Nothing lost, nothing escapes, round four (issue 41): names given as options or found in data
never decide where a file goes, inputs that live inside an output are never replaced, every input
is a regular file, and each refusal comes before the first byte is written (every byte of the
working folder is compared before and after)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.reliability import test_guard as guard

made, world = guard.made, guard.world  # the guard tests' fixtures: a synth dataset and a working folder
refused_intact = guard.refused_intact

#: Every hostile path component: a parent, an absolute path, a separator, NUL, a line break.
HOSTILE_NAMES = ["..", "../../ds/agent1/posegraph", "/tmp/studio-escaped", "a/b", "a\x00b", "a\nb"]


# --------------------------------------------------------------------------- names from options
@pytest.mark.parametrize("fmt", ["dpgo", "symbols", "jrl"])
@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_export_name_must_be_one_plain_component(world, fmt, hostile):
    """``--name ../../ds/agent1/posegraph`` once wrote DPGO's g2o over the dataset's own file
    (exit 0); ``/abs`` and ``../../escaped`` wrote outside ``-o``."""
    out = "out.jrl" if fmt == "jrl" else "out"
    Path("/tmp/studio-escaped.g2o").unlink(missing_ok=True)  # an earlier run of the old code
    err = refused_intact(["export", "ds", "-f", fmt, "-o", out, "--name", hostile], world, "--name: ")
    assert "\\n" in err or "\n" not in hostile  # the line break is shown escaped, the message one line
    assert not Path("/tmp/studio-escaped.g2o").exists()


@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_bag_agent_name_must_be_one_plain_component(world, hostile):
    (world / "run.bag").write_bytes(b"")  # never read: the name is refused first
    refused_intact(["convert", "bag", "run.bag", "--agent", f"{hostile}=/odom", "-o", "out"], world, "agent name")


def test_export_library_refuses_a_name_that_is_not_a_string(world):
    from studio.core.errors import ConfigError
    from studio.export import export_dataset

    with pytest.raises(ConfigError, match="--name: expected a string, got int"):
        export_dataset(world / "ds", world / "out", format="dpgo", name=3)  # type: ignore[arg-type]
    assert not (world / "out").exists()


def test_a_plain_export_name_names_the_files(world):
    from studio.export import export_dataset

    res = export_dataset(world / "ds", world / "out", format="dpgo", name="my data+1")
    assert "my data+1.g2o" in res.files and (world / "out" / "my data+1.g2o").is_file()


# --------------------------------------------------------------------------- names from data
@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_agent_names_in_agents_json_stay_inside_the_output(world, hostile):
    """Names found in data are made plain (``studio.io.names.safe_file_name``), never followed."""
    ds = world / "ds"
    agents = [{"folder": f"agent{k + 1}", "name": n} for k, n in enumerate([hostile, "bob", "carol"])]
    (ds / "agents.json").write_text(json.dumps({"format": "cslam-studio agents 1", "agents": agents}))
    before = guard._tree(world)
    res = guard.runner.invoke(guard.app, ["solve", "ds", "-o", "est"])
    assert res.exit_code == 0, res.stderr
    assert all(m.startswith("est") for m in set(guard._tree(world)) - set(before))
    assert not Path("/tmp/studio-escaped.tum").exists()


# --------------------------------------------------------------------------- inputs inside outputs
@pytest.fixture
def config_in_output(world) -> Path:
    """``out/`` holds a synth run of ``tiny_three.json`` and a copy of that config inside the dataset
    folder it wrote (``out/tiny_three/tiny_three.json``); ``out/seed0001/`` holds another copy."""
    from studio.synth import load_synth_config, synthesize, synthesize_seeds

    cfg = load_synth_config(world / "tiny_three.json")
    synthesize(cfg, world / "out", rrd=False, jobs=1)
    synthesize_seeds(cfg, world / "out", [0, 1], rrd=False, jobs=1)
    for folder in ("tiny_three", "seed0001"):
        (world / "out" / folder / "tiny_three.json").write_bytes((world / "tiny_three.json").read_bytes())
    return world / "out"


def test_synth_force_never_replaces_the_folder_holding_its_config(world, config_in_output):
    """``studio synth out/my/my.json -o out --force`` deleted the config it was given."""
    refused_intact(
        ["synth", "out/tiny_three/tiny_three.json", "-o", "out", "--force", "--no-rrd"], world, "contains the input"
    )


def test_synth_seeds_force_never_replaces_the_seed_folder_holding_its_config(world, config_in_output):
    refused_intact(
        ["synth", "out/seed0001/tiny_three.json", "-o", "out", "--force", "--seeds", "0..2", "--no-rrd"],
        world,
        "out/seed0001: the output contains the input",
    )


def test_synth_seeds_checks_every_seed_folder_before_writing_the_first(world):
    """``--seeds 0..2 -o out`` where ``out/seed0001`` is the user's folder wrote ``seed0000`` first."""
    (world / "out" / "seed0001").mkdir(parents=True)
    (world / "out" / "seed0001" / "notes.txt").write_text("mine\n")
    refused_intact(
        ["synth", "tiny_three.json", "-o", "out", "--seeds", "0..2", "--no-rrd"], world, "out/seed0001 already exists"
    )
    refused_intact(
        ["synth", "tiny_three.json", "-o", "out", "--seeds", "0..2", "--no-rrd", "--force"],
        world,
        "a folder studio did not write",
    )


def test_replay_refuses_a_recording_that_is_its_output_folder_before_any_work(world):
    """``studio replay ds -o r.rrd --rrd r.rrd`` wrote the replay folder, then refused."""
    refused_intact(["replay", "ds", "-o", "r.rrd", "--rrd", "r.rrd"], world, "r.rrd: the output is the other output")
    refused_intact(["replay", "ds", "-o", "rr", "--rrd", "rr/x.rrd"], world, "sits inside the other output rr")


def test_convert_force_never_replaces_the_folder_holding_its_convert_json(world):
    res = guard.runner.invoke(guard.app, ["convert", "tum", "alpha.tum", "bob.tum", "-o", "conv", "--no-rrd"])
    assert res.exit_code == 0, res.stderr
    refused_intact(
        ["convert", "--config", "conv/convert.json", "-o", "conv", "--force", "--no-rrd"], world, "contains the input"
    )


def test_distinct_outputs():
    from studio.core.errors import OutputError
    from studio.io.atomic import check_distinct_outputs

    check_distinct_outputs(["a", "b", "a.rrd", "ab/c"])
    for pair, what in ((["a", "a"], "is"), (["a", "a/b.rrd"], "sits inside"), (["a/b", "a"], "contains")):
        with pytest.raises(OutputError, match=f"the output {what} the other output"):
            check_distinct_outputs(pair)


# --------------------------------------------------------------------------- inputs that are not files
_NOT_FILES = {
    "rendezvous": ["replay", "ds", "--comms", "rendezvous:{p}", "-o", "out"],
    "jrl": ["convert", "jrl", "{p}", "-o", "out", "--no-rrd"],
    "synth config": ["synth", "{p}", "-o", "out", "--no-rrd"],
    "convert.json": ["convert", "--config", "{p}", "-o", "out", "--no-rrd"],
    "tum": ["convert", "tum", "{p}", "bob.tum", "-o", "out", "--no-rrd"],
    "sweep spec": ["sweep", "{p}", "-o", "out"],
}

_RUN_ALL = """
import json, sys
from typer.testing import CliRunner
from studio.cli import app
out = {}
for key, args in json.loads(sys.argv[1]).items():
    res = CliRunner().invoke(app, args)
    out[key] = [res.exit_code, res.stderr, res.stdout]
print(json.dumps(out))
"""


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_an_input_that_is_not_a_regular_file_is_one_line_and_never_blocks(world, kind):
    """A FIFO given as a rendezvous file or a JRL file blocked forever. The commands run in a child
    process with a timeout, so a reader that waits on the FIFO fails the test instead of hanging it."""
    import os
    import subprocess
    import sys

    if kind == "fifo":
        os.mkfifo(world / "in.x")
        path, match = "in.x", "is a FIFO (named pipe), not a regular file"
    elif kind == "device":
        path, match = "/dev/zero", "/dev/zero: is a character device, not a regular file"
    else:
        (world / "in.x").mkdir()
        path, match = "in.x", "is a folder"
    cases = {key: [a.format(p=path) for a in args] for key, args in _NOT_FILES.items()}
    before = guard._tree(world)
    child = subprocess.run(
        [sys.executable, "-c", _RUN_ALL, json.dumps(cases)],
        capture_output=True,
        text=True,
        timeout=25,
        cwd=world,
        env={**os.environ, "RERUN_ANALYTICS": "0"},
    )
    assert child.returncode == 0, child.stderr
    results = json.loads(child.stdout)
    for key, (code, err, out) in results.items():
        assert code == 2 and out == "", (key, code, err, out)
        assert len(err.splitlines()) == 1 and err.startswith("error: ") and match in err, (key, err)
    assert guard._tree(world) == before


# --------------------------------------------------------------------------- readers that believed their numbers
@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[]", 'agents.json: expected {"format"'),
        ("null", 'agents.json: expected {"format"'),
        ('"agents"', 'agents.json: expected {"format"'),
        (["agent1", "agent1", "agent3"], "agents[1]: the folder 'agent1' is already agents[0]'s"),
        (["agent1", "agent2"], "agents.json: the agent folder agent3 is not listed"),
    ],
)
def test_a_bad_agents_json_is_one_line_naming_it(world, text, match):
    """``[]`` and ``null`` raised AttributeError in every dataset command; two agents named to one
    folder read one folder twice; an unlisted folder was blamed on inter_agent_lc.dat."""
    if isinstance(text, list):
        names = ["a", "b", "c"]
        agents = [{"folder": f, "name": n} for f, n in zip(text, names)]
        text = json.dumps({"format": "cslam-studio agents 1", "agents": agents})
    (world / "ds" / "agents.json").write_text(text)
    for command in (["record", "ds", "-o", "x.rrd"], ["solve", "ds", "-o", "est"], ["check", "ds"]):
        refused_intact(command, world, match)


@pytest.mark.parametrize(
    ("line", "match"),
    [
        (f"0,0,{2**70}", "rz.txt:1: time [s] 1180591620717411303424 is outside [-9223372036, 9223372036]"),
        ("0,0,1_0", "rz.txt:1: expected ROBOT_ID,start,end,... as integers (decimal digits), got '0,0,1_0'"),
        ("1_0,0,3", "rz.txt:1: expected ROBOT_ID,start,end,... as integers (decimal digits), got '1_0,0,3'"),
        ("0,0," + "9" * 5000, "rz.txt:1: expected an integer (decimal digits) for the time [s], got '99999"),
        ("0,true,3", "rz.txt:1: expected ROBOT_ID,start,end,... as integers (decimal digits), got '0,true,3'"),
    ],
)
def test_rendezvous_numbers_are_plain_bounded_integers(world, line, match):
    """A window ending at 2^70 was an OverflowError; ``1_0`` was read as 10 (Swarm-SLAM reads 1)."""
    (world / "rz.txt").write_text(line + "\n")
    refused_intact(["replay", "ds", "--comms", "rendezvous:rz.txt", "-o", "out"], world, match)


def test_a_replay_clock_beyond_int64_is_one_line(world):
    """``--period 1e8 --step 1e8`` wrapped int64 stamps round into a GTSAM error."""
    refused_intact(
        ["replay", "ds", "--period", "1e8", "--step", "1e8", "-o", "out"], world, "--period: 100000000000000000 ns x"
    )


def test_a_comms_period_below_the_clock_says_so(world):
    refused_intact(
        ["replay", "ds", "--comms", "range:5,period=4e-10", "-o", "out"], world, "below the replay's 1 ns clock"
    )


def _jrl_with(world: Path, old: str, new: str) -> None:
    text = (world / "ds.jrl").read_text()
    assert old in text
    (world / "bad.jrl").write_text(text.replace(old, new, 1))


@pytest.fixture
def jrl_world(world) -> Path:
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "jrl", "-o", "ds.jrl"])
    assert res.exit_code == 0, res.stderr
    return world


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ('"0.5"', 'translation[0]: expected a number, got "0.5"'),
        ("true", "translation[0]: expected a number, got true"),
        ("1e300", "translation[0]: 1e+300 is beyond 1e+09 m"),
        ("9" * 400, "translation[0]: a number beyond a double's range"),
        ("9" * 5000, "an integer of 5000 digits"),
    ],
)
def test_jrl_numbers_are_numbers_within_the_bounds(jrl_world, value, match):
    """Strings and booleans were read as numbers, 1e300 m accepted, a 400-digit integer an
    OverflowError and a 5000-digit one Python's ValueError about its own limit."""
    text = (jrl_world / "ds.jrl").read_text()
    start = text.index('"translation":[') + len('"translation":[')
    end = text.index(",", start)
    (jrl_world / "bad.jrl").write_text(text[:start] + value + text[end:])
    refused_intact(["convert", "jrl", "bad.jrl", "-o", "out", "--no-rrd"], jrl_world, match)


def test_a_jrl_key_of_5000_digits_is_one_line(jrl_world):
    text = (jrl_world / "ds.jrl").read_text()
    start = text.index('"key1":') + len('"key1":')
    end = text.index(",", start)
    (jrl_world / "bad.jrl").write_text(text[:start] + "9" * 5000 + text[end:])
    refused_intact(["convert", "jrl", "bad.jrl", "-o", "out", "--no-rrd"], jrl_world, "an integer of 5000 digits")


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        (3, "2000000000", "robot 0 pose 2000000000: ids far beyond the"),
        (0, "1999999999", "robot id 1999999999 with only"),
    ],
)
def test_dpgo_ids_are_bounded_before_poses_are_allocated(world, field, value, match):
    """An id of 2,000,000,000 in measurements.csv allocated about 15 GiB before anything was said."""
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "dpgo", "-o", "dp"])
    assert res.exit_code == 0, res.stderr
    csv = world / "dp" / "robot0" / "measurements.csv"
    lines = csv.read_text().splitlines()
    fields = lines[2].split(",")
    fields[field] = value
    lines[2] = ",".join(fields)
    csv.write_text("\n".join(lines) + "\n")
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    refused_intact(["convert", "dpgo", "dp", "-o", "out", "--no-rrd"], world, match)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 1_000_000  # kB: under 1 GB more


# --------------------------------------------------------------------------- the library validates as the CLI does
def _tiny():
    from studio.synth import load_synth_config
    from tests.conftest import DATA

    return load_synth_config(DATA / "configs" / "tiny_three.json")


def _with(**changes):
    import dataclasses

    cfg = _tiny()
    inter = {k: v for k, v in changes.items() if k in ("loop_closure_radius",)}
    top = {k: v for k, v in changes.items() if k not in inter}
    if inter:
        top["inter"] = dataclasses.replace(cfg.inter, **inter)
    return dataclasses.replace(cfg, **top)


@pytest.mark.parametrize(
    ("make", "kwargs", "match"),
    [
        (lambda: {"number_of_agents": 2}, {}, "config: number_of_steps: missing key"),
        (lambda: 42, {}, "config: expected a SynthConfig"),
        (
            lambda: None,
            {},
            "config: expected a SynthConfig, a kollagen JSON document (dict) or a config file's path, got NoneType",
        ),
        (lambda: "/nonexistent/x.json", {}, "/nonexistent/x.json: no such file"),
        (lambda: _with(stepsize=0.0), {}, "config: agent_parameters.stepsize: must be positive, got 0.0"),
        (lambda: _with(stepsize=float("nan")), {}, "config: agent_parameters.stepsize: must be finite"),
        (lambda: _with(loop_closure_radius=0.0), {}, "inter_agent_loop_closure_parameters.loop_closure_radius"),
        (lambda: _with(number_of_steps=2.5), {}, "config: number_of_steps: must be an integer, got 2.5"),
        (lambda: _with(number_of_agents=0, agents=()), {}, "config: number_of_agents: must be at least 1, got 0"),
        (_tiny, {"seed": None}, "seed: expected a non-negative integer, got None"),
        (_tiny, {"seed": -1}, "seed: expected a non-negative integer, got -1"),
        (_tiny, {"jobs": "2"}, "jobs: expected None or 0 (the idle cores) .. 4096, got '2'"),
    ],
)
def test_generate_refuses_what_the_json_reader_refuses(make, kwargs, match):
    """A dict, a path, None, a zero or NaN step, a zero radius, no agents, a float step count, a
    None seed or a string job count raised AttributeError, ZeroDivisionError, IndexError,
    TypeError or MemoryError from the in-memory generator."""
    from studio.core.errors import ConfigError
    from studio.synth import generate

    with pytest.raises(ConfigError) as info:
        generate(make(), **kwargs)
    assert match in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("seeds", "kwargs", "match"),
    [
        (None, {}, "seeds: expected an iterable of non-negative integers, got None"),
        ([0, None], {}, "seed: expected a non-negative integer, got None"),
        ([0, 1.5], {}, "seed: expected a non-negative integer, got 1.5"),
        ([0, 1], {"jobs": "2"}, "jobs: expected None or 0"),
    ],
)
def test_generate_many_checks_its_arguments_at_the_call(seeds, kwargs, match):
    from studio.core.errors import ConfigError
    from studio.synth import generate_many

    with pytest.raises(ConfigError, match=match.replace("(", r"\(").replace(")", r"\)").replace(".", r"\.")):
        generate_many(_tiny(), seeds, **kwargs)  # no next(): the call itself refuses
    with pytest.raises(ConfigError, match="agent_parameters.stepsize: must be positive"):
        generate_many(_with(stepsize=0.0), [0])


def test_a_valid_config_generates_the_same_graph_checked_or_not():
    from studio.generator.extended import STUDIO
    from studio.synth import generate, generate_many

    cfg = _tiny()
    direct = STUDIO.generate(cfg, jobs=1).graph  # unchecked
    a = generate(cfg)
    (b,) = list(generate_many(cfg, [0], jobs=1))
    for g in (a, b):
        assert [x.num_poses for x in g.agents] == [x.num_poses for x in direct.agents]
        assert all((x.se3_poses() == y.se3_poses()).all() for x, y in zip(g.agents, direct.agents))


# --------------------------------------------------------------------------- misleading successes
def test_a_dpgo_measurement_of_1e300_m_is_refused_naming_its_line(world):
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "dpgo", "-o", "dp"])
    assert res.exit_code == 0, res.stderr
    csv = world / "dp" / "robot0" / "measurements.csv"
    lines = csv.read_text().splitlines()
    fields = lines[2].split(",")
    fields[8] = "1e300"
    lines[2] = ",".join(fields)
    csv.write_text("\n".join(lines) + "\n")
    refused_intact(["convert", "dpgo", "dp", "-o", "out", "--no-rrd"], world, "measurements.csv:3: translation [1e+300")


def test_an_imported_measurement_beyond_the_bound_is_refused_by_every_graph_source(world):
    """Symbol g2o files (and every graph source) imported a 1e300 m measurement as data."""
    g2o = world / "ds" / "agent1" / "posegraph.g2o"
    lines = g2o.read_text().splitlines()
    k = next(n for n, line in enumerate(lines) if line.startswith("EDGE"))
    fields = lines[k].split()
    fields[3] = "1e300"
    lines[k] = " ".join(fields)
    g2o.write_text("\n".join(lines) + "\n")
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "symbols", "-o", "sy"])
    assert res.exit_code == 0, res.stderr
    refused_intact(["convert", "symbols", "sy", "-o", "out", "--no-rrd"], world, "is beyond 1e+09 m ([1e+300")


def test_a_jrl_pose_given_twice_is_refused_naming_it(jrl_world):
    """The second value of a key silently won."""
    doc = json.loads((jrl_world / "ds.jrl").read_text())
    values = doc["initialization"]["a"]
    second = dict(values[1], key=values[0]["key"])
    doc["initialization"]["a"] = [values[0], second, *values[2:]]
    (jrl_world / "bad.jrl").write_text(json.dumps(doc))
    refused_intact(
        ["convert", "jrl", "bad.jrl", "-o", "out", "--no-rrd"],
        jrl_world,
        "initialization.a[1].key: pose 0 of robot 'a' is given twice in initialization",
    )


def test_a_jrl_outlier_listed_twice_is_refused_naming_it(jrl_world):
    """An outlier listed twice was written twice to outliers.txt."""
    doc = json.loads((jrl_world / "ds.jrl").read_text())
    inter = (0, 0)  # any pose-graph measurement may be labelled
    doc["outlier_factors"] = {"a": [list(inter), list(inter)]}
    (jrl_world / "bad.jrl").write_text(json.dumps(doc))
    refused_intact(
        ["convert", "jrl", "bad.jrl", "-o", "out", "--no-rrd"],
        jrl_world,
        f"outlier_factors.a[1]: {list(inter)} is listed already (outlier_factors.a[0])",
    )


def _mrclam(world: Path):
    from tests.converters.mrclam_files import ROBOT_BARCODES, write_mrclam_dataset

    root = write_mrclam_dataset(world / "mr", seconds=30.0)
    return root, ROBOT_BARCODES


def _edit_data_row(path: Path, pick, column: int, value: str) -> int:
    """Set ``column`` of the first data row ``pick(fields)`` accepts; returns its line number."""
    lines = path.read_text().splitlines()
    for k, line in enumerate(lines):
        if line.startswith("#") or not pick(line.split()):
            continue
        parts = line.split()
        parts[column] = value
        lines[k] = "\t".join(parts)
        path.write_text("\n".join(lines) + "\n")
        return k + 1
    raise AssertionError("no such row")


def test_an_mrclam_barcode_given_to_two_subjects_is_refused(world):
    """Barcodes.dat giving one barcode to a landmark and a robot silently moved the sightings."""
    root, robots = _mrclam(world)
    line = _edit_data_row(root / "Barcodes.dat", lambda f: f[0] == "6", 1, str(robots[1]))
    refused_intact(
        ["convert", "mrclam", "mr", "-o", "out", "--no-rrd"],
        world,
        f"Barcodes.dat:{line}: barcode {robots[1]} is given to a second subject (6)",
    )


def test_an_mrclam_fractional_barcode_is_refused_not_truncated(world):
    """A barcode of 14.5 was read as robot 2's 14."""
    root, robots = _mrclam(world)
    path = root / "Robot1_Measurement.dat"
    line = _edit_data_row(path, lambda f: f[1] == str(robots[1]), 1, f"{robots[1]}.5")
    refused_intact(
        ["convert", "mrclam", "mr", "-o", "out", "--no-rrd"],
        world,
        f"Robot1_Measurement.dat:{line}: barcode {robots[1]}.5 is not a barcode (an integer)",
    )


def test_an_mrclam_sighting_stamp_error_names_the_files_line(world):
    """A stamp error on a later line was reported as "row 1" (its row among the sightings)."""
    root, robots = _mrclam(world)
    path = root / "Robot1_Measurement.dat"
    lines = path.read_text().splitlines()
    sightings = [k for k, ln in enumerate(lines) if not ln.startswith("#") and ln.split()[1] in map(str, robots)]
    landmark_first = [k for k, ln in enumerate(lines) if not ln.startswith("#")][0] < sightings[0]
    assert landmark_first or len(sightings) > 1
    target = sightings[1]  # not the first sighting: its row among the sightings is not its line
    parts = lines[target].split()
    parts[0] = "1e300"
    lines[target] = "\t".join(parts)
    path.write_text("\n".join(lines) + "\n")
    refused_intact(
        ["convert", "mrclam", "mr", "-o", "out", "--no-rrd"],
        world,
        f"Robot1_Measurement.dat:{target + 1}: time 1e+300 s is beyond the int64 nanosecond range",
    )


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--partition", "time"], "--partition: studio convert g2o takes it only with --split"),
        (["--partition", "contiguous"], "--partition: studio convert g2o takes it only with --split"),
        (["--overlap", "2"], "--overlap: studio convert g2o takes it only with --split"),
    ],
)
def test_a_split_option_without_split_is_refused_not_ignored(world, args, match):
    """``--partition`` without ``--split`` was silently ignored."""
    refused_intact(["convert", "g2o", "single/tiny_three.g2o", *args, "-o", "out", "--no-rrd"], world, match)


def test_graph_import_options_refuse_a_partition_without_a_split():
    from studio.converters.graph_split import GraphImportOptions
    from studio.core.errors import ConfigError

    with pytest.raises(ConfigError, match="partition: time needs a split into robots"):
        GraphImportOptions(partition="time")
    with pytest.raises(ConfigError, match="overlap_s: an overlap needs a split into robots"):
        GraphImportOptions(overlap_s=2.0)
    assert GraphImportOptions(split=2, partition="time", overlap_s=1.0).overlap_s == 1.0


# --------------------------------------------------------------------------- each message names what it is about
def test_an_unknown_odometry_from_agent_is_named_by_its_flag(world):
    refused_intact(
        ["convert", "tum", "alpha.tum", "bob.tum", "-o", "out", "--no-rrd", "--odometry-from", "zed=alpha.tum"],
        world,
        "--odometry-from: no agent 'zed' (agents: alpha, bob)",
    )


@pytest.mark.parametrize(("literal", "place"), [("NaN", "1:21"), ("-Infinity", "2:22")])
def test_a_nan_literal_in_a_config_is_named_by_file_line_and_column(world, literal, place):
    head = '{"a": "NaN x",\n  ' if place == "2:22" else "{"
    text = head + '"number_of_steps": ' + literal + "}"
    (world / "nan.json").write_text(text)
    refused_intact(["synth", "nan.json", "-o", "out"], world, f"nan.json:{place}: invalid JSON: {literal} is not")


def test_a_config_over_the_memory_limit_is_named_by_its_file(world):
    doc = json.loads((world / "tiny_three.json").read_text())
    doc["number_of_agents"], doc["number_of_steps"] = 10_000, 1
    doc["agent_parameters"]["agent_specific"] = doc["agent_parameters"]["agent_specific"][:1]
    (world / "big.json").write_text(json.dumps(doc))
    refused_intact(["synth", "big.json", "-o", "out"], world, "error: big.json: 5e+04 poses and their loop-closure")


def test_a_config_file_whose_stem_names_no_folder_is_named(world):
    (world / "..json").write_bytes((world / "tiny_three.json").read_bytes())
    refused_intact(["synth", "..json", "-o", "out"], world, "..json: the dataset is named after the file's stem '.'")


def test_check_names_the_file_of_an_edge_with_negative_information(world):
    g2o = world / "ds" / "agent1" / "posegraph.g2o"
    lines = g2o.read_text().splitlines()
    k = next(n for n, line in enumerate(lines) if line.startswith("EDGE"))
    fields = lines[k].split()
    fields[10] = "-" + fields[10]  # the first diagonal entry of the information
    lines[k] = " ".join(fields)
    g2o.write_text("\n".join(lines) + "\n")
    refused_intact(["check", "ds"], world, "ds/agent1/posegraph.g2o: odometry edge")


def test_a_ground_truth_beyond_the_bound_is_blamed_not_the_estimate(world):
    """A ground-truth pose at 1e300 was reported as the estimate's error not being finite."""
    res = guard.runner.invoke(guard.app, ["solve", "ds", "-o", "est"])
    assert res.exit_code == 0, res.stderr
    gt = world / "ds" / "agent1" / "agent1_GT.tum"
    lines = gt.read_text().splitlines()
    k = next(n for n, line in enumerate(lines) if line and not line.startswith("#"))
    fields = lines[k].split()
    fields[1] = "1e300"
    lines[k] = " ".join(fields)
    gt.write_text("\n".join(lines) + "\n")
    refused_intact(["evaluate", "ds", "--estimate", "est/estimate"], world, "agent1_GT.tum: pose 0 lies beyond 1e+09 m")


def test_one_tum_file_is_not_the_estimate_of_two_agents(world):
    for name, src in (("x", "alpha"), ("x_1", "bob")):
        (world / f"{name}.tum").write_bytes((world / f"{src}.tum").read_bytes())
    res = guard.runner.invoke(guard.app, ["convert", "tum", "x.tum", "x_1.tum", "-o", "conv", "--no-rrd"])
    assert res.exit_code == 0, res.stderr
    (world / "est").mkdir()
    (world / "est" / "x_1.tum").write_bytes((world / "x_1.tum").read_bytes())
    refused_intact(
        ["evaluate", "conv", "--estimate", "est"],
        world,
        "x_1.tum is the TUM file of both agent x and agent x_1",
    )


def test_a_key_given_twice_is_refused_in_every_small_json(world):
    """The decoder kept the last of two values silently."""
    doc = (world / "tiny_three.json").read_text()
    (world / "dup.json").write_text(
        doc.replace('"number_of_steps": 60,', '"number_of_steps": 60, "number_of_steps": 6,')
    )
    refused_intact(["synth", "dup.json", "-o", "out"], world, "the key 'number_of_steps' is given twice in one object")
    agents = '{"format": "cslam-studio agents 1", "agents": [], "agents": []}'
    (world / "ds" / "agents.json").write_text(agents)
    refused_intact(["check", "ds"], world, "agents.json: not a readable agents file (the key 'agents' is given twice")
    (world / "ds" / "agents.json").unlink()
    res = guard.runner.invoke(guard.app, ["convert", "tum", "alpha.tum", "bob.tum", "-o", "conv", "--no-rrd"])
    assert res.exit_code == 0, res.stderr
    text = (world / "conv" / "convert.json").read_text()
    (world / "c.json").write_text(text.replace('"seed": 0,', '"seed": 0, "seed": 3,'))
    refused_intact(["convert", "--config", "c.json", "-o", "out", "--no-rrd"], world, "the key 'seed' is given twice")
    (world / "s.json").write_text('{"base": "tiny_three.json", "base": "x.json", "grid": {"seed": [0]}}')
    refused_intact(["sweep", "s.json", "-o", "out"], world, "s.json: not valid JSON (the key 'base' is given twice")


# --------------------------------------------------------------------------- bench and sweep onto a full disk
@pytest.mark.parametrize("command", ["sweep", "bench"])
def test_bench_and_sweep_onto_a_full_disk_leave_no_partial_folder(world, tmp_path, command):
    """Both left a half-made output folder (``runs/``, ``datasets/``, ``configs/``) on a full file
    system. A folder the failed run made is removed; one of earlier runs keeps their work."""
    import os

    from tests.reliability.test_outputs import _tmpfs

    with _tmpfs(tmp_path / "disk", "size=1m") as disk:
        st = os.statvfs(disk)
        (disk / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 8 * 1024))
        spec = "s.toml" if command == "sweep" else "bench.toml"
        res = guard.runner.invoke(guard.app, [command, spec, "-o", str(disk / "out")])
        assert res.exit_code == 2, (res.stderr, res.exception)
        assert len(res.stderr.splitlines()) == 1 and "No space left on device" in res.stderr, res.stderr
        assert sorted(p.name for p in disk.iterdir()) == ["filler"]


def test_a_workspace_of_earlier_runs_is_kept_when_a_run_fails(tmp_path):
    from studio.core.errors import OutputError
    from studio.io.atomic import output_workspace

    with output_workspace(tmp_path / "ws", kind="bench") as ws:
        (ws / "cell.json").write_text("{}")
    with pytest.raises(OutputError, match="No space left on device"):
        with output_workspace(tmp_path / "ws", kind="bench") as ws:
            raise OSError(28, "No space left on device", str(ws / "cell2.json"))
    assert (tmp_path / "ws" / "cell.json").read_text() == "{}"
    with pytest.raises(OutputError, match="No space left on device"):
        with output_workspace(tmp_path / "new", kind="bench") as ws:
            raise OSError(28, "No space left on device", str(ws / "cell.json"))
    assert not (tmp_path / "new").exists()


def test_solve_onto_a_full_disk_names_its_output_folder(world, tmp_path):
    """A write's OSError carries no file name: the line was only "No space left on device"."""
    import os

    from tests.reliability.test_outputs import _tmpfs

    with _tmpfs(tmp_path / "disk", "size=1m") as disk:
        st = os.statvfs(disk)
        (disk / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 8 * 1024))
        before = guard._tree(world)
        res = guard.runner.invoke(guard.app, ["solve", "ds", "-o", str(disk / "est")])
        assert res.exit_code == 2, (res.stderr, res.exception)
        assert res.stderr == f"error: {disk / 'est'}: No space left on device\n", res.stderr
        assert sorted(p.name for p in disk.iterdir()) == ["filler"]
        assert guard._tree(world) == before


def test_a_jrl_key_given_twice_is_refused(jrl_world):
    text = (jrl_world / "ds.jrl").read_text()
    assert text.startswith('{"name":')
    (jrl_world / "bad.jrl").write_text('{"name": "other", ' + text[1:])
    refused_intact(
        ["convert", "jrl", "bad.jrl", "-o", "out", "--no-rrd"], jrl_world, "the key 'name' is given twice in one object"
    )


def test_dpgo_files_holding_only_the_header_are_named(world):
    """A measurements.csv holding only its header was reported without its file (the first robot's
    folder named for all of them)."""
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "dpgo", "-o", "dp"])
    assert res.exit_code == 0, res.stderr
    for r in range(3):
        csv = world / "dp" / f"robot{r}" / "measurements.csv"
        csv.write_text(csv.read_text().splitlines()[0] + "\n")
    refused_intact(
        ["convert", "dpgo", "dp", "-o", "out", "--no-rrd"],
        world,
        f"{world / 'dp'}: no measurements in its 3 measurements.csv files (only DPGO's header)",
    )


def test_one_robots_dpgo_file_alone_is_refused_as_not_connected_not_as_ids(world):
    res = guard.runner.invoke(guard.app, ["export", "ds", "-f", "dpgo", "-o", "dp"])
    assert res.exit_code == 0, res.stderr
    refused_intact(
        ["convert", "dpgo", "dp/robot0/measurements.csv", "-o", "out", "--no-rrd"], world, "are not connected"
    )


@pytest.mark.parametrize(
    "args",
    [
        ["convert", "tum", "alpha.tum", "bob.tum", "-o", ".", "--force"],
        ["solve", "ds", "-o", ".", "--force"],
        ["replay", "ds", "-o", "..", "--force"],
        ["export", "ds", "-f", "dpgo", "-o", ".", "--force"],
        ["bench", "bench.toml", "-o", "."],
        ["sweep", "s.toml", "-o", "."],
    ],
)
def test_o_dot_names_the_option(world, args):
    """``-o .`` with ``--force`` named only the resolved folder, not the option."""
    out = args[args.index("-o") + 1]
    refused_intact(args, world, f"-o {out}: is the current folder or one of its parents")


@pytest.mark.parametrize("hostile", HOSTILE_NAMES)
def test_agent_names_in_a_jrl_file_stay_inside_the_output(jrl_world, hostile):
    """A JRL file's agent names (its studio block) become agents.json names, never folders."""
    doc = json.loads((jrl_world / "ds.jrl").read_text())
    doc["studio"]["agents"] = [hostile, "bob", "carol"]
    (jrl_world / "named.jrl").write_text(json.dumps(doc))
    before = guard._tree(jrl_world)
    res = guard.runner.invoke(guard.app, ["convert", "jrl", "named.jrl", "-o", "out", "--no-rrd"])
    assert res.exit_code == 0, res.stderr
    made = set(guard._tree(jrl_world)) - set(before)
    assert made and all(m == "out" or m.startswith("out/") for m in made), made
    assert sorted(p.name for p in (jrl_world / "out").iterdir() if p.is_dir()) == ["agent1", "agent2", "agent3"]
    names = [a["name"] for a in json.loads((jrl_world / "out" / "agents.json").read_text())["agents"]]
    assert names == [hostile, "bob", "carol"]  # kept as data, where it belongs
    res = guard.runner.invoke(guard.app, ["solve", "out", "-o", "est"])
    assert res.exit_code == 0, res.stderr
    assert all(p.parent == jrl_world / "est" / "estimate" / "tum" for p in (jrl_world / "est").rglob("*.tum"))
    assert not Path("/tmp/studio-escaped.tum").exists()


# --------------------------------------------------------------------------- leftovers named
SELF_LOOP_G2O = (
    "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
    "EDGE_SE2 0 1 1 0 0 100 0 0 100 0 100\nEDGE_SE2 1 2 1 0 0 100 0 0 100 0 100\n"
    "EDGE_SE2 2 2 0.5 0 0 100 0 0 100 0 100\n"
)


@pytest.mark.parametrize("command", [["check"], ["convert", "g2o"], ["solve"]])
def test_a_self_loop_is_refused_with_its_line(world, command):
    (world / "loop.g2o").write_text(SELF_LOOP_G2O)
    out = ["-o", world / "out"] if command[0] != "check" else []
    refused_intact([*command, world / "loop.g2o", *out], world, "loop.g2o:6: edge from vertex 2 to itself")


def test_a_command_solution_far_away_names_the_program_and_its_file(world):
    (world / "far.py").write_text(
        "import sys\n"
        "with open(sys.argv[1]) as f, open(sys.argv[2], 'w') as g:\n"
        "    for line in f:\n"
        "        p = line.split()\n"
        "        if p and p[0] == 'VERTEX_SE2':\n"
        "            g.write(f'VERTEX_SE2 {p[1]} 1e300 0 0\\n')\n"
    )
    (world / "line.g2o").write_text(SELF_LOOP_G2O.rsplit("EDGE_SE2 2 2", 1)[0])
    import sys

    cmd = f"{sys.executable} {world / 'far.py'} {{input}} {{output}}"
    err = refused_intact(
        ["solve", world / "line.g2o", "-o", world / "out", "--method", "command", "--command", cmd],
        world,
        "solution.g2o written by",
    )
    assert "vertex 0 is not finite or lies beyond" in err and "(3 such vertices)" in err
