"""studio sweep on Dask: same bytes as sequential synth runs, resuming, a killed worker, a failing
cell, and a separate scheduler process."""

from __future__ import annotations

import filecmp
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.core.errors import ConfigError
from studio.sweep import expand, load_sweep_spec, sweep, sweep_spec_from_dict

DATA = Path(__file__).resolve().parent.parent / "data"
REPO = DATA.parent.parent
runner = CliRunner()
pytest.importorskip("distributed")


def _spec(tmp_path: Path, steps: str = '["evaluate"]', extra: str = "") -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(
        f'name = "grid"\nbase = "{DATA / "configs" / "tiny_three.json"}"\nsteps = {steps}\n{extra}'
        "[grid]\nnumber_of_steps = [20, 40, 60]\n"
        '"inter_agent_loop_closure_parameters.loop_closure_radius" = [1.0, 2.0]\nseed = [0, 1]\n'
    )
    return path


def _same_tree(a: Path, b: Path) -> bool:
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    return (
        bool(files)
        and files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
        and all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)
    )


def _same_renamed(a: Path, b: Path, old: str, new: str) -> bool:
    """``a`` and ``b`` hold the same bytes, a file of ``b`` named with ``new`` where ``a``'s has ``old``."""
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    return bool(files) and all(filecmp.cmp(a / f, b / str(f).replace(old, new), shallow=False) for f in files)


def test_twelve_cells_on_two_workers_give_the_bytes_of_sequential_synth_runs_and_resume(tmp_path):
    spec = load_sweep_spec(_spec(tmp_path))
    out = tmp_path / "out"
    res = sweep(spec, out, workers=2)
    assert len(res.rows) == 12 and res.computed == 12 and res.failed == 0
    df = pd.read_parquet(res.table_path)
    assert len(df) == 12 and df["ape_initial_none_m"].gt(0).all()
    assert sorted(df["param:number_of_steps"].unique()) == [20, 40, 60]
    # every cell is what `studio synth configs/<cell>.json` makes on its own
    for row in res.rows[:12]:
        cell = row["cell"]
        alone = tmp_path / "alone" / cell
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "studio.cli",
                "synth",
                str(out / "configs" / f"{cell}.json"),
                "-o",
                str(alone),
                "-q",
                "--no-rrd",
            ],
            capture_output=True,
            text=True,
            cwd=REPO,
            env=dict(os.environ, CI="true"),
        )
        assert done.returncode == 0, done.stderr
        assert row["command"].startswith(f"studio synth {out / 'configs' / cell}.json -o DIR")
        # the seed replicates of a config are made together (OUT/seeds/<group>/seed<k>/<group>)
        dataset = out / row["dataset"]
        group = dataset.name
        assert row["dataset"] == f"seeds/{group}/seed{row['param:seed']:04d}/{group}"
        assert _same_tree(alone / cell, dataset)
        assert _same_renamed(alone / f"{cell}_singleg2o", dataset.parent / f"{group}_singleg2o", cell, group)
    # an interrupted run: three cells unfinished (one with a half-made folder); the rest is kept
    names = [r["cell"] for r in res.rows]
    stamps = {n: (out / "cells" / n / "result.json").stat().st_mtime_ns for n in names}
    for n in names[:3]:
        (out / "cells" / n / "result.json").unlink()
    (out / res.rows[0]["dataset"] / "agent1" / "posegraph.g2o").write_text("half")
    again = sweep(spec, out, workers=2)
    assert again.computed == 3
    for n in names[3:]:
        assert (out / "cells" / n / "result.json").stat().st_mtime_ns == stamps[n]
    assert _same_tree(tmp_path / "alone" / names[0] / names[0], out / res.rows[0]["dataset"])
    assert sweep(spec, out, workers=2).computed == 0


