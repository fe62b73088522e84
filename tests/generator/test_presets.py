"""The two datasets of the kollagen paper, from the built-in presets."""

from __future__ import annotations

import json

import pytest

from studio.generator.kollagen import generate
from studio.generator.presets import preset, preset_names
from studio.io.synth_config import parse_synth_config


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "poses", "odometry", "total"),
    [("multi3500x8", 8 * 3501, 28000, 67645), ("multi10000x5", 5 * 10001, 50000, 76134)],
)
def test_paper_datasets_have_the_papers_constraint_counts(name, poses, odometry, total):
    graph = generate(preset(name)).graph
    counts = graph.edge_counts()
    assert graph.num_poses == poses
    assert counts["odometry"] == odometry
    assert sum(counts.values()) == total


@pytest.mark.parametrize("name,file", [("multi3500x8", "Multi3500x8"), ("multi10000x5", "Multi10000x5")])
def test_presets_equal_the_papers_json(kollagen_reference, name, file):
    data = json.loads((kollagen_reference / "configs" / f"{file}.json").read_text())
    assert parse_synth_config(data, name=file) == preset(file)
    assert preset(name).name == name


def test_preset_lookup():
    assert preset_names() == ["cube3d", "multi10000x5", "multi3500x8", "multi3500x8_outliers"]
    assert preset("Multi3500x8").name == "Multi3500x8"
    assert preset("multi3500x8").name == "multi3500x8"
    with pytest.raises(KeyError):
        preset("multi1x1")
