"""`studio evaluate`: evo's metrics per agent and pooled, estimate layouts, alignment, bad input."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from studio.cli import app
from studio.core.errors import ConfigError, EvaluationError, FormatError
from studio.core.trajectory import Trajectory
from studio.evaluate import Alignment, evaluate, format_markdown, format_table, score
from studio.generator.presets import preset
from studio.io.estimate import read_estimate
from studio.io.g2o import G2oDocument, write_g2o
from studio.io.multig2o import read_multi_g2o
from studio.io.tum import write_tum
from studio.synth import synthesize

_NS = 1_000_000_000


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A 3-agent, 241-poses-per-agent kollagen dataset written by `studio synth` (3D multi-g2o records)."""
    base = preset("multi3500x8")
    cfg = dataclasses.replace(base, number_of_steps=60, number_of_agents=3, agents=base.agents[:3], name="Small")
    return synthesize(cfg, tmp_path_factory.mktemp("synth"))


@pytest.fixture(scope="module")
def graph(small):
    return read_multi_g2o(small.dataset_dir).to_se3()


def _perturbed(graph, seed=7):
    """Ground truth with 3D noise on every pose (z, roll and pitch too), one (n, 7) array per agent."""
    rng = np.random.default_rng(seed)
    out = []
    for a in graph.agents:
        gt = a.ground_truth
        p = gt.copy()
        p[:, 0:3] += rng.normal(0, 0.3, (len(gt), 3))
        p[:, 3:7] = (Rotation.from_quat(gt[:, 3:7]) * Rotation.from_rotvec(rng.normal(0, 0.05, (len(gt), 3)))).as_quat()
        out.append(p)
    return out


def _doc(ids, poses):
    z = np.zeros(0, dtype=np.int64)
    from studio.core.model import PoseKind

    return G2oDocument(PoseKind.SE3, np.asarray(ids, dtype=np.int64), poses, z, z, np.zeros((0, 7)), np.zeros((0, 21)))


def _write_single(path, poses, order=None):
    allp = np.concatenate(poses)
    ids = np.arange(len(allp))
    if order is not None:
        ids, allp = ids[order], allp[order]
    write_g2o(path, _doc(ids, allp))


def _write_multi(folder, graph, poses):
    for a, p in zip(graph.agents, poses):
        (folder / a.name).mkdir(parents=True)
        write_g2o(folder / a.name / "posegraph.g2o", _doc(np.arange(len(p)), p))


def _write_tum(folder, graph, poses, suffix="", shift_ns=0):
    folder.mkdir(parents=True, exist_ok=True)
    for a, p in zip(graph.agents, poses):
        write_tum(folder / f"{a.name}{suffix}.tum", Trajectory.from_poses(a.name, a.stamps_ns + shift_ns, p))


def _numbers(ev):
    d = ev.to_dict()
    del d["dataset"], d["estimate"], d["estimate_layout"]
    return d


# ------------------------------------------------------------------------------------------ the values


def test_initial_estimate_pooled_ape_is_the_mean_distance_over_all_poses(small, graph):
    ev = evaluate(small.dataset_dir)
    gt = np.concatenate([a.ground_truth[:, 0:3] for a in graph.agents])
    init = np.concatenate([a.initial[:, 0:3] for a in graph.agents])
    dist = np.linalg.norm(gt - init, axis=1)
    assert ev.overall.poses == len(gt) == 3 * 241
    assert ev.overall.ape_translation_m.mean == pytest.approx(dist.mean(), rel=1e-15)
    assert ev.overall.ape_translation_m.max == pytest.approx(dist.max(), rel=1e-15)
    assert ev.overall.ape_translation_m.rmse == pytest.approx(np.sqrt(np.mean(dist**2)), rel=1e-12)
    assert ev.overall.ape_translation_m.mean > 0.1  # dead reckoning drifts
    for k, a in enumerate(ev.agents):
        assert a.ape_translation_m.mean == pytest.approx(dist[241 * k : 241 * (k + 1)].mean(), rel=1e-15)
        assert a.ape_translation_m.min == 0.0  # every agent starts on its ground truth
    assert ev.alignment is Alignment.none and ev.alignment_text == "unaligned"


