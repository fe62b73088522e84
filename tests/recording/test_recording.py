"""studio.recording: what a recording holds, determinism, the exact fingerprint, synth integration."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from studio.core.model import AgentGraph, PoseGraph
from studio.generator.kollagen import generate
from studio.recording.dataset import STRIP_CHUNK_ROWS, inter_pair_path, record_graph, recording_id_for
from studio.recording.entities import (
    APPLICATION_ID,
    LOOP_CLOSURES_INTER,
    LOOP_CLOSURES_INTRA,
    PATH_GROUND_TRUTH,
    PATH_INITIAL,
    POSE_GROUND_TRUTH,
    SERIES_INTER_LOOP_CLOSURES,
    SERIES_LOOP_CLOSURES,
    SERIES_POSITION_ERROR,
    TIMELINE_NODE,
    TIMELINE_TIME,
)
from studio.recording.rrd_checks import fingerprint_rrd, read_fingerprint, rrd_compare, rrd_verify, write_fingerprint
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data" / "configs"
SMALL = DATA / "small3x100.json"


# --------------------------------------------------------------------------------------------------
# Reading a recording back


def read_back(path: Path) -> dict:
    """``{(entity, component): [(index dict, value), ...]}`` of the recording store, plus the
    timelines seen and the store's ids under ``("_timelines",)`` and ``("_store",)``."""
    import rerun.chunk as rc

    reader = rc.RrdReader(path)
    (store,) = reader.recordings()
    out: dict = {("_timelines",): set(), ("_store",): (store.application_id, store.recording_id)}
    for chunk in reader.stream(store=store):
        batch = chunk.to_record_batch()
        kinds = {f.name: (f.metadata or {}).get(b"rerun:kind", b"").decode() for f in batch.schema}
        index = [n for n, k in kinds.items() if k == "index"]
        out[("_timelines",)].update(index)
        idx_vals = {n: batch.column(n).cast("int64").to_pylist() for n in index}
        for name, kind in kinds.items():
            if kind != "data":
                continue
            values = batch.column(name).to_pylist()
            rows = out.setdefault((chunk.entity_path, name), [])
            for r, v in enumerate(values):
                rows.append(({n: idx_vals[n][r] for n in index}, v))
    return out


def _entity(template: str, agent: AgentGraph) -> str:
    return "/" + template.format(agent=agent.name)


