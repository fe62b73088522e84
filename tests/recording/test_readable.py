"""Recordings readable at paper scale (issue 27): many inter-agent loop closures drawn as their
density (the segments kept, hidden, in their own entities), one legend that fits eight agents above
the data, and an evaluation panel with every agent, `all` and RPE."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import studio.recording.dataset as dataset_recording
from studio.evaluate import evaluate, write_evaluation_recording
from studio.generator.presets import preset
from studio.io.multig2o import read_multi_g2o
from studio.recording.dataset import DENSITY_CELLS_ACROSS, LEGEND_HEADROOM, closure_density, record_graph
from studio.recording.entities import INTER_LOOP_CLOSURE_DENSITY, TIMELINE_NODE
from studio.synth import load_synth_config, synthesize
from tests.recording.test_recording import read_back

DATA = Path(__file__).resolve().parent.parent / "data" / "configs"
LEFT_TOP = 1  # Rerun's Corner2D.LeftTop as stored


def _blueprint(path: Path) -> dict[tuple[str, str], list]:
    """``{(entity, component): values}`` of the recording's blueprint store."""
    import rerun.chunk as rc

    reader = rc.RrdReader(path)
    out: dict[tuple[str, str], list] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" in name:
                    out.setdefault((str(chunk.entity_path), name), []).extend(batch.column(name).to_pylist())
    return out


def _legends(bp: dict) -> dict[str, tuple[bool, int | None]]:
    """Per view id: (legend visible, corner)."""
    out = {}
    for (entity, comp), values in bp.items():
        if entity.endswith("/PlotLegend") and comp == "PlotLegend:visible":
            view = entity.rsplit("/", 1)[0]
            corner = bp.get((entity, "PlotLegend:corner"), [[None]])[-1][0]
            out[view] = (bool(values[-1][0]), corner)
    return out


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    return synthesize(load_synth_config(DATA / "small3x100.json"), tmp_path_factory.mktemp("small"), rrd=False)


def test_many_inter_agent_closures_are_drawn_as_their_density(small, tmp_path, monkeypatch):
    graph = read_multi_g2o(small.dataset_dir)
    inliers = len(graph.inter)
    assert inliers > 10
    monkeypatch.setattr(dataset_recording, "MANY_INTER_LOOP_CLOSURES", 10)  # small3x100 counts as many
    path = record_graph(graph, tmp_path / "many.rrd", name="small3x100").path
    data = read_back(path)
    ((index, positions),) = data[("/" + INTER_LOOP_CLOSURE_DENSITY, "Points3D:positions")]
    ((_, radii),) = data[("/" + INTER_LOOP_CLOSURE_DENSITY, "Points3D:radii")]
    assert index[TIMELINE_NODE] == max(a.num_poses for a in graph.agents) - 1  # shown where the file opens
    # one disc per occupied cell of the closures' grid; the fullest has a radius of one cell
    g = graph.to_se3()
    offsets = np.concatenate([[0], np.cumsum([a.num_poses for a in g.agents])])
    truth = np.concatenate([a.ground_truth[:, 0:3] for a in g.agents])
    i = g.inter
    mid = 0.5 * (truth[offsets[i.from_agent] + i.from_index] + truth[offsets[i.to_agent] + i.to_index])
    across = float(np.max(np.ptp(mid, axis=0)))
    centres, counts = closure_density(mid, across)
    assert counts.sum() == inliers and len(positions) == len(centres) < inliers
    np.testing.assert_allclose(np.array(positions)[:, 0:2], centres[:, 0:2], rtol=1e-5, atol=1e-4)
    assert max(radii) == pytest.approx(across / DENSITY_CELLS_ACROSS, rel=1e-5)
    # the segments are still there, one entity per pair, hidden by the layout (the eye toggles them)
    pairs = [k for k in data if k[0].startswith("/world/inter_loop_closures/") and k[1] == "LineStrips3D:strips"]
    assert len(pairs) == 3
    bp = _blueprint(path)
    hidden = [v for (e, c), v in bp.items() if e.endswith("/overrides/world/inter_loop_closures/visualizers")]
    assert hidden == [[[False]]]


def test_few_inter_agent_closures_are_segments_in_view(small, tmp_path):
    graph = read_multi_g2o(small.dataset_dir)
    path = record_graph(graph, tmp_path / "few.rrd", name="small3x100").path
    assert not any(k[0] == "/" + INTER_LOOP_CLOSURE_DENSITY for k in read_back(path))
    assert not any("overrides" in e for e, _ in _blueprint(path))


@pytest.fixture(scope="module")
def eight(tmp_path_factory):
    """Eight agents, as Multi3500x8, 60 steps each."""
    base = preset("multi3500x8")
    cfg = dataclasses.replace(base, number_of_steps=60, name="Eight")
    return synthesize(cfg, tmp_path_factory.mktemp("eight"))


def test_one_legend_for_eight_agents_above_the_data(eight):
    bp = _blueprint(eight.rrd_path)
    legends = _legends(bp)
    shown = [v for v, (visible, _) in legends.items() if visible]
    assert len(legends) == 3 and len(shown) == 1  # position error; the other two plots name their series
    (view,) = shown
    assert legends[view][1] == LEFT_TOP
    ((low, high),) = bp[(view + "/ScalarAxis", "ScalarAxis:range")][-1]
    graph = read_multi_g2o(eight.dataset_dir)
    largest = max(float(np.max(np.linalg.norm(a.initial[:, :3] - a.ground_truth[:, :3], axis=1))) for a in graph.agents)
    assert low == 0.0 and high == pytest.approx(LEGEND_HEADROOM * largest)


def test_the_evaluation_panel_lists_every_agent_all_and_rpe(eight, tmp_path):
    ev = evaluate(eight.dataset_dir)
    path = write_evaluation_recording(ev, tmp_path / "ev.rrd")
    ((_, (text,)),) = read_back(path)[("/evaluation/summary", "TextDocument:text")]
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    header, body = rows[0], rows[1:]
    assert "RPE t RMSE" in header and "RPE r RMSE" in header and "APE t mean" in header
    assert [r.split(" | ")[0].strip("| *") for r in body] == [f"agent{k}" for k in range(1, 9)] + ["all"]
    all_cells = [c.strip(" *") for c in body[-1].strip("|").split("|")]
    assert float(all_cells[2]) == pytest.approx(ev.overall.ape_translation_m.mean, abs=5e-5)
    assert float(all_cells[6]) == pytest.approx(ev.overall.rpe_m_translation_m.rmse, abs=5e-5)
    assert max(len(r) for r in rows) < 110  # narrow enough for the panel (the full table is twice as wide)
    bp = _blueprint(path)
    kinds = [v[-1][0] for (e, c), v in bp.items() if c == "ContainerBlueprint:container_kind"]
    from rerun.blueprint.components.container_kind import ContainerKind

    assert ContainerKind.Tabs.value in kinds  # the two plots share one pane as tabs
    legends = _legends(bp)
    assert len(legends) == 2 and all(visible and corner == LEFT_TOP for visible, corner in legends.values())