def test_metrics_equal_evo_metric_objects(graph):
    """APE rotation and RPE are evaluated on columns here; they must equal evo's own per-pose loops."""
    from evo.core import metrics
    from evo.core.trajectory import PoseTrajectory3D

    est = _perturbed(graph)
    ev = score(graph, [Trajectory.from_poses(a.name, a.stamps_ns, p) for a, p in zip(graph.agents, est)])

    def traj(p, a):
        return PoseTrajectory3D(
            positions_xyz=p[:, 0:3], orientations_quat_wxyz=p[:, [6, 3, 4, 5]], timestamps=a.stamps_ns / _NS
        )

    rel = metrics.PoseRelation
    pooled = {key: [] for key in ("at", "ar", "mt", "mr", "nt", "nr")}
    for a, p, row in zip(graph.agents, est, ev.agents):
        data = (traj(a.ground_truth, a), traj(p, a))
        cases = [
            ("at", row.ape_translation_m, metrics.APE(rel.translation_part)),
            ("ar", row.ape_rotation_deg, metrics.APE(rel.rotation_angle_deg)),
            (
                "mt",
                row.rpe_m_translation_m,
                metrics.RPE(rel.translation_part, 1.0, metrics.Unit.meters, pairs_from_reference=True),
            ),
            (
                "mr",
                row.rpe_m_rotation_deg,
                metrics.RPE(rel.rotation_angle_deg, 1.0, metrics.Unit.meters, pairs_from_reference=True),
            ),
            ("nt", row.rpe_node_translation_m, metrics.RPE(rel.translation_part, 1, metrics.Unit.frames)),
            ("nr", row.rpe_node_rotation_deg, metrics.RPE(rel.rotation_angle_deg, 1, metrics.Unit.frames)),
        ]
        for key, ours, metric in cases:
            metric.process_data(data)
            pooled[key].append(metric.error)
            ref = metric.get_all_statistics()
            assert ours.count == len(metric.error) > 10
            for stat in ("rmse", "mean", "median", "std", "min", "max"):
                assert getattr(ours, stat) == pytest.approx(ref[stat], rel=1e-9, abs=1e-9), (a.name, key, stat)
    assert ev.overall.rpe_m_translation_m.mean == pytest.approx(np.concatenate(pooled["mt"]).mean(), rel=1e-9)
    assert ev.overall.ape_rotation_deg.max == pytest.approx(np.concatenate(pooled["ar"]).max(), rel=1e-9)


def test_ground_truth_as_estimate_scores_zero(graph):
    ev = score(graph, [Trajectory.from_poses(a.name, a.stamps_ns, a.ground_truth) for a in graph.agents])
    assert ev.overall.ape_translation_m.max == 0.0
    assert ev.overall.ape_rotation_deg.max < 1e-6
    assert ev.overall.rpe_node_translation_m.max < 1e-12
    assert ev.overall.rpe_m_rotation_deg.max < 1e-6


# ------------------------------------------------------------------------------------------ layouts


def test_single_g2o_multi_g2o_and_tum_estimates_give_the_same_numbers(small, graph, tmp_path):
    est = _perturbed(graph)
    n = sum(len(p) for p in est)
    _write_single(tmp_path / "opt.g2o", est, order=np.random.default_rng(1).permutation(n))  # any vertex order
    _write_multi(tmp_path / "multi", graph, est)
    _write_tum(tmp_path / "tum", graph, est, suffix="_optimized")
    results = [
        evaluate(small.dataset_dir, estimate=p) for p in (tmp_path / "opt.g2o", tmp_path / "multi", tmp_path / "tum")
    ]
    assert [r.estimate_layout for r in results] == ["single-g2o", "multi-g2o", "tum"]
    assert _numbers(results[0]) == _numbers(results[1]) == _numbers(results[2])
    direct = score(graph, [Trajectory.from_poses(a.name, a.stamps_ns, p) for a, p in zip(graph.agents, est)])
    assert results[0].overall.ape_translation_m.mean == direct.overall.ape_translation_m.mean
    assert 0.3 < results[0].overall.ape_translation_m.mean < 0.6  # 3D noise of 0.3 m per axis


def test_datasets_own_single_g2o_scores_like_its_initial_estimate(small):
    """kollagen's NAME.g2o (2D records, agents concatenated) holds the initial estimate."""
    single = small.single_dir / "Small.g2o"
    assert _numbers(evaluate(small.dataset_dir, estimate=single)) == _numbers(evaluate(small.dataset_dir))


