"""Numbers bounded where they enter (issue 23): nanosecond stamps beyond int64, and every numeric
option of convert, replay and solve that has no natural range (NaN, inf, negative, absurdly large).
Each is one line naming the file:line or the option, exit 2, nothing written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.reliability import test_guard as guard

refused_intact = guard.refused_intact
made, world = guard.made, guard.world  # the guard tests' fixtures: a synth dataset and a working folder


@pytest.mark.parametrize("layout", ["mocap0", "state_groundtruth_estimate0"])
@pytest.mark.parametrize(
    "stamp", ["9223372036854775808", "99999999999999999999", "-9223372036854775809", "1" * 30, "9" * 5000]
)
def test_a_nanosecond_stamp_beyond_int64_is_one_line_naming_file_and_line(world, layout, stamp):
    columns = 8 if layout == "mocap0" else 17
    csv = world / "seq" / "mav0" / layout / "data.csv"
    csv.parent.mkdir(parents=True)
    row = ",".join(["0", "0", "0", "1", "0", "0", "0"] + ["0"] * (columns - 8))  # p, q wxyz, the rest
    csv.write_text(f"#timestamp [ns],...\n1000,{row}\n{stamp},{row}\n")
    err = refused_intact(["convert", "euroc", world / "seq", "-o", world / "out"], world, f"{csv}:3: timestamp")
    assert "int64" in err and (stamp in err or f"{stamp[:20]}...({len(stamp)} digits)" in err)


def test_the_largest_int64_stamp_is_still_read(world):
    """The bound is the type's, not tighter: 2**63 - 1 ns passes the reader (the pipeline then
    refuses a two-pose trajectory for its own reason, not the stamp)."""
    from studio.converters.text import read_table

    csv = world / "data.csv"
    csv.write_text("0,0,0,0,1,0,0,0\n9223372036854775807,1,0,0,1,0,0,0\n")
    _, stamps = read_table(csv, 8, what="test", int_first=True)
    assert stamps is not None and int(stamps[-1]) == 2**63 - 1


SINGLE = ["convert", "g2o", "single/tiny_three.g2o", "--ground-truth", "vertices"]
TUM = ["convert", "tum", "alpha.tum"]
REPLAY = ["replay", "ds", "-b", "centralized"]
SOLVE = ["solve", "ds"]

#: (command, options, the option the one line must name)
CASES = [
    (SINGLE, ["--split", "2", "--overlap", "1e300"], "--overlap"),
    (SINGLE, ["--split", "2", "--partition", "time", "--overlap", "1e300"], "--overlap"),
    (SINGLE, ["--split", "2", "--partition", "time", "--overlap", "inf"], "--overlap"),
    (SINGLE, ["--split", "2", "--partition", "time", "--overlap", "nan"], "--overlap"),
    (SINGLE, ["--split", "99999999999999999999"], "--split"),
    (SINGLE, ["--split", "-3"], "--split"),
    (TUM, ["--split", "2", "--overlap", "1e300"], "--overlap"),
    (TUM, ["--split", "2", "--overlap", "-1"], "--overlap"),
    (TUM, ["--split", "99999999999999999999"], "--split"),
    (TUM, ["--split", "2", "--heading-window-m", "1e300"], "--heading-window-m"),
    (TUM, ["--lc-radius", "1e300"], "--lc-radius"),
    (TUM, ["--max-memory-gb", "nan"], "--max-memory-gb"),
    (REPLAY, ["--step", "1e300"], "--step"),
    (REPLAY, ["--step", "nan"], "--step"),
    (REPLAY, ["--step", "1e-6"], "--step"),  # 240 million ticks: refused from the count
    (REPLAY, ["--period", "1e300"], "--period"),
    (REPLAY, ["--period", "-1"], "--period"),
    (REPLAY, ["--every", "99999999999999999999"], "--every"),
    (REPLAY, ["--every", "0"], "--every"),
    (REPLAY, ["--comms-seed", "-1"], "--comms-seed"),
    (REPLAY, ["--comms-seed", "99999999999999999999"], "--comms-seed"),
    (REPLAY, ["--relinearize-skip", "99999999999999999999"], "--relinearize-skip"),
    (REPLAY, ["--relinearize-threshold", "1e300"], "--relinearize-threshold"),
    (REPLAY, ["--relinearize-threshold", "nan"], "--relinearize-threshold"),
    (REPLAY, ["--comms", "range:1e300"], "range"),
    (REPLAY, ["--comms", "range:5,period=1e300"], "period"),
    (REPLAY, ["--bandwidth", "1e300/s"], "bandwidth"),
    (SOLVE, ["--iterations", "99999999999999999999"], "--iterations"),
    (SOLVE, ["--iterations", "0"], "--iterations"),
    (SOLVE, ["-m", "dgs", "--robots", "99999999999"], "--robots"),
    (SOLVE, ["-m", "dgs", "--robots", "-1"], "--robots"),
]


@pytest.mark.parametrize(("command", "options", "flag"), CASES, ids=[" ".join(c[1]) for c in CASES])
def test_a_range_less_number_is_one_line_naming_its_option(world, command, options, flag):
    err = refused_intact([*command, "-o", Path("out"), *options], world, flag)
    assert "Traceback" not in err and not (world / "out").exists()


def _aliasing_config(world: Path, *, window: int, fragment: int, steps: int) -> Path:
    import json

    cfg = json.loads((world / "tiny_three.json").read_text())
    cfg["number_of_steps"] = steps
    cfg["agent_parameters"]["step_fragment"] = fragment
    cfg["studio"] = {
        "version": 1,
        "outliers": {
            "intra_fraction": 0.05,
            "inter_fraction": 0.05,
            "kinds": {"aliasing": 1.0},
            "aliasing_window": window,
        },
    }
    path = world / f"alias_{window}_{fragment}.json"
    path.write_text(json.dumps(cfg))
    return path


def test_aliasing_outliers_with_a_large_window_are_refused_from_the_estimate(world):
    """2,000 steps of 40 fragments, a window of 5 steps: every one of 80,001 poses per agent compares
    401 x 401 cells (about 0.8 TB); refused from the estimate in one line naming the window and the
    option that lifts it, before any allocation."""
    import time

    from studio.generator.config import aliasing_bytes, estimate_resources
    from studio.synth import load_synth_config

    config = _aliasing_config(world, window=5, fragment=40, steps=2000)
    t0 = time.perf_counter()
    err = refused_intact(["synth", config, "-o", Path("out")], world, "aliasing windows (401x401 cells per pose)")
    assert "--max-memory-gb" in err and time.perf_counter() - t0 < 10
    parsed = load_synth_config(config)
    assert aliasing_bytes(parsed) == 80_001 * 401 * 401 * 64
    assert estimate_resources(parsed)[0] > aliasing_bytes(parsed)
    small = load_synth_config(_aliasing_config(world, window=1, fragment=4, steps=60))
    assert aliasing_bytes(small) == 241 * 9 * 9 * 64  # counted, and far under the limit


def test_the_aliasing_estimate_covers_the_measured_peak():
    """The per-cell cost is not below what the pattern comparison really allocates (tracemalloc)."""
    import tracemalloc

    import numpy as np

    from studio.generator.config import MEMORY_BYTES_PER_ALIAS_CELL
    from studio.generator.outliers import local_patterns

    rng = np.random.default_rng(0)
    n, half = 1500, 15
    cells = np.cumsum(rng.integers(-1, 2, (n, 3)), axis=0)
    cells[:, 2] = 0
    tracemalloc.start()
    try:
        local_patterns(cells, rng.integers(0, 4, n), half)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= n * (2 * half + 1) ** 2 * MEMORY_BYTES_PER_ALIAS_CELL
    assert peak >= n * (2 * half + 1) ** 2 * MEMORY_BYTES_PER_ALIAS_CELL / 4  # and not far above it


def _solve_rss_kib(world: Path, command: str) -> tuple[subprocess.CompletedProcess, int]:
    """Run ``studio solve ds -m command`` in a fresh interpreter; its result and the solve process's
    peak RSS (the largest descendant the wrapper waited for: the studio, not the tiny shell tools)."""
    wrapper = (
        "import resource, subprocess, sys; p = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
        "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); print(p.returncode); "
        "sys.stdout.write(p.stdout); sys.stderr.write(p.stderr)"
    )
    argv = [sys.executable, "-c", "from studio.cli import main; main()", "solve", "ds", "-o", "est", "-m", "command"]
    env = dict(os.environ, CI="true", RERUN_ANALYTICS="0")
    res = subprocess.run(
        [sys.executable, "-c", wrapper, *argv, "--command", command],
        capture_output=True,
        text=True,
        env=env,
        cwd=world,
        timeout=600,
    )
    rss, code, *_ = res.stdout.splitlines()
    return subprocess.CompletedProcess(res.args, int(code), res.stdout, res.stderr), int(rss)


@pytest.mark.parametrize("megabytes", [pytest.param(1000, marks=pytest.mark.slow), 100])
def test_a_solver_printing_a_gigabyte_holds_kilobytes(world, megabytes):
    """An external solver that prints ``megabytes`` MB and fails: one line with its last words and
    the count of what was cut; one that prints as much and succeeds: a truthful success. The studio's
    peak RSS stays far under what it printed (it was 2.9 GB for 1 GB)."""
    flood = f"head -c {megabytes * 1_000_000} /dev/zero"
    res, rss_kib = _solve_rss_kib(world, f"sh -c '{flood}; echo last words >&2; exit 3' {{input}} {{output}}")
    assert res.returncode == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: command: sh exited with status 3: last words ("), lines
    assert f"{megabytes * 1_000_000 + 11:,} bytes of output; the first and last 32 KiB kept" in lines[0]
    assert rss_kib < 400_000 and not (world / "est").exists()
    res, rss_kib = _solve_rss_kib(world, f'sh -c \'{flood}; cp "$0" "$1"\' {{input}} {{output}}')
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert "chi2" in res.stdout and (world / "est" / "solve.json").is_file()
    assert rss_kib < 400_000


# --------------------------------------------------------------------------- strict JSON
def test_dumps_strict_names_the_output_and_the_json_path():
    import math

    from studio.core.errors import OutputError
    from studio.io.strict_json import dumps_strict, non_finite_path

    assert dumps_strict({"a": [1.0, 2]}, "x.json") == '{"a": [1.0, 2]}'
    assert non_finite_path({"a": [1.0, {"b": math.inf}]}) == ("$.a[1].b", math.inf)
    with pytest.raises(OutputError, match=r"^out/solve\.json: \$\.runs\[0\]\.ape_m is nan, not a finite number"):
        dumps_strict({"runs": [{"ape_m": math.nan}]}, "out/solve.json")


def test_no_json_the_studio_writes_holds_nan(world):
    """Every JSON under a fresh solve, convert and export is standard JSON (parsed strictly)."""
    import json

    def strict(text: str) -> object:
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in JSON"))

    from typer.testing import CliRunner

    from studio.cli import app

    runner = CliRunner()
    for args in (
        ["solve", "ds", "-o", "est"],
        ["convert", "tum", "alpha.tum", "bob.tum", "-o", "conv", "--no-rrd"],
        ["export", "ds", "--format", "jrl", "-o", "ds.jrl"],
    ):
        assert runner.invoke(app, args).exit_code == 0, args
    found = [p for p in world.rglob("*.json")] + [world / "ds.jrl"]
    assert len(found) >= 5
    for p in found:
        strict(p.read_text(encoding="utf-8"))
    res = runner.invoke(app, ["solve", "ds", "-o", "est2", "--json"])
    strict(res.stdout)


def test_a_nan_bench_result_fails_its_cell_instead_of_being_written(world, monkeypatch):
    import json
    import math

    import studio.bench as bench_mod

    def nan_cell(cell, spec, dataset, single, run_dir):
        return {
            "dataset": cell.dataset,
            "case": cell.case,
            "method": cell.method,
            "input": spec.input,
            "ape_se3_m": math.nan,
        }

    monkeypatch.setattr(bench_mod, "_run_cell", nan_cell)
    spec = bench_mod.load_bench_spec(str(world / "bench.toml"))
    res = bench_mod.bench(spec, world / "b", isolate=False)
    (cell,) = [r for r in res.rows if r["method"] == "gtsam"]
    assert "ape_se3_m" not in cell and "$.ape_se3_m is nan, not a finite number" in cell["error"]
    for p in (world / "b").rglob("*.json"):
        assert "NaN" not in p.read_text() and json.loads(p.read_text()), p


# --------------------------------------------------------------------------- one outliers.txt writer
def test_convert_and_synth_write_outliers_txt_with_one_writer_and_one_header(world):
    from typer.testing import CliRunner

    from studio.cli import app
    from studio.io.outliers_txt import read_outliers_txt

    args = ["convert", "tum", "alpha.tum", "bob.tum", "-o", "conv", "--no-rrd", "--outlier-fraction", "0.3"]
    assert CliRunner().invoke(app, args).exit_code == 0
    rows, kinds = read_outliers_txt(world / "conv" / "outliers.txt")
    assert len(rows) > 0 and set(kinds) == {"far"}
    converted = (world / "conv" / "outliers.txt").read_text().splitlines()
    from studio.io.outliers_txt import write_outliers_txt

    write_outliers_txt(world / "synth_outliers.txt", rows[:1], ["aliasing"])  # as synth writes its kinds
    written = (world / "synth_outliers.txt").read_text().splitlines()
    header = written[: written.index("# kind: aliasing")]
    assert len(header) == 5 and converted[:6] == [*header, "# kind: far"]


def test_only_the_outliers_txt_module_writes_outliers_txt():
    """No other module formats the file's rows itself (convert once did, without kinds)."""
    import re

    root = Path(__file__).resolve().parents[2]
    writers = []
    for path in [*root.joinpath("studio").rglob("*.py"), *root.joinpath("converters").rglob("*.py")]:
        text = path.read_text(encoding="utf-8")
        if re.search(r"outliers\.txt\"?\)?[^\n]*\.(write_text|write_bytes)|write_text\([^\n]*outliers\.txt", text):
            writers.append(path.name)
        if re.search(r"Loop closures that are outliers", text):
            writers.append(path.name)
    assert writers == ["outliers_txt.py"], writers