def check_recording_matches(path: Path, graph: PoseGraph) -> None:
    """Every agent's paths, current poses and loop-closure counts, as logged (float32 positions)."""
    data = read_back(path)
    g = graph.to_se3()
    assert data[("_store",)] == (APPLICATION_ID, recording_id_for(graph))
    for agent in g.agents:
        ((_, gt_strips),) = data[(_entity(PATH_GROUND_TRUTH, agent), "LineStrips3D:strips")]
        np.testing.assert_array_equal(
            np.array(gt_strips[0], dtype=np.float32), agent.ground_truth[:, 0:3].astype(np.float32)
        )
        ((_, init_strips),) = data[(_entity(PATH_INITIAL, agent), "LineStrips3D:strips")]
        np.testing.assert_array_equal(
            np.array(init_strips[0], dtype=np.float32), agent.initial[:, 0:3].astype(np.float32)
        )
        poses = sorted(
            data[(_entity(POSE_GROUND_TRUTH, agent), "Transform3D:translation")], key=lambda r: r[0][TIMELINE_NODE]
        )
        assert [r[0][TIMELINE_NODE] for r in poses] == list(range(agent.num_poses))
        np.testing.assert_array_equal(
            np.array([r[1][0] for r in poses], dtype=np.float32), agent.ground_truth[:, 0:3].astype(np.float32)
        )
        lcs = data.get((_entity(LOOP_CLOSURES_INTRA, agent), "LineStrips3D:strips"), [])
        assert len(lcs) == len(agent.loop_closures)
        created = np.maximum(agent.loop_closures.from_index, agent.loop_closures.to_index)
        assert sorted(r[0][TIMELINE_NODE] for r in lcs) == sorted(created.tolist())
        counts = sorted(
            data[(_entity(SERIES_LOOP_CLOSURES, agent), "Scalars:scalars")], key=lambda r: r[0][TIMELINE_NODE]
        )
        assert counts[-1][1] == [float(len(agent.loop_closures))]
        errors = sorted(
            data[(_entity(SERIES_POSITION_ERROR, agent), "Scalars:scalars")], key=lambda r: r[0][TIMELINE_NODE]
        )
        expected = np.linalg.norm(agent.initial[:, 0:3] - agent.ground_truth[:, 0:3], axis=1)
        np.testing.assert_array_equal(np.array([r[1][0] for r in errors]), expected)
    inter_root = "/" + LOOP_CLOSURES_INTER.split("{")[0]
    inter = [
        r
        for key, rows in data.items()
        if len(key) == 2 and str(key[0]).startswith(inter_root) and key[1] == "LineStrips3D:strips"
        for r in rows
    ]
    assert len(inter) == len(graph.inter)  # no outliers here: every one is drawn as an inlier
    pairs = {(min(a, b), max(a, b)) for a, b in zip(graph.inter.from_agent.tolist(), graph.inter.to_agent.tolist())}
    for a, b in pairs:  # one entity per agent pair
        rows = data[("/" + inter_pair_path(graph, a, b), "LineStrips3D:strips")]
        lo = np.minimum(graph.inter.from_agent, graph.inter.to_agent)
        hi = np.maximum(graph.inter.from_agent, graph.inter.to_agent)
        assert len(rows) == int(np.count_nonzero((lo == a) & (hi == b)))
    if len(graph.inter):
        counts = data[("/" + SERIES_INTER_LOOP_CLOSURES, "Scalars:scalars")]
        assert max(v[0] for _, v in counts) == float(len(graph.inter))
    facts = {key[1]: v for key, rows in data.items() if key[0] == "/__properties/dataset" for _, v in rows}
    edge_counts = graph.edge_counts()
    assert facts["agents"] == [len(graph.agents)]
    assert facts["nodes"] == [graph.num_poses]
    assert facts["intra_loop_closures"] == [edge_counts["intra_loop_closures"]]
    assert facts["inter_loop_closures"] == [edge_counts["inter_loop_closures"]]
    assert facts["odometry_edges"] == [edge_counts["odometry"]]


# --------------------------------------------------------------------------------------------------
# Fixtures


@pytest.fixture(scope="module")
def small_graph() -> PoseGraph:
    return generate(load_synth_config(SMALL)).graph