def test_tum_estimate_matched_within_tolerance(small, graph, tmp_path):
    est = _perturbed(graph)
    _write_tum(tmp_path / "ok", graph, est, shift_ns=4_000_000)  # 4 ms off: within 10 ms
    _write_multi(tmp_path / "multi", graph, est)
    assert _numbers(evaluate(small.dataset_dir, estimate=tmp_path / "ok")) == _numbers(
        evaluate(small.dataset_dir, estimate=tmp_path / "multi")
    )
    with pytest.raises(EvaluationError, match=r"estimate of agent1: no timestamp matches .* within 0.001 s"):
        evaluate(small.dataset_dir, estimate=tmp_path / "ok", tum_max_diff_s=0.001)
    half = tmp_path / "half"
    half.mkdir()
    for a, p in zip(graph.agents, est):
        write_tum(half / f"{a.name}.tum", Trajectory.from_poses(a.name, a.stamps_ns[::2], p[::2]))
    ev = evaluate(small.dataset_dir, estimate=half)
    assert [a.poses for a in ev.agents] == [121, 121, 121]
    assert ev.overall.poses == 363
    assert (
        ev.warnings[2]
        == "estimate of agent3: 121 of 241 ground-truth poses matched within 0.01 s; only those are scored"
    )
    assert evaluate(small.dataset_dir, estimate=tmp_path / "ok").warnings == ()
    res = CliRunner().invoke(app, ["evaluate", str(small.dataset_dir), "-e", str(half)])
    assert res.exit_code == 0 and "warning: estimate of agent1: 121 of 241 ground-truth poses matched" in res.output


# ------------------------------------------------------------------------------------------ alignment


def _moved(poses, r, t, s=1.0):
    out = poses.copy()
    out[:, 0:3] = s * poses[:, 0:3] @ r.as_matrix().T + t
    out[:, 3:7] = (r * Rotation.from_quat(poses[:, 3:7])).as_quat()
    return out


def test_alignment_removes_a_common_transform(graph):
    r = Rotation.from_euler("z", 30, degrees=True)
    est = [
        Trajectory.from_poses(a.name, a.stamps_ns, _moved(a.ground_truth, r, [5.0, -3.0, 1.0], 1.2))
        for a in graph.agents
    ]
    assert score(graph, est).overall.ape_translation_m.mean > 1.0
    assert score(graph, est, align="se3").overall.ape_translation_m.mean > 0.1  # scale is left
    ev = score(graph, est, align="sim3")
    assert ev.overall.ape_translation_m.max < 1e-9
    assert ev.overall.ape_rotation_deg.max < 1e-5
    assert ev.overall.rpe_m_translation_m.max < 1e-9  # RPE is computed after the sim(3) scale too
    ((rot, _, s),) = ev.alignment_transforms
    assert s == pytest.approx(1 / 1.2)
    assert np.allclose(rot, r.inv().as_matrix())
    assert "sim3 Umeyama alignment, one for all agents" in format_table(ev)


def test_unknown_alignment_is_a_studio_error(graph):
    with pytest.raises(EvaluationError, match=r"unknown alignment 'se2' \(known: none, first-pose, se3, sim3\)"):
        score(graph, align="se2")


def test_align_per_agent_removes_one_transform_per_agent(graph):
    est = [
        Trajectory.from_poses(
            a.name, a.stamps_ns, _moved(a.ground_truth, Rotation.from_euler("z", 10 * k, degrees=True), [k, 0, 0])
        )
        for k, a in enumerate(graph.agents)
    ]
    assert score(graph, est, align="se3").overall.ape_translation_m.mean > 0.1
    ev = score(graph, est, align="se3", align_per_agent=True)
    assert ev.overall.ape_translation_m.max < 1e-9
    assert len(ev.alignment_transforms) == 3
    assert ev.alignment_text == "se3 Umeyama alignment, one per agent"


@pytest.mark.parametrize("align", ["none", "first-pose"])
def test_the_library_refuses_align_per_agent_the_cli_refuses(graph, align):
    with pytest.raises(ConfigError, match=rf"^align_per_agent: .* needs an se3 or sim3 alignment, not {align}$") as err:
        score(graph, None, align=align, align_per_agent=True)
    assert err.value.option == "align_per_agent"


# ------------------------------------------------------------------------------------------ bad input