def test_seed_replicates_are_one_synthesize_seeds_call_with_the_rows_and_bytes_of_cells_made_alone(tmp_path):
    """Cells that differ only in ``seed`` are made by ``synthesize_seeds`` in runs of consecutive
    seeds (here 6 seeds on one worker: two runs of 3); each row and dataset is what the cell made
    alone (``run_cell``) gives, and ``studio synth configs/<group>.json --seeds`` remakes the group."""
    import dataclasses

    from studio.io.synth_config import read_synth_config
    from studio.sweep import _batches, run_cell
    from studio.synth import synthesize_seeds

    data = {"name": "reps", "base": str(DATA / "configs" / "tiny_three.json"), "grid": {"seed": [0, 1, 2, 3, 4, 5]}}
    spec = sweep_spec_from_dict(data, "reps.toml")
    out = tmp_path / "out"
    tasks = expand(spec, out)
    assert len({t.group for t in tasks}) == 1 and tasks[0].group
    assert [[t.params["seed"] for t in b] for b in _batches(tasks, 1)] == [[0, 1, 2], [3, 4, 5]]
    res = sweep(spec, out, workers=1)
    assert res.failed == 0 and res.computed == 6
    group = tasks[0].group
    assert sorted(p.name for p in (out / "seeds" / group).iterdir()) == [f"seed{k:04d}" for k in range(6)]
    alone_root = tmp_path / "alone"
    for task, row in zip(tasks, res.rows):
        alone = run_cell(dataclasses.replace(task, group="", group_config=None, out_root=str(alone_root)))
        timing = ("make_s", "cell_s", "dataset", "command", "reused")
        assert {k: v for k, v in row.items() if k not in timing} == {k: v for k, v in alone.items() if k not in timing}
        assert _same_tree(alone_root / alone["dataset"], out / row["dataset"])
    again = tmp_path / "again"
    synthesize_seeds(read_synth_config(out / "configs" / f"{group}.json"), again, list(range(6)), rrd=False)
    for k in range(6):
        assert _same_tree(again / f"seed{k:04d}", out / "seeds" / group / f"seed{k:04d}")


def test_a_failing_seed_group_records_its_errors_and_leaves_nothing(tmp_path):
    spec = sweep_spec_from_dict(
        {
            "name": "fail",
            "base": str(DATA / "configs" / "tiny_three.json"),
            "steps": ["evaluate", "solve"],
            "options": {"solve": {"method": "command"}},
            "grid": {"seed": [0, 1, 2]},
        },
        "fail.toml",
    )
    res = sweep(spec, tmp_path / "out", workers=1)
    assert res.failed == 3
    assert all(r["error"].startswith("command: method command needs the program") for r in res.rows)
    assert not any((tmp_path / "out" / "cells").iterdir())
    assert not any((tmp_path / "out" / "seeds").iterdir())  # no seed folder, no empty group folder


def test_a_killed_worker_leaves_no_partial_cell_and_the_cell_completes(tmp_path):
    spec = load_sweep_spec(_spec(tmp_path, '["evaluate", "tests.studio.sweep_steps:die_once"]'))
    spec = sweep_spec_from_dict(
        {"name": "kill", "base": spec.base, "steps": list(spec.steps), "grid": {"number_of_steps": [20, 30]}},
        "kill.toml",
    )
    out = tmp_path / "out"
    res = sweep(spec, out, workers=2)
    assert res.failed == 0 and len(res.rows) == 2
    assert all(r["survived_kill"] for r in res.rows)
    assert sorted(p.name for p in (out / "killed").iterdir()) == sorted(r["cell"] for r in res.rows)
    for r in res.rows:
        cell = out / "cells" / r["cell"]
        assert sorted(p.name for p in cell.iterdir()) == sorted(
            [r["cell"], f"{r['cell']}_singleg2o", f"{r['cell']}.config.json", "result.json"]
        )


def test_a_failing_cell_records_its_error_and_the_sweep_goes_on(tmp_path):
    spec = sweep_spec_from_dict(
        {
            "name": "fail",
            "base": str(DATA / "configs" / "tiny_three.json"),
            "steps": ["evaluate", "solve"],
            "options": {"solve": {"method": "command"}},
            "grid": {"number_of_steps": [20, 30]},
        },
        "fail.toml",
    )
    res = sweep(spec, tmp_path / "out", workers=1)
    assert res.failed == 2
    assert all(r["error"].startswith("command: method command needs the program") for r in res.rows)
    assert not any((tmp_path / "out" / "cells").iterdir())  # nothing half-made is left