# --------------------------------------------------------------------------- names from data
HOSTILE_NAMES = ["../../escaped", "/tmp/studio-bounds-abs", "a\x00b", "x" * 300, "..", ".hidden", "sub/dir"]


def test_agent_names_never_become_paths_in_a_robots_folder_layout(tmp_path):
    """``folder_names="robots"`` names the agent folders after the agents: hostile names give plain
    folders inside the dataset (at most 100 characters), never a path outside it."""
    import dataclasses

    from studio.io.multig2o import read_multi_g2o, write_multi_g2o
    from studio.synth import load_synth_config
    from studio.synth import synthesize as run_synth

    made = run_synth(load_synth_config(guard.DATA / "configs" / "tiny_three.json"), tmp_path / "s", rrd=False, jobs=1)
    graph = read_multi_g2o(made.dataset_dir)
    for hostile in HOSTILE_NAMES:
        agents = (dataclasses.replace(graph.agents[0], name=hostile), *graph.agents[1:])
        out = tmp_path / "out"
        out.mkdir()
        write_multi_g2o(dataclasses.replace(graph, agents=agents), out, folder_names="robots")
        made_entries = sorted(p.name for p in out.iterdir())
        assert all("/" not in n and not n.startswith(".") and len(n) <= 100 for n in made_entries), made_entries
        assert not Path("/tmp/studio-bounds-abs").exists() and not (tmp_path / "escaped").exists()
        assert len([p for p in out.iterdir() if p.is_dir()]) == 3, made_entries
        import shutil

        shutil.rmtree(out)


