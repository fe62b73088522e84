"""studio solve: the pipeline on synthetic datasets, its outputs, the CLI, and the iteration recording."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.evaluate import evaluate
from studio.solve import load_problem, solve
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"
runner = CliRunner()


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    root = tmp_path_factory.mktemp("solve")
    return synthesize(load_synth_config(DATA / "configs" / "small3x100.json"), root, rrd=False, jobs=1)


def test_solving_a_multi_g2o_folder_lowers_the_error_and_writes_an_estimate(small, tmp_path):
    res = solve(small.dataset_dir, tmp_path / "est")
    assert res.planar  # kollagen's 3D records of a planar walk are solved in SE(2)
    assert res.chi2_final < res.chi2_initial <= res.chi2_dataset
    before = evaluate(small.dataset_dir, align="se3").overall.ape_translation_m.mean
    after = evaluate(small.dataset_dir, estimate=res.estimate_path, align="se3").overall.ape_translation_m.mean
    assert after < 0.2 * before
    info = json.loads((tmp_path / "est" / "solve.json").read_text())
    assert info["method"] == "gtsam" and info["iterations"] == res.iterations >= 1
    assert info["chi2_final"] == pytest.approx(res.chi2_final)
    assert info["chi2_history"][0] == pytest.approx(res.chi2_initial)
    names = sorted(p.name for p in (tmp_path / "est" / "estimate").iterdir())
    assert names == ["agent1", "agent2", "agent3", "inter_agent_lc.dat", "tum"]
    assert sorted(p.name for p in (tmp_path / "est" / "estimate" / "tum").iterdir()) == [
        "agent1.tum",
        "agent2.tum",
        "agent3.tum",
    ]
    # the TUM files score exactly like the g2o estimate
    by_tum = evaluate(small.dataset_dir, estimate=tmp_path / "est" / "estimate" / "tum", align="se3")
    assert by_tum.overall.ape_translation_m.mean == pytest.approx(after, rel=1e-9)


def test_the_single_g2o_and_the_folder_reach_the_same_optimum_up_to_the_connectors(small, tmp_path):
    single = small.single_dir / f"{small.config.name}.g2o"
    a = solve(single, tmp_path / "a")
    b = solve(small.dataset_dir, tmp_path / "b")
    assert a.estimate_path.name == "small3x100.g2o"
    assert load_problem(single).problem.num_edges == load_problem(small.dataset_dir).problem.num_edges + 2
    # kollagen's two connector edges (agent k's last pose to agent k+1's first) add a little cost
    assert b.chi2_final <= a.chi2_final < 1.05 * b.chi2_final
    ev = evaluate(small.dataset_dir, estimate=a.estimate_path, align="first-pose")
    assert ev.overall.ape_translation_m.mean < 1.0


def test_the_same_inputs_give_the_same_bytes(small, tmp_path):
    solve(small.dataset_dir, tmp_path / "a")
    solve(small.dataset_dir, tmp_path / "b")
    for f in ("agent1/posegraph.g2o", "inter_agent_lc.dat", "tum/agent2.tum"):
        assert (tmp_path / "a" / "estimate" / f).read_bytes() == (tmp_path / "b" / "estimate" / f).read_bytes()


def test_g2o_method_matches_the_default_optimum(small, tmp_path):
    a = solve(small.dataset_dir, tmp_path / "a")
    b = solve(small.dataset_dir, tmp_path / "b", method="g2o")
    assert b.iterations == 10
    assert b.chi2_final == pytest.approx(a.chi2_final, rel=1e-3)


def test_solve_recording_has_every_iteration(small, tmp_path):
    from studio.recording.rrd_checks import rrd_verify

    res = solve(small.dataset_dir, tmp_path / "est", rrd=tmp_path / "run.rrd")
    rrd_verify(tmp_path / "run.rrd")
    import rerun.chunk as rc

    reader = rc.RrdReader(tmp_path / "run.rrd")
    store = reader.recordings()[0]
    steps = set()
    entities = set()
    for chunk in reader.stream(store=store):
        entities.add(str(chunk.entity_path))
        batch = chunk.to_record_batch()
        if "iteration" in batch.schema.names:
            steps.update(batch.column("iteration").cast("int64").to_pylist())
    assert steps == set(range(res.iterations + 1))
    assert {"/solve/agent1/estimate", "/solve/agent1/ground_truth", "/solve/metrics/chi2"} <= entities


@pytest.mark.parametrize("source", ["folder", "single"])
def test_solve_recording_is_the_same_for_the_same_run(small, tmp_path, source):
    """Same run, same recording id and fingerprint (fixed blueprint ids, no `log_time`); a single
    g2o file, which has no dataset recording to join, gets an id derived from the run."""
    import rerun.chunk as rc

    from studio.recording.rrd_checks import fingerprint_rrd

    dataset = small.dataset_dir if source == "folder" else small.single_dir / f"{small.config.name}.g2o"
    for name in ("a", "b"):
        solve(dataset, tmp_path / name, rrd=tmp_path / f"{name}.rrd")
    ids = [[s.recording_id for s in rc.RrdReader(tmp_path / f"{n}.rrd").recordings()] for n in "ab"]
    assert ids[0] == ids[1]
    assert fingerprint_rrd(tmp_path / "a.rrd") == fingerprint_rrd(tmp_path / "b.rrd")
    names = {
        str(c.entity_path)
        for c in rc.RrdReader(tmp_path / "a.rrd").stream()
        for n in c.to_record_batch().schema.names
        if n == "log_time"
    }
    assert not names  # no wall clock in the data


def test_cli_solve_then_evaluate(small, tmp_path):
    out = tmp_path / "est"
    res = runner.invoke(app, ["solve", str(small.dataset_dir), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "gtsam" in res.output and str(out / "estimate") in res.output
    again = runner.invoke(app, ["solve", str(small.dataset_dir), "-o", str(out)])
    assert again.exit_code == 2 and "already exists" in again.output
    ev = runner.invoke(
        app, ["evaluate", str(small.dataset_dir), "--estimate", str(out / "estimate"), "--align", "first-pose"]
    )
    assert ev.exit_code == 0 and "first pose of each agent" in ev.output


@pytest.mark.parametrize(
    "args, message",
    [
        (["solve", "missing-folder", "-o", "x"], "no such dataset"),
        (["solve", "{ds}", "-o", "{tmp}/x", "--iterations", "0"], "--iterations: expected an integer in 1..10000"),
        (["solve", "{ds}", "-o", "{tmp}/x", "--method", "command"], "command: method command needs the program"),
        (["solve", "{ds}", "-o", "{tmp}/x", "--rrd", "{tmp}/run.png"], "must end in .rrd"),
    ],
)
def test_cli_bad_input_is_one_line(small, tmp_path, args, message):
    argv = [a.format(ds=small.dataset_dir, tmp=tmp_path) for a in args]
    res = runner.invoke(app, argv)
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and message in lines[0], res.output
    assert not (tmp_path / "x").exists()


def test_first_pose_alignment_removes_one_rigid_transform_per_agent(small):
    from scipy.spatial.transform import Rotation

    from studio.core.trajectory import Trajectory
    from studio.evaluate import score
    from studio.io.multig2o import read_multi_g2o

    graph = read_multi_g2o(small.dataset_dir, edges=False).to_se3()
    est = []
    for k, a in enumerate(graph.agents):
        r = Rotation.from_euler("z", 20 * (k + 1), degrees=True)
        p = a.ground_truth.copy()
        p[:, 0:3] = r.apply(p[:, 0:3]) + [k, 2.0 * k, 0]
        p[:, 3:7] = (r * Rotation.from_quat(p[:, 3:7])).as_quat()
        est.append(Trajectory.from_poses(a.name, a.stamps_ns, p))
    assert score(graph, est).overall.ape_translation_m.mean > 1.0
    ev = score(graph, est, align="first-pose")
    assert ev.overall.ape_translation_m.max < 1e-9
    assert ev.overall.ape_rotation_deg.max < 1e-6
    assert len(ev.alignment_transforms) == len(graph.agents)


def test_default_method_never_ends_above_its_start_on_kollagen_exact_information(tmp_path):
    """kollagen's Exact odometry information is over-confident on turning edges; a Gauss-Newton step
    can raise the cost there, and the method then goes on with Levenberg-Marquardt."""
    import dataclasses

    cfg = dataclasses.replace(
        load_synth_config(DATA / "configs" / "small3x100.json"), exact_information_matrix=True, name="exact"
    )
    res = synthesize(cfg, tmp_path, rrd=False, jobs=1)
    out = solve(res.single_dir / "exact.g2o", tmp_path / "est")
    history = out.solution.chi2_history
    assert out.chi2_final < 0.5 * out.chi2_initial
    # GTSAM minimises its own (logarithm) error: the g2o chi2 may wiggle by a few 1e-5 at the end
    assert history[-1] <= 1.0001 * min(history)


def test_absurd_or_unsolvable_graphs_are_one_line(small, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(small.dataset_dir, bad)
    g2o = bad / "agent1" / "posegraph.g2o"
    lines = g2o.read_text().splitlines()
    parts = lines[3].split()
    parts[2] = "1e300"
    lines[3] = " ".join(parts)
    g2o.write_text("\n".join(lines) + "\n")
    res = runner.invoke(app, ["solve", str(bad), "-o", str(tmp_path / "x")])
    assert res.exit_code == 2
    assert (
        res.output.strip() == f"error: {bad}: vertex 3 (global id order) lies beyond 1e+09 m: "
        "not a pose graph an optimizer can take"
    )
    # an agent joined to no other (its inter-agent closures removed): a method that holds one anchor
    # alone refuses it before it runs (g2o once drifted to a higher chi2 and called it a success);
    # gtsam and gnc hold each piece at its first pose and say so
    lone = tmp_path / "lone"
    shutil.copytree(small.dataset_dir, lone)
    (lone / "inter_agent_lc.dat").write_text("")
    res = runner.invoke(app, ["solve", str(lone), "-o", str(tmp_path / "y"), "-m", "g2o"])
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1, res.output
    assert "the graph is not connected" in res.output and "agent2 vertex 0" in res.output
    assert not (tmp_path / "y").exists()
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
    for method in ("gtsam", "gnc"):
        res = runner.invoke(app, ["solve", str(lone), "-o", str(tmp_path / method), "-m", method])
        assert res.exit_code == 0, res.output
        assert "gauge: 3 pieces, 0 priors; held at their first pose (no prior reaches them): agent1 vertex 0, " in (
            res.output
        )
        gauge = json.loads((tmp_path / method / "solve.json").read_text())["gauge"]
        assert gauge["pieces"] == 3 and gauge["anchored"] == ["agent1 vertex 0", "agent2 vertex 0", "agent3 vertex 0"]


def test_a_methods_own_options_reach_it_by_name_and_other_methods_refuse_them(small, tmp_path):
    """dgs's tolerances are fields of its own options class (DgsOptions, named by its registry
    entry); `solve` takes them by name (a bench spec's `[options.dgs] rotation_tol = ...` used to
    end in a TypeError traceback), a method that does not read one refuses it, and solve.json lists
    the shared options and the method's own, no other method's."""
    from studio.bench import bench_spec_from_dict
    from studio.core.errors import ConfigError
    from studio.solvers.options import DgsOptions

    res = solve(small.dataset_dir, tmp_path / "dgs", method="dgs", rotation_tol=0.05)
    info = json.loads((tmp_path / "dgs" / "solve.json").read_text())
    assert res.options.own == DgsOptions(rotation_tol=0.05) and info["notes"]["rotation_tol"] == 0.05
    assert list(info["options"]) == ["optimizer", "init", "max_iterations", "relative_tolerance", *vars(DgsOptions())]
    assert info["options"]["rotation_tol"] == 0.05 and info["options"]["max_iterations"] == 100
    with pytest.raises(ConfigError, match=r"^rotation_tol: method gtsam does not read it \(it reads optimizer"):
        solve(small.dataset_dir, tmp_path / "g", method="gtsam", rotation_tol=0.05)
    with pytest.raises(ConfigError, match=r"^pose_tol: expected a finite number >= 0, got -1"):
        solve(small.dataset_dir, tmp_path / "g", method="dgs", pose_tol=-1)
    with pytest.raises(ConfigError, match=r"^schedule: expected gauss-seidel or jacobi, got 'random'"):
        solve(small.dataset_dir, tmp_path / "g", method="dgs", schedule="random")
    assert not (tmp_path / "g").exists()
    gtsam = solve(small.dataset_dir, tmp_path / "gtsam")
    assert gtsam.options.own is None
    assert list(gtsam.to_dict()["options"]) == ["optimizer", "init", "max_iterations", "relative_tolerance"]
    spec = {"datasets": ["x"], "methods": ["dgs"], "options": {"dgs": {"rotation_tol": 0.05, "robots": 2}}}
    assert bench_spec_from_dict(spec, "spec.toml").options == {"dgs": {"rotation_tol": 0.05, "robots": 2}}


def test_the_cli_has_a_flag_per_own_option_and_passes_only_those_typed(small, tmp_path):
    """`studio solve`'s dgs flags are DgsOptions' fields: a typed one reaches the method, and one
    typed for a method that does not read it is refused naming its flag, not ignored (exit 0 before)."""
    out = tmp_path / "dgs"
    argv = ["solve", str(small.dataset_dir), "-o", str(out), "-m", "dgs", "--iterations", "5"]
    res = runner.invoke(app, [*argv, "--rotation-tol", "0.05", "--coarse", "0", "--schedule", "jacobi"])
    assert res.exit_code == 0, res.output
    options = json.loads((out / "solve.json").read_text())["options"]
    assert (options["rotation_tol"], options["coarse_size"], options["schedule"]) == (0.05, 0, "jacobi")
    res = runner.invoke(app, ["solve", str(small.dataset_dir), "-o", str(tmp_path / "g"), "--coarse", "3"])
    assert res.exit_code == 2 and res.stderr.startswith("error: --coarse: method gtsam does not read it")
    res = runner.invoke(
        app, ["solve", str(small.dataset_dir), "-o", str(tmp_path / "s"), "-m", "dgs", "--schedule", "x"]
    )
    assert res.exit_code == 2 and "error: --schedule: expected gauss-seidel or jacobi, got 'x'" in res.stderr
    assert not (tmp_path / "g").exists() and not (tmp_path / "s").exists()
