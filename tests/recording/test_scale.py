"""Recordings that read at scale: per-pair inter-agent entities, outliers apart, styles, pose kind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.core.errors import FormatError
from studio.recording.dataset import (
    MANY_INTER_LOOP_CLOSURES,
    inter_style,
    read_outliers,
    record_dataset,
)
from studio.recording.entities import LOOP_CLOSURES_OUTLIERS
from tests.recording.test_recording import read_back

TRAJECTORIES = Path(__file__).resolve().parent.parent / "data" / "trajectories"


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    from studio.convert import ConvertConfig, convert
    from studio.converters.build import GraphOptions

    inputs = tuple(str(p) for p in sorted(TRAJECTORIES.glob("*.tum")))
    cfg = ConvertConfig("tum", inputs, (), GraphOptions(seed=7, outlier_fraction=0.2))
    return convert(cfg, tmp_path_factory.mktemp("conv") / "ds")


def _strips(data: dict, prefix: str) -> int:
    return sum(
        len(rows)
        for key, rows in data.items()
        if len(key) == 2 and str(key[0]).startswith(prefix) and key[1] == "LineStrips3D:strips"
    )


def test_outliers_have_their_own_entity_and_are_not_drawn_as_inliers(converted, tmp_path):
    rows = read_outliers(converted.dataset_dir / "outliers.txt", converted.build.graph)
    assert len(rows) == converted.build.candidates["outliers"] > 0
    counts = converted.build.graph.edge_counts()
    for path in (converted.rrd_path, record_dataset(converted.dataset_dir, tmp_path / "again.rrd").path):
        data = read_back(path)
        assert len(data[("/" + LOOP_CLOSURES_OUTLIERS, "LineStrips3D:strips")]) == len(rows)
        inliers = _strips(data, "/world/inter_loop_closures/") + sum(
            _strips(data, f"/world/{a.name}/loop_closures") for a in converted.build.graph.agents
        )
        assert inliers == counts["intra_loop_closures"] + counts["inter_loop_closures"] - len(rows)


def test_bad_outliers_file_names_the_line(converted, tmp_path):
    bad = tmp_path / "outliers.txt"
    bad.write_text("# header\n1 0 2 3\n1 zero 2 3\n")
    with pytest.raises(FormatError, match=r"outliers.txt:3: expected four integers"):
        read_outliers(bad, converted.build.graph)
    bad.write_text("9 0 1 0\n")
    with pytest.raises(FormatError, match=r"outliers.txt:1: agent 9 is not in 1..3"):
        read_outliers(bad, converted.build.graph)


def test_many_inter_agent_loop_closures_are_thinner_and_fainter():
    (_, _, _, few_alpha), few_radius = inter_style(MANY_INTER_LOOP_CLOSURES)
    (_, _, _, many_alpha), many_radius = inter_style(MANY_INTER_LOOP_CLOSURES + 1)
    assert many_alpha < few_alpha and abs(many_radius) < abs(few_radius)


def test_estimate_is_drawn_thinner_and_fainter_than_ground_truth(converted):
    data = read_back(converted.rrd_path)
    name = converted.build.graph.agents[0].name
    ((_, gt_colour),) = data[(f"/world/{name}/ground_truth", "LineStrips3D:colors")]
    ((_, est_colour),) = data[(f"/world/{name}/initial", "LineStrips3D:colors")]
    ((_, gt_radius),) = data[(f"/world/{name}/ground_truth", "LineStrips3D:radii")]
    ((_, est_radius),) = data[(f"/world/{name}/initial", "LineStrips3D:radii")]
    # same hue (RGB), the estimate translucent: colours are packed 0xRRGGBBAA
    assert gt_colour[0] >> 8 == est_colour[0] >> 8
    assert (est_colour[0] & 0xFF) < (gt_colour[0] & 0xFF) == 0xFF
    assert abs(est_radius[0]) < abs(gt_radius[0])
    assert np.isfinite(gt_radius[0])