def test_agent_names_that_meet_in_one_folder_are_refused(tmp_path):
    import dataclasses

    from studio.core.errors import FormatError
    from studio.io.multig2o import read_multi_g2o, write_multi_g2o
    from studio.synth import load_synth_config
    from studio.synth import synthesize as run_synth

    made = run_synth(load_synth_config(guard.DATA / "configs" / "tiny_three.json"), tmp_path / "s", rrd=False, jobs=1)
    graph = read_multi_g2o(made.dataset_dir)
    agents = (dataclasses.replace(graph.agents[0], name="a/b"), dataclasses.replace(graph.agents[1], name="a_b"))
    (tmp_path / "out").mkdir()
    with pytest.raises(FormatError, match="give the same file name 'a_b'"):
        write_multi_g2o(
            dataclasses.replace(graph, agents=(*agents, graph.agents[2])), tmp_path / "out", folder_names="robots"
        )


def test_a_very_long_tum_stem_makes_a_short_agent_folder(world):
    long_name = "y" * 240 + ".tum"
    (world / long_name).write_bytes((world / "alpha.tum").read_bytes())
    from typer.testing import CliRunner

    from studio.cli import app

    res = CliRunner().invoke(
        app, ["convert", "tum", long_name, "bob.tum", "-o", "conv", "--no-rrd", "--folder-names", "robots"]
    )
    assert res.exit_code == 0, res.stderr
    assert sorted(p.name for p in (world / "conv").iterdir() if p.is_dir()) == ["bob", "y" * 100]