def test_single_g2o_missing_vertex_names_agent_and_count(small, graph, tmp_path):
    est = _perturbed(graph)
    allp = np.concatenate(est)
    keep = np.ones(len(allp), dtype=bool)
    keep[241 + 17] = False  # agent2's vertex 17
    write_g2o(tmp_path / "opt.g2o", _doc(np.flatnonzero(keep), allp[keep]))
    with pytest.raises(
        EvaluationError,
        match=r"opt.g2o: agent2 has 240 of its 241 vertices \(ids 241..481\); "
        r"1 missing, the first is id 258",
    ):
        evaluate(small.dataset_dir, estimate=tmp_path / "opt.g2o")
    write_g2o(tmp_path / "more.g2o", _doc(np.arange(len(allp) + 2), np.concatenate([allp, allp[:2]])))
    with pytest.raises(EvaluationError, match=r"2 vertices have ids outside the dataset's 723 \(ids 0..722\)"):
        evaluate(small.dataset_dir, estimate=tmp_path / "more.g2o")


def test_multi_g2o_estimate_mismatches(small, graph, tmp_path):
    est = _perturbed(graph)
    _write_multi(tmp_path / "short", graph, [est[0], est[1][:-3], est[2]])
    with pytest.raises(EvaluationError, match=r"agent2/posegraph.g2o: agent2 has 238 vertices, the dataset 241"):
        evaluate(small.dataset_dir, estimate=tmp_path / "short")
    _write_multi(tmp_path / "missing", graph, est)
    shutil.rmtree(tmp_path / "missing" / "agent3")
    with pytest.raises(EvaluationError, match=r"no agent3/posegraph.g2o for agent agent3"):
        evaluate(small.dataset_dir, estimate=tmp_path / "missing")
    _write_multi(tmp_path / "shifted", graph, est)
    write_g2o(tmp_path / "shifted" / "agent2" / "posegraph.g2o", _doc(np.arange(241) + 1, est[1]))
    with pytest.raises(
        EvaluationError,
        match=r"agent2 has 240 of its 241 vertices \(ids 0..240\); 1 missing, "
        r"the first is id 0",
    ):
        evaluate(small.dataset_dir, estimate=tmp_path / "shifted")
    _write_multi(tmp_path / "extra", graph, est)
    shutil.copytree(tmp_path / "extra" / "agent3", tmp_path / "extra" / "agent4")
    with pytest.raises(EvaluationError, match=r"agent agent4 is not in the dataset \(agents: agent1, agent2, agent3\)"):
        evaluate(small.dataset_dir, estimate=tmp_path / "extra")


def test_nan_pose_is_rejected(small, graph, tmp_path):
    est = _perturbed(graph)
    _write_multi(tmp_path / "nan", graph, est)
    path = tmp_path / "nan" / "agent2" / "posegraph.g2o"
    lines = path.read_text().splitlines(keepends=True)
    lines[5] = lines[5].replace(lines[5].split()[3], "nan", 1)
    path.write_text("".join(lines))
    with pytest.raises(FormatError, match=r"agent2/posegraph.g2o:6: value is not finite"):
        evaluate(small.dataset_dir, estimate=tmp_path / "nan")
    bad = [p.copy() for p in est]
    bad[2][9, 1] = np.nan
    with pytest.raises(EvaluationError, match=r"estimate of agent3: pose 9 is not finite"):
        score(graph, [Trajectory.from_poses(a.name, a.stamps_ns, p) for a, p in zip(graph.agents, bad)])