@pytest.mark.parametrize(
    "data, message",
    [
        ({"grid": {}}, "base: missing key"),
        ({"base": "multi3500x8", "grids": {}}, "grids: unknown key (did you mean 'grid'?)"),
        ({"base": "multi3500x8", "steps": ["plot"]}, "steps: unknown step 'plot'"),
        ({"base": "multi3500x8", "grid": {"number_of_agent": [2]}}, "cell 1: number_of_agent: no such key"),
        ({"base": "multi3500x8", "grid": {"number_of_agents": [0]}}, "number_of_agents"),
        ({"base": "multi3500x8", "grid": {"seed": [-1]}}, "seed: expected a non-negative integer"),
        (
            {"base": "multi3500x8", "steps": ["replay"], "grid": {"replay.comms": ["radio"]}},
            "cell 1: options.replay: comms: unknown model 'radio'",
        ),
        (
            {"base": "multi3500x8", "steps": ["replay"], "grid": {"replay.backends": ["nope"]}},
            "cell 1: options.replay: ",
        ),
        (
            {"base": "multi3500x8", "steps": ["replay"], "options": {"replay": {"evry": 5}}},
            "options.replay: evry: not a replay option (known: backends, bandwidth, comms, every",
        ),
        ({"base": "multi3500x8", "grid": {"replay.comms": ["always"]}}, "cell 1: replay.comms: no such key"),
    ],
)
def test_bad_specs_are_refused_before_any_work(tmp_path, data, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)").replace("?", r"\?")):
        expand(sweep_spec_from_dict(data, "s.toml"), tmp_path)
    assert not any(tmp_path.iterdir())


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_sweep_on_a_scheduler_started_as_a_separate_process(tmp_path):
    port = _free_port()
    env = dict(os.environ, CI="true", PYTHONPATH=str(REPO))
    sched = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--no-dashboard",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    worker = None
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.2)
        worker = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "distributed.cli.dask_worker",
                f"tcp://127.0.0.1:{port}",
                "--nworkers",
                "1",
                "--nthreads",
                "1",
                "--no-dashboard",
                "--host",
                "127.0.0.1",
            ],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            cwd=tmp_path,
        )
        spec_path = tmp_path / "s.toml"
        spec_path.write_text(
            f'name = "remote"\nbase = "{DATA / "configs" / "tiny_three.json"}"\n[grid]\nnumber_of_steps = [20, 30]\n'
        )
        res = runner.invoke(
            app, ["sweep", str(spec_path), "-o", str(tmp_path / "out"), "--scheduler", f"tcp://127.0.0.1:{port}"]
        )
        assert res.exit_code == 0, res.output
        assert "remote: 2 cells (2 run now, 0 failed)" in res.output
        assert len(pd.read_parquet(tmp_path / "out" / "sweep.parquet")) == 2
        assert (tmp_path / "out" / "sweep.rrd").stat().st_size > 0
    finally:
        for proc in (worker, sched):
            if proc is not None:
                os.killpg(proc.pid, 15)
                proc.wait(timeout=30)