@pytest.fixture(scope="module")
def small_synth(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth")
    return synthesize(load_synth_config(SMALL), out)


@pytest.fixture(scope="module")
def small_rrd(small_synth) -> Path:
    return small_synth.rrd_path


# --------------------------------------------------------------------------------------------------
# Content


def test_synth_writes_a_recording_that_verifies_and_holds_the_dataset(small_synth):
    assert small_synth.rrd_path == small_synth.dataset_dir.parent / "small3x100.rrd"
    assert small_synth.rrd_path.is_file()
    rrd_verify(small_synth.rrd_path)
    check_recording_matches(small_synth.rrd_path, small_synth.output.graph)


def test_synthetic_data_has_no_time_timeline_and_no_clock_values(small_rrd):
    data = read_back(small_rrd)
    assert data[("_timelines",)] == {TIMELINE_NODE}  # no log_time/log_tick: nothing from the clock


def test_properties_hold_the_config(small_rrd):
    data = read_back(small_rrd)
    ((_, text),) = data[("/__properties/config", "json")]
    assert json.loads(text[0])["number_of_agents"] == 3
    ((_, name),) = data[("/__properties", "RecordingInfo:name")]
    assert name == ["small3x100"]


def test_time_indexed_strips_come_in_chunks_of_at_most_a_thousand_rows(small_rrd):
    import rerun.chunk as rc

    reader = rc.RrdReader(small_rrd)
    sizes = [
        c.num_rows
        for c in reader.stream()
        if c.entity_path.startswith("/world/") and "loop_closures" in c.entity_path and not c.is_static
    ]
    assert sizes and max(sizes) <= STRIP_CHUNK_ROWS
    assert sum(sizes) == 313 + 677  # intra + inter loop closures of small3x100


def test_real_stamps_add_a_time_timeline(small_graph, tmp_path):
    base = 1_700_000_000 * 10**9
    agents = tuple(
        dataclasses.replace(a, stamps_ns=base + np.arange(a.num_poses) * 50_000_000 + 7 * k)
        for k, a in enumerate(small_graph.agents)
    )
    graph = dataclasses.replace(small_graph, agents=agents)
    res = record_graph(graph, tmp_path / "t.rrd", name="t")
    assert res.real_time
    data = read_back(tmp_path / "t.rrd")
    assert data[("_timelines",)] == {TIMELINE_NODE, TIMELINE_TIME}
    a = graph.agents[1]
    poses = data[(_entity(POSE_GROUND_TRUTH, a), "Transform3D:translation")]
    assert sorted(r[0][TIMELINE_TIME] for r in poses) == a.stamps_ns.tolist()


def test_agent_without_ground_truth_draws_loop_closures_on_the_initial_estimate(small_graph, tmp_path):
    agents = (dataclasses.replace(small_graph.agents[0], ground_truth=None),) + small_graph.agents[1:]
    graph = dataclasses.replace(small_graph, agents=agents)
    record_graph(graph, tmp_path / "n.rrd", name="n")
    data = read_back(tmp_path / "n.rrd")
    a = graph.agents[0]
    assert (_entity(PATH_GROUND_TRUTH, a), "LineStrips3D:strips") not in data
    assert (_entity(SERIES_POSITION_ERROR, a), "Scalars:scalars") not in data
    lcs = data[(_entity(LOOP_CLOSURES_INTRA, a), "LineStrips3D:strips")]
    first = min(lcs, key=lambda r: r[0][TIMELINE_NODE])
    lc = a.loop_closures
    k = int(np.argmin(np.maximum(lc.from_index, lc.to_index)))
    np.testing.assert_array_equal(
        np.array(first[1][0], dtype=np.float32)[0], np.r_[a.initial[lc.from_index[k], 0:2], 0.0].astype(np.float32)
    )


# --------------------------------------------------------------------------------------------------
# Determinism and the exact check


def test_two_runs_give_equal_fingerprints_and_rrd_compare_accepts_them(small_graph, small_rrd, tmp_path):
    again = tmp_path / "again.rrd"
    record_graph(
        small_graph, again, name="small3x100", config_json=json.dumps(json.loads((SMALL).read_text()), sort_keys=True)
    )
    assert small_rrd.read_bytes() != again.read_bytes()  # chunk ids and row ids differ ...
    assert fingerprint_rrd(again) == fingerprint_rrd(small_rrd)  # ... the content does not
    rrd_compare(small_rrd, again)


def test_one_ulp_change_to_one_pose_changes_the_fingerprint(small_graph, tmp_path):
    a0 = small_graph.agents[0]
    gt = a0.ground_truth.copy()
    # one ulp of the float32 that Rerun stores for x of pose 17
    gt[17, 0] = float(np.nextafter(np.float32(gt[17, 0]), np.float32(np.inf)))
    assert np.float32(gt[17, 0]) != np.float32(a0.ground_truth[17, 0])
    changed = dataclasses.replace(
        small_graph, agents=(dataclasses.replace(a0, ground_truth=gt),) + small_graph.agents[1:]
    )
    base, ulp = tmp_path / "base.rrd", tmp_path / "ulp.rrd"
    record_graph(small_graph, base, name="x")
    record_graph(changed, ulp, name="x")
    fa, fb = fingerprint_rrd(base), fingerprint_rrd(ulp)
    assert fa.keys() == fb.keys()
    differing = {k for k in fa if fa[k] != fb[k]}
    assert {
        "recording0 /world/agent1/ground_truth LineStrips3D:strips",
        "recording0 /world/agent1/ground_truth_pose Transform3D:translation",
        "recording0 /metrics/position_error/agent1 Scalars:scalars",
    } <= differing
    assert "recording0 /world/agent2/ground_truth LineStrips3D:strips" not in differing


def test_fingerprint_includes_the_blueprint(small_graph, tmp_path, monkeypatch):
    import studio.recording.dataset as recording

    record_graph(small_graph, tmp_path / "a.rrd", name="x")
    monkeypatch.setattr(recording, "TIMELINE_NODE", "nodes")  # the time panel starts elsewhere
    record_graph(small_graph, tmp_path / "b.rrd", name="x")
    fa, fb = fingerprint_rrd(tmp_path / "a.rrd"), fingerprint_rrd(tmp_path / "b.rrd")
    assert (
        fa["blueprint0 /time_panel TimePanelBlueprint:timeline"]
        != fb["blueprint0 /time_panel TimePanelBlueprint:timeline"]
    )


def test_fingerprint_file_round_trips(small_rrd, tmp_path):
    fp = fingerprint_rrd(small_rrd)
    write_fingerprint(fp, tmp_path / "fp")
    assert read_fingerprint(tmp_path / "fp") == fp
    assert len(fp) > 100 and all(len(v) == 64 for v in fp.values())


def test_record_of_the_written_folder_equals_the_synth_recording(small_synth, tmp_path):
    from studio.recording.dataset import record_dataset

    res = record_dataset(small_synth.dataset_dir, tmp_path / "r.rrd")
    fa, fb = fingerprint_rrd(small_synth.rrd_path), fingerprint_rrd(res.path)
    # kollagen's folder holds 3D records of a planar graph: both paths record the same thing, SE2
    assert {k for k in fa if fa[k] != fb[k]} == set()
    for path in (small_synth.rrd_path, res.path):
        facts = {
            key[1]: v for key, rows in read_back(path).items() if key[0] == "/__properties/dataset" for _, v in rows
        }
        assert facts["pose_kind"] == ["SE2"]


def test_synth_without_rrd(tmp_path):
    res = synthesize(load_synth_config(SMALL), tmp_path, rrd=False)
    assert res.rrd_path is None
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "small3x100",
        "small3x100.config.json",
        "small3x100_singleg2o",
    ]