@pytest.mark.parametrize("hostile", ["../x", "/abs", "a/b", "..", ".x", "convert.json", "a\x00b"])
def test_a_bag_agent_name_that_is_not_a_plain_folder_name_is_refused(world, hostile):
    (world / "run.bag").write_bytes(b"")  # never read: the name is refused first
    refused_intact(["convert", "bag", "run.bag", "--agent", f"{hostile}=/odom", "-o", Path("out")], world, "agent name")


def test_sweep_plot_names_from_spec_parameters_stay_plain_file_names():
    from studio.io.names import safe_file_name

    for label in ("../../x", "base./etc/passwd", "a" * 300):
        name = safe_file_name(label.replace(".", "_"), fallback="parameter")
        assert "/" not in name and not name.startswith(".") and len(name) <= 100


def test_fits_without_a_value_are_null_in_report_json_not_nan():
    """A robot that never moved has no drift per metre, a run without sightings no RMS: null."""
    import json
    import math

    from studio.converters.odometry_source import OdometryFit
    from studio.converters.sightings import SightingsFit
    from studio.io.strict_json import dumps_strict

    odo = OdometryFit("a", "a.tum", 3, 0.1, 0.01, 0.1, 0.01, 0.01, 0.0, 0.0, math.nan)
    sight = SightingsFit(0, 0, 0.1, 0.01, math.nan, math.nan, 0, 0.0, 0.0, {})
    for fit in (odo, sight):
        doc = json.loads(dumps_strict(fit.to_dict(), "report.json"))
        assert None in doc.values() and all(v is None or v == v for v in doc.values() if isinstance(v, float))