def test_missing_ground_truth_file(small, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(small.dataset_dir, data)
    (data / "agent2" / "agent2_GT.tum").unlink()
    with pytest.raises(EvaluationError, match=r"agent2: no ground truth \(.*agent2/agent2_GT.tum is missing\)"):
        evaluate(data)


def test_tum_folder_without_a_file_for_an_agent(small, graph, tmp_path):
    _write_tum(tmp_path / "tum", graph, _perturbed(graph))
    (tmp_path / "tum" / "agent3.tum").unlink()
    with pytest.raises(EvaluationError, match=r"no agent3.tum or agent3_\*.tum for agent agent3"):
        read_estimate(tmp_path / "tum", graph)
    for name in ("agent3_a", "agent3_b"):
        write_tum(
            tmp_path / "tum" / f"{name}.tum",
            Trajectory.from_poses("agent3", graph.agents[2].stamps_ns, graph.agents[2].ground_truth),
        )
    with pytest.raises(EvaluationError, match=r"several TUM files for agent agent3: agent3_a.tum, agent3_b.tum"):
        read_estimate(tmp_path / "tum", graph)
    # the agent's own file wins over prefixed ones (solve writes <agent>.tum; another agent may be
    # named agent3_b, as after `convert tum a.tum a_b.tum`)
    write_tum(
        tmp_path / "tum" / "agent3.tum",
        Trajectory.from_poses("agent3", graph.agents[2].stamps_ns, graph.agents[2].ground_truth),
    )
    assert read_estimate(tmp_path / "tum", graph).agents[2].source.endswith("agent3.tum")


def test_short_path_has_no_rpe_per_metre(graph):
    a = graph.agents[0]
    from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph

    tiny = AgentGraph(
        "tiny", a.kind, a.stamps_ns[:3], a.initial[:3], a.ground_truth[:3], Edges.empty(a.kind), Edges.empty(a.kind)
    )
    ev = score(PoseGraph(a.kind, (tiny,), InterAgentEdges.empty(a.kind)))
    assert ev.agents[0].rpe_m_translation_m is None  # 3 poses, 0.5 m of path
    assert ev.agents[0].rpe_node_translation_m.count == 2
    assert " - " in format_table(ev)


# ------------------------------------------------------------------------------------------ CLI


def test_cli_table_json_and_markdown(small):
    runner = CliRunner()
    res = runner.invoke(app, ["evaluate", str(small.dataset_dir)])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[2] == "alignment: unaligned"
    ev = evaluate(small.dataset_dir)
    all_row = next(ln for ln in lines if ln.startswith("all "))
    assert f"{ev.overall.ape_translation_m.mean:.6f}" in all_row.split()
    assert [ln.split()[0] for ln in lines if ln.startswith("agent")][1:] == ["agent1", "agent2", "agent3"]

    res = runner.invoke(app, ["evaluate", str(small.dataset_dir), "--json", "--align", "se3"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["alignment"] == {"mode": "se3", "per_agent": False}
    assert (
        doc["all"]["ape_translation_m"]["mean"]
        == evaluate(small.dataset_dir, align="se3").overall.ape_translation_m.mean
    )
    assert [a["name"] for a in doc["agents"]] == ["agent1", "agent2", "agent3"]

    res = runner.invoke(app, ["evaluate", str(small.dataset_dir), "--markdown"])
    assert res.exit_code == 0
    assert res.output == format_markdown(ev)
    assert "| agent | poses | APE t mean |" in res.output


@pytest.mark.parametrize(
    "args, message",
    [
        (["--json", "--markdown"], "error: --json and --markdown exclude each other"),
        (
            ["--align-per-agent"],
            "error: --align-per-agent: one alignment per agent needs an se3 or sim3 alignment, not none",
        ),
        (["--estimate", "nowhere.g2o"], "error: nowhere.g2o: no such file or folder"),
        (["--rpe-delta-m", "0"], "error: the RPE distance must be a positive number of metres, got 0.0"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(small, args, message):
    res = CliRunner().invoke(app, ["evaluate", str(small.dataset_dir), *args])
    assert res.exit_code == 2
    assert res.output.strip() == message


def test_cli_missing_dataset(tmp_path):
    res = CliRunner().invoke(app, ["evaluate", str(tmp_path / "nope")])
    assert res.exit_code == 2
    assert res.output.strip() == f"error: {tmp_path / 'nope'}: not a folder"


# ------------------------------------------------------------------------------------------ reading


def test_reading_vertices_only_keeps_every_pose(small):
    full = read_multi_g2o(small.dataset_dir)
    poses = read_multi_g2o(small.dataset_dir, edges=False)
    assert poses.edge_counts() == {"odometry": 0, "intra_loop_closures": 0, "inter_loop_closures": 0}
    assert full.edge_counts()["odometry"] == 3 * 240
    for a, b in zip(full.agents, poses.agents):
        assert a.initial.tobytes() == b.initial.tobytes()
        assert a.ground_truth.tobytes() == b.ground_truth.tobytes()
        assert a.stamps_ns.tobytes() == b.stamps_ns.tobytes()


def test_g2o_file_with_vertices_only_reads(tmp_path):
    from studio.io.g2o import read_g2o

    (tmp_path / "v.g2o").write_text("VERTEX_SE3:QUAT 0 1 2 3 0 0 0 1\nVERTEX_SE3:QUAT 1 4 5 6 0 0 0 1\n")
    doc = read_g2o(tmp_path / "v.g2o")
    assert doc.vertex_poses[:, 0].tolist() == [1.0, 4.0]
    assert doc.edge_information_upper.shape == (0, 21)


# ------------------------------------------------------------------------------------------ Rerun


def test_rrd_holds_the_per_node_error_series(small, graph, tmp_path):
    from rerun.chunk import RrdReader

    est = _perturbed(graph)
    _write_multi(tmp_path / "multi", graph, est)
    rrd = tmp_path / "errors.rrd"
    res = CliRunner().invoke(
        app, ["evaluate", str(small.dataset_dir), "-e", str(tmp_path / "multi"), "--rrd", str(rrd)]
    )
    assert res.exit_code == 0, res.output
    ev = evaluate(small.dataset_dir, estimate=tmp_path / "multi")
    chunks = {c.entity_path: c for c in RrdReader(rrd).stream() if not c.is_static}
    batch = chunks["/evaluation/ape_translation_m/agent2"].to_record_batch()
    values = np.concatenate(batch.column("Scalars:scalars").to_pylist())
    assert np.array_equal(values, ev.ape_translation_series_m[1])
    assert batch.column("node").to_pylist() == list(range(241))
    assert set(chunks) == {
        f"/evaluation/{s}/agent{k}" for k in (1, 2, 3) for s in ("ape_translation_m", "ape_rotation_deg")
    }
    # the 3D view: ground truth as one strip, the estimate as segments coloured by their error
    static = {c.entity_path: c.to_record_batch() for c in RrdReader(rrd).stream() if c.is_static}
    gt = static["/evaluation/world/agent2/ground_truth"].column("LineStrips3D:strips").to_pylist()[0][0]
    np.testing.assert_array_equal(np.array(gt, dtype=np.float32), ev.ground_truth_xyz[1].astype(np.float32))
    est = static["/evaluation/world/agent2/estimate"]
    assert len(est.column("LineStrips3D:strips").to_pylist()[0]) == 240
    colours = est.column("LineStrips3D:colors").to_pylist()[0]
    worst = int(np.argmax(ev.ape_translation_series_m[1][:-1] + ev.ape_translation_series_m[1][1:]))
    assert len(set(colours)) > 10 and colours[worst] != colours[0]
    reader = RrdReader(rrd)
    kinds = sorted(
        v
        for c in reader.stream(store=reader.blueprints()[0])
        if "ViewBlueprint:class_identifier" in c.to_record_batch().schema.names
        for v in np.concatenate(c.to_record_batch().column("ViewBlueprint:class_identifier").to_pylist())
    )
    assert kinds == ["3D", "TextDocument", "TimeSeries", "TimeSeries"]  # one plot per metric
    res = CliRunner().invoke(app, ["evaluate", str(small.dataset_dir), "--rrd", str(rrd)])
    assert res.exit_code == 2 and "already exists (use --force to overwrite)" in res.output


def test_evaluation_recording_is_the_same_for_the_same_inputs(small, graph, tmp_path):
    """Two runs of `studio evaluate --rrd` on the same inputs: the same recording id and the same
    fingerprint. The bytes still differ: Rerun's chunk and row ids are time-based (docs/recordings.md)."""
    from rerun.chunk import RrdReader

    from studio.recording.dataset import recording_id_for
    from studio.recording.rrd_checks import fingerprint_rrd

    _write_multi(tmp_path / "multi", graph, _perturbed(graph))
    args = ["evaluate", str(small.dataset_dir), "-e", str(tmp_path / "multi"), "--align", "se3"]
    for name in ("a.rrd", "b.rrd"):
        res = CliRunner().invoke(app, args + ["--rrd", str(tmp_path / name)])
        assert res.exit_code == 0, res.output
    ids = [[s.recording_id for s in RrdReader(tmp_path / n).recordings()] for n in ("a.rrd", "b.rrd")]
    assert ids[0] == ids[1] and len(ids[0]) == 1
    assert ids[0][0] != recording_id_for(graph)  # its own id, not the dataset recording's
    assert fingerprint_rrd(tmp_path / "a.rrd") == fingerprint_rrd(tmp_path / "b.rrd")
    # another option, another recording: the id follows the inputs
    res = CliRunner().invoke(app, args[:-1] + ["sim3", "--rrd", str(tmp_path / "c.rrd")])
    assert res.exit_code == 0, res.output
    assert [s.recording_id for s in RrdReader(tmp_path / "c.rrd").recordings()] != ids[0]


def test_dataset_with_2d_records_scores_like_3d(small, tmp_path):
    two_d = synthesize(small.config, tmp_path, multi_records="2d")
    assert "VERTEX_SE2" in (two_d.dataset_dir / "agent1" / "posegraph.g2o").read_text()[:20]
    assert _numbers(evaluate(two_d.dataset_dir)) == _numbers(evaluate(small.dataset_dir))
