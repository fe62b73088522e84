"""studio replay: the pipeline on small synthetic datasets against the batch optimum, determinism,
the CLI and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.evaluate import evaluate
from studio.replay import replay
from studio.solve import solve
from studio.synth import load_synth_config, synthesize

pytest.importorskip("gtsam")

DATA = Path(__file__).resolve().parent.parent / "data"
runner = CliRunner()


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    root = tmp_path_factory.mktemp("replay")
    return synthesize(load_synth_config(DATA / "configs" / "small3x100.json"), root, rrd=False, jobs=1)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("replay-tiny")
    return synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), root, rrd=False, jobs=1)


@pytest.fixture(scope="module")
def batch(small, tmp_path_factory):
    out = tmp_path_factory.mktemp("batch") / "solved"
    res = solve(small.dataset_dir, out)
    fp = evaluate(small.dataset_dir, estimate=res.estimate_path, align="first-pose").overall.ape_translation_m.mean
    se3 = evaluate(small.dataset_dir, estimate=res.estimate_path, align="se3").overall.ape_translation_m.mean
    return res.chi2_final, fp, se3


@pytest.fixture(scope="module")
def always(small, tmp_path_factory):
    return replay(small.dataset_dir, tmp_path_factory.mktemp("always") / "r", comms="always", every=20)


def test_centralized_with_always_connected_comms_ends_at_the_batch_optimum(always, batch):
    chi2, fp, se3 = batch
    central = always.runs[0]
    assert central.name == "centralized"
    assert central.chi2_final == pytest.approx(chi2, rel=0.01)
    assert central.ape_team_first_pose_m[-1] == pytest.approx(fp, rel=0.02)
    assert central.ape_team_se3_m[-1] == pytest.approx(se3, rel=0.02)
    # the metric is taken along the way: every 20 ticks and at the end
    assert central.checkpoint_ticks.tolist()[:3] == [0, 20, 40]
    assert central.checkpoint_ticks[-1] == len(always.schedule.ticks_ns) - 1
    assert central.poses_seen[-1].tolist() == [401, 401, 401]


def test_independent_is_worst_and_swarm_lies_between(always, small, tmp_path):
    runs = {r.name: r for r in always.runs}
    c, i, s = runs["centralized"], runs["independent"], runs["swarm"]
    assert i.ape_team_se3_m[-1] > 5 * c.ape_team_se3_m[-1]
    assert c.ape_team_se3_m[-1] * 0.98 <= s.ape_team_se3_m[-1] < i.ape_team_se3_m[-1]
    ranged = {r.name: r for r in replay(small.dataset_dir, tmp_path / "r5", comms="range:5", every=20).runs}
    c5, i5, s5 = ranged["centralized"], ranged["independent"], ranged["swarm"]
    assert c5.ape_team_se3_m[-1] < s5.ape_team_se3_m[-1] < i5.ape_team_se3_m[-1]
    # independent ignores the comms: the same beliefs under both models
    assert np.array_equal(i5.final_poses, i.final_poses)
    # fewer closures delivered at 5 m than with always-on links: the centralized optimum is worse
    assert c5.chi2_final > c.chi2_final
    # swarm exchanged graphs and estimates over the links it used
    assert s.messages.sum() > 0 and s.bytes.sum() > s.messages.sum()


def test_never_connected_leaves_every_back_end_on_its_own(tiny, tmp_path):
    res = replay(tiny.dataset_dir, tmp_path / "never", comms="never", every=25)
    assert (res.schedule.delivered_tick == -1).all()
    runs = {r.name: r for r in res.runs}
    assert runs["swarm"].ape_team_se3_m[-1] == pytest.approx(runs["independent"].ape_team_se3_m[-1], rel=1e-6)
    assert runs["centralized"].ape_team_se3_m[-1] == pytest.approx(runs["independent"].ape_team_se3_m[-1], rel=1e-3)
    assert runs["swarm"].messages.sum() == 0


def test_recorded_delivers_every_closure_when_measured_and_links_only_then(tiny, tmp_path):
    names = ["centralized", "swarm"]
    on = replay(tiny.dataset_dir, tmp_path / "always", comms="always", every=25, backends=names)
    rec = replay(tiny.dataset_dir, tmp_path / "recorded", comms="recorded", every=25, backends=names)
    assert (rec.schedule.delivered_tick >= 0).all()
    assert np.array_equal(rec.schedule.delivered_tick, on.schedule.delivered_tick)
    # contact exactly at the ticks where closures arrive, nowhere else
    pair_of = {tuple(p): k for k, p in enumerate(rec.schedule.pairs.tolist())}
    expected = np.zeros_like(rec.schedule.contact)
    for a, b, t in zip(rec.schedule.closure_from, rec.schedule.closure_to, rec.schedule.delivered_tick):
        expected[t, pair_of[(min(a, b), max(a, b))]] = True
    assert np.array_equal(rec.schedule.contact, expected) and expected.sum() < on.schedule.contact.sum()
    # the centralized solver sees the same closures at the same ticks; swarm talks less
    assert rec.runs[0].chi2_final == pytest.approx(on.runs[0].chi2_final, rel=1e-9)
    assert 0 < rec.runs[1].messages.sum() < on.runs[1].messages.sum()
    assert json.loads((rec.out_dir / "replay.json").read_text())["comms"] == "recorded"


def test_the_same_dataset_model_and_seed_give_the_same_bytes(tiny, tmp_path):
    files = ["schedule/contacts.csv", "schedule/closures.csv", "metrics.csv", "summary.csv", "links.csv"]
    files += ["centralized.jrr", "independent.jrr", "swarm.jrr", "dgs.jrr"]
    spec = "range:10,period=3,p=0.5"
    every = ["centralized", "independent", "swarm", "dgs"]
    a = replay(tiny.dataset_dir, tmp_path / "a", comms=spec, seed=4, every=10, backends=every)
    b = replay(tiny.dataset_dir, tmp_path / "b", comms=spec, seed=4, every=10, backends=every)
    c = replay(tiny.dataset_dir, tmp_path / "c", comms=spec, seed=5, every=10, backends=["centralized"])
    for name in files:
        assert (a.out_dir / name).read_bytes() == (b.out_dir / name).read_bytes(), name
    assert (a.out_dir / "schedule/contacts.csv").read_bytes() != (c.out_dir / "schedule/contacts.csv").read_bytes()
    info = json.loads((a.out_dir / "replay.json").read_text())
    assert info["comms"] == spec and info["seed"] == 4 and info["clock"] == "dataset stamps"
    header = (a.out_dir / "metrics.csv").read_text().splitlines()[0]
    assert header == "backend,tick,time_s,robot,poses,ape_first_pose_m,ape_se3_m,sve_t_m,sve_r_rad"


def test_a_bandwidth_limit_delays_deliveries(tiny, tmp_path):
    free = replay(tiny.dataset_dir, tmp_path / "free", comms="always", backends=["centralized"], every=50)
    slow = replay(
        tiny.dataset_dir, tmp_path / "slow", comms="always", backends=["centralized"], every=50, bandwidth="0.5/s"
    )
    got_free, got_slow = free.schedule.delivered_tick, slow.schedule.delivered_tick
    assert (got_free >= 0).all()
    delivered = got_slow >= 0
    assert (got_slow[delivered] >= got_free[delivered]).all() and (got_slow[delivered] > got_free[delivered]).any()
    # at most one closure per 2 s on each link
    pairs = slow.schedule.closure_from * 10 + slow.schedule.closure_to
    for p in np.unique(pairs):
        ticks = np.sort(got_slow[(pairs == p) & delivered])
        assert (np.diff(ticks) >= 2).all()


def test_a_period_sets_the_clock_and_is_recorded(tiny, tmp_path):
    res = replay(tiny.dataset_dir, tmp_path / "p", comms="always", backends=["independent"], period_s=0.5, every=40)
    assert res.schedule.ticks_ns[-1] == 120_000_000_000  # 241 poses x 0.5 s: the last at 120 s
    info = json.loads((res.out_dir / "replay.json").read_text())
    assert info["period_s"] == 0.5 and info["clock"] == "pose index x period"


def test_the_cli_replays_and_reports(tiny, tmp_path):
    out = tmp_path / "cli"
    r = runner.invoke(app, ["replay", str(tiny.dataset_dir), "--comms", "range:20", "-o", str(out), "--every", "30"])
    assert r.exit_code == 0, r.output
    assert "centralized: APE first-pose" in r.output and "swarm" in r.output
    for name in ["metrics.csv", "summary.csv", "summary.md", "links.csv", "timings.csv", "report.md", "replay.json"]:
        assert (out / name).is_file(), name
    assert "% time connected" in (out / "report.md").read_text()
    again = runner.invoke(app, ["replay", str(tiny.dataset_dir), "-o", str(out)])
    assert again.exit_code == 2 and "already exists" in again.output


def _fails(args: list[str], match: str, out: Path) -> None:
    r = runner.invoke(app, args)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and match in lines[0], r.output
    assert "Traceback" not in r.output
    assert not out.exists()


def test_bad_input_is_one_line_exit_2_and_nothing_written(tiny, tmp_path):
    ds = str(tiny.dataset_dir)
    out = tmp_path / "never-written"
    sched = tmp_path / "rdv.txt"
    sched.write_text("0,0,10\n-7,0,5\n")
    _fails(["replay", ds, "--comms", f"rendezvous:{sched}", "-o", str(out)], f"{sched}:2: robot id -7", out)
    sched.write_text("0,0,10,5,20\n")
    _fails(["replay", ds, "--comms", f"rendezvous:{sched}", "-o", str(out)], f"{sched}:1: window 2", out)
    _fails(["replay", ds, "--comms", "range:-5", "-o", str(out)], "must be > 0", out)
    _fails(["replay", ds, "--comms", "range:5,period=-2", "-o", str(out)], "period", out)
    _fails(["replay", ds, "--period", "-1", "-o", str(out)], "period", out)
    _fails(["replay", ds, "--backend", "dpgo", "-o", str(out)], "unknown back-end 'dpgo'", out)
    # a dataset whose stamps run backwards
    broken = tmp_path / "broken"
    import shutil

    shutil.copytree(tiny.dataset_dir, broken)
    tum = broken / "agent2" / "agent2_GT.tum"
    rows = tum.read_text().splitlines()
    rows[5], rows[6] = rows[6], rows[5]
    tum.write_text("\n".join(rows) + "\n")
    _fails(["replay", str(broken), "-o", str(out)], "agent2_GT.tum", out)


def test_a_rendezvous_file_is_used_and_copied_beside_the_schedule(tiny, tmp_path):
    sched = tmp_path / "rdv.txt"
    sched.write_text("0,0,30,100,140\n1,20,120\n2,0,240\n")
    res = replay(tiny.dataset_dir, tmp_path / "r", comms=f"rendezvous:{sched}", every=20)
    assert (res.out_dir / "schedule" / "rendezvous.txt").read_text() == sched.read_text()
    windows = res.schedule.windows()
    assert [(s, e) for a, b, s, e in windows.tolist() if (a, b) == (0, 1)] == [(20, 30), (100, 120)]
    assert res.report.connected_fraction[2] > res.report.connected_fraction[1]


def test_a_schedule_naming_more_robots_is_one_warning(tiny, tmp_path):
    """Swarm-SLAM's schedules (cslam_experiments) name up to six robots; the others' lines are ignored."""
    sched = tmp_path / "rdv.txt"
    sched.write_text("0,0,30,100,140\n1,20,120\n2,0,240\n3,0,10\n5,0,10\n")
    r = runner.invoke(
        app, ["replay", str(tiny.dataset_dir), "--comms", f"rendezvous:{sched}", "-o", str(tmp_path / "r")]
    )
    assert r.exit_code == 0, r.output
    warnings = [ln for ln in r.output.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "robots 3, 5" in warnings[0]
    written = (tmp_path / "r" / "schedule" / "rendezvous.txt").read_text()
    assert written == "0,0,30,100,140\n1,20,120\n2,0,240\n"


def test_the_recording_shows_beliefs_links_and_closures_and_has_a_stable_fingerprint(tiny, tmp_path):
    from studio.recording.rrd_checks import fingerprint_rrd

    a = replay(tiny.dataset_dir, tmp_path / "a", comms="range:10", every=30, rrd=tmp_path / "a.rrd")
    replay(tiny.dataset_dir, tmp_path / "b", comms="range:10", every=30, rrd=tmp_path / "b.rrd")
    assert a.rrd_path is not None and a.rrd_path.stat().st_size < 5_000_000
    fa, fb = fingerprint_rrd(tmp_path / "a.rrd"), fingerprint_rrd(tmp_path / "b.rrd")
    assert fa == fb
    text = repr(fa)
    for entity in ["replay/world/centralized/agent1", "replay/world/links", "replay/world/delivered_closures"]:
        assert entity in text, entity
    swarm = next(r for r in a.runs if r.name == "swarm")
    assert swarm.sve is not None and np.isfinite(swarm.sve[:, 0]).any()
    assert "replay/metrics/sve_t_m/swarm" in text
    # an existing recording is refused before anything is written
    with pytest.raises(Exception, match="already exists"):
        replay(tiny.dataset_dir, tmp_path / "c", comms="never", rrd=tmp_path / "a.rrd")
    assert not (tmp_path / "c").exists()


def test_parquet_tables_hold_the_csv_columns_and_rows(tiny, tmp_path):
    pa_csv = pytest.importorskip("pyarrow.csv")
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "pq"
    r = runner.invoke(app, ["replay", str(tiny.dataset_dir), "--comms", "range:10", "-o", str(out), "--parquet"])
    assert r.exit_code == 0, r.output
    tables = sorted(p.relative_to(out).as_posix() for p in out.rglob("*.parquet"))
    assert tables == [
        "links.parquet",
        "metrics.parquet",
        "schedule/closures.parquet",
        "schedule/contacts.parquet",
        "summary.parquet",
        "timings.parquet",
    ]
    for name in tables:
        table = pq.read_table(out / name)
        text = (out / name).with_suffix(".csv").read_text().splitlines()
        assert table.column_names == text[0].split(","), name
        assert table.num_rows == len(text) - 1, name
        assert table.equals(pa_csv.read_csv(out / Path(name).with_suffix(".csv"))), name
    metrics = pq.read_table(out / "metrics.parquet").to_pydict()
    assert metrics["backend"][0] == "centralized" and metrics["ape_se3_m"][0] is None  # a robot's row
    team = [k for k, robot in enumerate(metrics["robot"]) if robot == "all"]
    assert all(metrics["ape_se3_m"][k] > 0 for k in team[1:])
    # the same replay gives the same Parquet bytes (timings aside)
    again = tmp_path / "pq2"
    replay(tiny.dataset_dir, again, comms="range:10", parquet=True)
    for name in tables:
        if name != "timings.parquet":
            assert (out / name).read_bytes() == (again / name).read_bytes(), name


def test_parquet_without_pyarrow_is_one_line_and_nothing_written(tiny, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow now raises ImportError
    out = tmp_path / "never-written"
    _fails(["replay", str(tiny.dataset_dir), "-o", str(out), "--parquet"], "parquet: needs pyarrow", out)


def test_dgs_with_always_connected_comms_ends_close_to_centralized(always, small, tmp_path):
    """DGS rounds at every checkpoint, warm-started, reach the centralized back-end's end on a small
    dataset; they send separators on every link; under ``never`` each robot is its own exact solve."""
    central = always.runs[0]
    dgs = replay(small.dataset_dir, tmp_path / "dgs", comms="always", every=20, backends=["dgs"]).runs[0]
    assert dgs.name == "dgs"
    assert dgs.chi2_final == pytest.approx(central.chi2_final, rel=0.01)
    assert dgs.ape_team_first_pose_m[-1] == pytest.approx(central.ape_team_first_pose_m[-1], rel=0.05)
    assert dgs.ape_team_se3_m[-1] == pytest.approx(central.ape_team_se3_m[-1], rel=0.05)
    assert dgs.poses_seen[-1].tolist() == [401, 401, 401]
    assert (dgs.messages > 0).all() and (dgs.bytes > 8 * dgs.messages).all()
    # along the way the team's map follows centralized's (the two-level rounds converge between
    # checkpoints; plain DGS rounds lagged far behind: docs/replay.md)
    assert (dgs.ape_team_se3_m <= 1.3 * central.ape_team_se3_m + 0.01).all()
    never = replay(small.dataset_dir, tmp_path / "never", comms="never", every=50, backends=["dgs", "independent"])
    alone, independent = never.runs
    assert alone.messages.sum() == 0 and alone.bytes.sum() == 0
    assert alone.ape_team_se3_m[-1] == pytest.approx(independent.ape_team_se3_m[-1], rel=0.05)


def test_a_robot_keeps_what_it_learned_after_the_last_rendezvous(small, tmp_path):
    """Windows that end half-way (200 s of 400): swarm and dgs keep the closures delivered and the
    neighbour poses received, so each ends strictly better than independent (both APEs and chi2 over
    the delivered edges) and not better than centralized on the objective centralized minimizes,
    chi2 over every edge anyone knows (its APE may be beaten: the optimum minimizes chi2, not APE)."""
    sched = tmp_path / "rdv.txt"
    sched.write_text("0,0,200\n1,0,200\n2,0,200\n")
    backends = ["centralized", "independent", "swarm", "dgs"]
    res = replay(small.dataset_dir, tmp_path / "r", comms=f"rendezvous:{sched}", every=20, backends=backends)
    runs = {r.name: r for r in res.runs}
    c, i = runs["centralized"], runs["independent"]
    for name in ("swarm", "dgs"):
        r = runs[name]
        for ape in ("ape_team_first_pose_m", "ape_team_se3_m"):
            assert getattr(r, ape)[-1] < 0.9 * getattr(i, ape)[-1], (name, ape)
        assert c.chi2_delivered <= r.chi2_delivered < i.chi2_delivered, name
    # after the windows close each robot is alone yet stays near the team's map: it no longer
    # falls back to its own graph (the first-pose APE was independent's before robots kept memory)
    assert runs["swarm"].ape_team_first_pose_m[-1] < 0.6 * i.ape_team_first_pose_m[-1]
    assert (res.schedule.windows()[:, 3] <= 200).all()


def test_never_connected_swarm_is_independent_exactly(small, tmp_path):
    res = replay(small.dataset_dir, tmp_path / "never", comms="never", every=20, backends=["independent", "swarm"])
    independent, swarm = res.runs
    assert np.array_equal(swarm.final_poses, independent.final_poses)
    assert np.array_equal(swarm.ape_team_se3_m, independent.ape_team_se3_m)
    assert swarm.bytes.sum() == 0


def test_swarm_and_dgs_report_the_shared_variable_error_and_write_jrl_results(small, tmp_path):
    from studio.core.jrl_metrics import sve
    from studio.io.jrr import read_jrr
    from studio.jrl_evaluate import evaluate_jrr

    res = replay(small.dataset_dir, tmp_path / "r", comms="range:5", every=30, backends=["centralized", "swarm", "dgs"])
    runs = {r.name: r for r in res.runs}
    assert runs["centralized"].sve is None  # one estimate: nothing to disagree on
    for name in ("swarm", "dgs"):
        run = runs[name]
        assert run.sve is not None and run.sve.shape == (len(run.checkpoint_ticks), 2)
        assert np.isnan(run.sve[0]).all()  # nothing shared at the first pose
        assert np.isfinite(run.sve[-1]).all() and run.sve[-1, 0] > 0  # stale copies disagree
        jrr = read_jrr(res.out_dir / f"{name}.jrr")
        own_keys = sum(int(((s.keys >> 56) == ord(c)).sum()) for c, s in zip(jrr.robots, jrr.solutions))
        assert own_keys == 3 * 401 and sum(len(s.keys) for s in jrr.solutions) > own_keys
        # the .jrr holds the final beliefs: jrl's SVE of it is the last checkpoint's
        assert sve(list(jrr.solutions)) == pytest.approx(tuple(run.sve[-1]), rel=1e-9)
        # partial: a robot holds copies only of the closures delivered to it
        scored = evaluate_jrr(small.dataset_dir, res.out_dir / f"{name}.jrr", partial=True).summary
        assert scored.sve == pytest.approx(tuple(run.sve[-1]), rel=1e-9)
    rows = [ln.split(",") for ln in (res.out_dir / "metrics.csv").read_text().splitlines()[1:]]
    last = [r for r in rows if r[0] == "swarm" and r[3] == "all"][-1]
    assert float(last[7]) == pytest.approx(runs["swarm"].sve[-1, 0], rel=1e-8)
    assert [r[7:] for r in rows if r[0] == "centralized"][-1] == ["", ""]
    assert read_jrr(res.out_dir / "centralized.jrr").solutions[0].keys.size == 401


def test_each_back_end_reports_its_gap_to_the_certified_optimum(always, small):
    from studio.solve import load_problem
    from studio.solvers.sesync import certified_optimum, sesync_objective

    optimum = certified_optimum(load_problem(small.dataset_dir).problem)
    assert optimum.certified
    runs = {r.name: r for r in always.runs}
    for run in runs.values():
        assert run.sesync_f == pytest.approx(sesync_objective(load_problem(small.dataset_dir).problem, run.final_poses))
        assert run.gap_to_optimum == pytest.approx((run.sesync_f - optimum.f_star) / optimum.f_star, rel=1e-9)
        assert run.gap_to_optimum > -1e-9  # nothing lies below the certified optimum
    # the centralized back-end with every closure delivered is near the optimum, independent far above
    assert runs["centralized"].gap_to_optimum < 0.01 < runs["independent"].gap_to_optimum
    header, *rows = (always.out_dir / "summary.csv").read_text().splitlines()
    assert header.split(",")[5:7] == ["sesync_f", "gap_to_optimum"]
    assert all(float(r.split(",")[6]) == pytest.approx(runs[r.split(",")[0]].gap_to_optimum, rel=1e-8) for r in rows)


def test_a_graph_in_pieces_has_no_gap_to_report():
    from studio.core.model import PoseKind
    from studio.replay.metrics import gaps_to, team_optimum
    from studio.solvers.problem import Problem

    # two robots that never met: two chains with no edge between them
    poses = np.array([[0.0, 0, 0], [1, 0, 0], [5, 0, 0], [6, 0, 0]])
    upper = np.tile([1.0, 0, 0, 1, 0, 1], (2, 1))
    edges = np.array([[1.0, 0, 0]] * 2)
    problem = Problem(PoseKind.SE2, poses, np.array([0, 2]), np.array([1, 3]), edges, upper, np.zeros(2, bool))
    assert team_optimum(problem) is None
    f_star, scored = gaps_to(problem, [poses], None)
    assert f_star is None and scored[0][1] is None and np.isnan(scored[0][0])