@pytest.mark.parametrize("far", ["1e11", "1e300", "-1e12"])
def test_a_kitti_time_beyond_the_int64_nanosecond_range_is_one_line(world, far):
    (world / "kitti").mkdir()
    (world / "kitti" / "00.txt").write_text("".join(f"1 0 0 {k} 0 1 0 0 0 0 1 0\n" for k in range(20)))
    times = [f"{k * 0.1:.1f}" for k in range(20)]
    times[5] = far
    (world / "kitti" / "times.txt").write_text("\n".join(times) + "\n")
    err = refused_intact(
        ["convert", "kitti", world / "kitti" / "00.txt", "-o", Path("out")], world, "times.txt: time 6"
    )
    assert "beyond the int64 nanosecond range" in err


@pytest.mark.parametrize(
    ("file", "column", "match"),
    [
        ("Robot1_Groundtruth.dat", 0, "time 1e+300 s is beyond the int64 nanosecond range"),
        ("Robot2_Measurement.dat", 1, "barcode 1e+300 is not a barcode"),
    ],
)
def test_an_mrclam_time_or_barcode_out_of_range_is_one_line_naming_the_file(world, file, column, match):
    from tests.converters.mrclam_files import write_mrclam_dataset

    root = write_mrclam_dataset(world / "mr", seconds=30.0)
    path = root / file
    lines = path.read_text().splitlines()
    data = [k for k, ln in enumerate(lines) if not ln.startswith("#")]
    parts = lines[data[3]].split()
    parts[column] = "1e300"
    lines[data[3]] = "\t".join(parts)
    path.write_text("\n".join(lines) + "\n")
    # the file's line (issue 41: a stamp on line 6 was reported as "row 1")
    refused_intact(["convert", "mrclam", root, "-o", Path("out")], world, f"{path}:{data[3] + 1}: {match}")