def test_cli_bad_spec_is_one_line(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text('base = "multi3500x8"\nstep = ["evaluate"]\n')
    res = runner.invoke(app, ["sweep", str(spec), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2
    assert res.output.strip() == (
        f"error: {spec}: step: unknown key (did you mean 'steps'?); known: base, cells, grid, name, options, steps"
    )


def test_a_bug_in_a_step_is_the_cells_one_line_error_and_dask_prints_nothing(tmp_path):
    """Through the CLI in its own process: a cell whose step raises a plain exception records it, the
    other cell completes, exit 0, and nothing of Dask's (logs, the 'port 8787 in use' warning) reaches
    stderr, even with 8787 taken."""
    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen()
    except OSError:
        pass  # already taken by something else: the case we want anyway
    try:
        spec_path = tmp_path / "s.json"
        spec_path.write_text(
            json.dumps(
                {
                    "name": "bug",
                    "base": str(DATA / "configs" / "tiny_three.json"),
                    "steps": ["tests.studio.sweep_steps:boom"],
                    "grid": {"number_of_steps": [20, 30]},
                }
            )
        )
        done = subprocess.run(
            [sys.executable, "-m", "studio.cli", "sweep", str(spec_path), "-o", str(tmp_path / "o"), "--workers", "1"],
            capture_output=True,
            text=True,
            cwd=REPO,
            env=dict(os.environ, CI="true", PYTHONPATH=str(REPO)),
        )
    finally:
        holder.close()
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert "bug: 2 cells (2 run now, 1 failed)" in done.stdout
    df = pd.read_parquet(tmp_path / "o" / "sweep.parquet").set_index("param:number_of_steps")
    assert df.loc[30, "error"] == "ValueError: a bug in a user's step"
    assert df.loc[20, "boom_ok"] == 1 and pd.isna(df.loc[20, "error"])
    assert sorted(p.name for p in (tmp_path / "o" / "cells").iterdir()) == [df.loc[20, "cell"]]


def test_a_cell_whose_worker_dies_on_every_attempt_is_an_error_row_and_leaves_nothing(tmp_path):
    spec = sweep_spec_from_dict(
        {
            "name": "dead",
            "base": str(DATA / "configs" / "tiny_three.json"),
            "steps": ["tests.studio.sweep_steps:die_always"],
            "grid": {"number_of_steps": [20]},
        },
        "dead.toml",
    )
    res = sweep(spec, tmp_path / "out", workers=1, retries=0)
    assert res.failed == 1
    assert res.rows[0]["error"].startswith("no attempt finished (1 tried): KilledWorker")
    assert not any((tmp_path / "out" / "cells").iterdir())


def test_plots_leave_out_the_seed_and_constant_series():
    import pandas as pd

    from studio.sweep import _plotted

    df = pd.DataFrame(
        {
            "param:inter_agent_loop_closure_parameters.loop_closure_radius": [2.0, 2.0, 4.0, 4.0],
            "param:seed": [0, 1, 0, 1],
            "param:number_of_agents": [3, 3, 3, 3],
            "inter_loop_closures": [10, 12, 30, 33],
            "odometry": [400, 400, 400, 400],
            "ape_initial_none_m": [0.5, 0.6, 0.5, 0.6],
        }
    )
    params, metrics = _plotted(df)
    assert params == ["param:inter_agent_loop_closure_parameters.loop_closure_radius"]
    assert metrics == ["inter_loop_closures", "ape_initial_none_m"]


def test_default_plots_show_metrics_with_units_not_timings(tmp_path, monkeypatch):
    """Timings vary with the machine's load, not the parameter: they stay in the table, not the plots."""
    import types

    import matplotlib.pyplot as plt
    import pandas as pd

    from studio.sweep import PLOTTED, _panel, _plots, _plotted

    df = pd.DataFrame(
        {
            "param:inter_agent_loop_closure_parameters.loop_closure_radius": [2.0, 4.0, 8.0],
            "cell_s": [1.2, 0.9, 1.5],
            "make_s": [0.4, 0.3, 0.6],
            "solve_s": [0.2, 0.1, 0.3],
            "inter_loop_closures": [10, 30, 90],
            "ape_solved_se3_m": [0.5, 0.4, 0.3],
        }
    )
    assert _plotted(df)[1] == ["inter_loop_closures", "ape_solved_se3_m"]
    assert not any(c.endswith("_s") for c in PLOTTED)
    assert PLOTTED["ape_solved_se3_m"][1] == "m"
    assert _panel("replay_swarm_sve_r_rad") == ("swarm: SVE, rotation", "rad")
    assert _panel("replay_ape_se3_m") == ("team APE, SE(3)-aligned", "m")
    seen = []
    real_close = plt.close

    def close(fig):
        seen.append([(a.get_title(), a.get_ylabel()) for a in fig.axes if a.get_visible()])
        real_close(fig)

    monkeypatch.setattr(plt, "close", close)
    paths = _plots(types.SimpleNamespace(name="radius"), tmp_path, df)
    assert [p.name for p in paths] == ["inter_agent_loop_closure_parameters_loop_closure_radius.png"]
    assert seen == [[("inter-agent loop closures", "count"), ("mean APE, solved, SE(3)-aligned", "[m]")]]


def test_replay_cells_of_datasets_comms_and_backends_give_one_table_plots_and_resume(tmp_path):
    """2 datasets x 3 communication models x 3 back-ends: each cell's row holds the replay's final
    team APE and SVE (the bytes of the replay run alone), the plots follow each swept parameter,
    and the resumed sweep redoes nothing."""
    pytest.importorskip("gtsam")
    from studio.replay import replay
    from studio.synth import load_synth_config, synthesize

    path = tmp_path / "replays.toml"
    path.write_text(
        f'name = "replays"\nbase = "{DATA / "configs" / "tiny_three.json"}"\nsteps = ["replay"]\n'
        "[grid]\nnumber_of_steps = [20, 30]\n"
        '"replay.comms" = ["always", "range:5", "range:5,partners=1,rounds=2"]\n'
        '"replay.backends" = ["centralized", "independent", "swarm"]\n'
        "[options.replay]\nevery = 10\n"
    )
    out = tmp_path / "out"
    res = sweep(load_sweep_spec(path), out, workers=2)
    assert len(res.rows) == 18 and res.computed == 18 and res.failed == 0
    df = pd.read_parquet(res.table_path)
    assert df["replay_ape_se3_m"].gt(0).all()
    swarm = df["param:replay.backends"] == "swarm"
    assert df.loc[swarm, "replay_sve_t_m"].gt(0).all() and df.loc[~swarm, "replay_sve_t_m"].isna().all()
    assert sorted(p.name for p in res.plot_paths) == ["number_of_steps.png", "replay_backends.png", "replay_comms.png"]
    # a cell's row is its replay run alone, and its folder that replay's bytes (timings aside)
    row = df[(df["param:replay.comms"] == "range:5,partners=1,rounds=2") & swarm].iloc[0]
    made = synthesize(load_synth_config(out / "configs" / f"{row['cell']}.json"), tmp_path / "alone", rrd=False)
    alone = replay(made.dataset_dir, tmp_path / "r", comms=row["param:replay.comms"], backends=["swarm"], every=10)
    assert row["replay_sve_t_m"] == pytest.approx(alone.runs[0].sve[-1, 0], rel=1e-12)
    assert row["replay_ape_se3_m"] == pytest.approx(alone.runs[0].ape_team_se3_m[-1], rel=1e-12)
    cell = out / "cells" / row["cell"] / "replay"
    for name in ("metrics.csv", "summary.csv", "links.csv", "schedule/contacts.csv", "swarm.jrr"):
        assert (cell / name).read_bytes() == (alone.out_dir / name).read_bytes(), name
    assert "studio replay" in row["command"] and row["command"].endswith(
        "--comms range:5,partners=1,rounds=2 --every 10 --backend swarm"
    )
    stamps = {p: p.stat().st_mtime_ns for p in (out / "cells").rglob("*") if p.is_file()}
    again = sweep(load_sweep_spec(path), out, workers=2)
    assert (
        again.computed == 0 and {p: p.stat().st_mtime_ns for p in (out / "cells").rglob("*") if p.is_file()} == stamps
    )
    resumed = pd.read_parquet(again.table_path)
    assert resumed[sorted(resumed.columns)].equals(df[sorted(df.columns)])  # result.json's keys are sorted


def test_a_solve_step_takes_a_methods_own_options_and_its_command_remakes_the_cell(tmp_path):
    """`[options.solve]` may hold the method's own options (dgs's `coarse_size`, `rotation_tol`:
    a TypeError before), and the `studio solve` line the table lists uses their declared flags
    (`--coarse`, `--iterations`; it wrote `--coarse-size` and `--max-iterations`, which the command
    does not have) and remakes the cell's estimate byte for byte."""
    import shlex

    spec = sweep_spec_from_dict(
        {
            "name": "dgs",
            "base": str(DATA / "configs" / "tiny_three.json"),
            "steps": ["solve"],
            "options": {"solve": {"method": "dgs", "coarse_size": 0, "rotation_tol": 0.1, "max_iterations": 5}},
        },
        "dgs.toml",
    )
    res = sweep(spec, tmp_path / "out", workers=1)
    assert res.failed == 0 and len(res.rows) == 1
    row = res.rows[0]
    synth, solve = row["command"].split(" && ")
    assert solve.endswith("--coarse 0 --iterations 5 --method dgs --rotation-tol 0.1")
    alone = tmp_path / "alone"
    for line in (synth, solve):
        words = [w.replace("DIR", str(alone)) for w in shlex.split(line)]
        done = CliRunner().invoke(app, words[1:])
        assert done.exit_code == 0, done.output
    made = tmp_path / "out" / "cells" / row["cell"] / "solved" / "estimate"
    assert _same_tree(made, alone / "solved" / "estimate")
    options = json.loads((alone / "solved" / "solve.json").read_text())["options"]
    assert (options["coarse_size"], options["rotation_tol"], options["max_iterations"]) == (0, 0.1, 5)