@pytest.mark.slow
def test_multi3500x8_synth_recording(tmp_path):
    res = synthesize(load_synth_config("multi3500x8"), tmp_path)
    assert res.rrd_path == tmp_path / "multi3500x8.rrd"
    rrd_verify(res.rrd_path)
    check_recording_matches(res.rrd_path, res.output.graph)


def test_single_agent_without_inter_agent_edges(small_graph, tmp_path):
    from studio.core.model import InterAgentEdges

    graph = PoseGraph(small_graph.kind, small_graph.agents[:1], InterAgentEdges.empty(small_graph.kind))
    record_graph(graph, tmp_path / "one.rrd", name="one")
    check_recording_matches(tmp_path / "one.rrd", graph)
    data = read_back(tmp_path / "one.rrd")
    assert ("/" + SERIES_INTER_LOOP_CLOSURES, "Scalars:scalars") not in data


def test_spatial_graph_keeps_its_heights(small_graph, tmp_path):
    g = small_graph.to_se3()
    a0 = g.agents[0]
    lifted = a0.ground_truth.copy()
    lifted[:, 2] = np.linspace(0.0, 5.0, a0.num_poses)
    graph = dataclasses.replace(g, agents=(dataclasses.replace(a0, ground_truth=lifted),) + g.agents[1:])
    record_graph(graph, tmp_path / "z.rrd", name="z")
    check_recording_matches(tmp_path / "z.rrd", graph)
    data = read_back(tmp_path / "z.rrd")
    ((_, strips),) = data[(_entity(PATH_GROUND_TRUTH, a0), "LineStrips3D:strips")]
    assert strips[0][-1][2] == pytest.approx(5.0)


def test_fingerprint_does_not_depend_on_chunking(small_graph, tmp_path, monkeypatch):
    import studio.recording.dataset as recording

    record_graph(small_graph, tmp_path / "a.rrd", name="x")
    monkeypatch.setattr(recording, "STRIP_CHUNK_ROWS", 7)
    record_graph(small_graph, tmp_path / "b.rrd", name="x")
    import rerun.chunk as rc

    chunks = [len(list(rc.RrdReader(tmp_path / n).stream())) for n in ("a.rrd", "b.rrd")]
    assert chunks[1] > chunks[0] + 100  # really chunked differently
    assert fingerprint_rrd(tmp_path / "a.rrd") == fingerprint_rrd(tmp_path / "b.rrd")


def test_record_of_kollagens_own_output(kollagen_reference, tmp_path):
    from studio.recording.dataset import record_dataset

    name = "small_three"
    res = record_dataset(kollagen_reference / "outputs" / name, tmp_path / "k.rrd")
    graph = generate(load_synth_config(kollagen_reference / "configs" / f"{name}.json")).graph
    assert res.recording_id == recording_id_for(graph)  # same dataset, same id
    check_recording_matches(tmp_path / "k.rrd", graph)
