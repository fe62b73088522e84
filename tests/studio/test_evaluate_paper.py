"""The kollagen paper's odometry column (Tables I and II), from the files `studio synth` writes.

APE, translation part, unaligned, mean over every pose of every agent (the first included), of the
initial estimate (dead reckoning) read back from the multi-g2o folder (3D records, kollagen's default).
"""

from __future__ import annotations

import pytest

from studio.evaluate import evaluate
from studio.generator.presets import preset
from studio.synth import synthesize


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, poses, odometry_ape",
    [
        ("multi3500x8", 8 * 3501, "14.883697"),
        ("multi10000x5", 5 * 10001, "17.427713"),
    ],
)
def test_paper_odometry_ape(tmp_path, name, poses, odometry_ape):
    res = synthesize(preset(name), tmp_path)
    ev = evaluate(res.dataset_dir)
    assert ev.overall.poses == poses
    assert f"{ev.overall.ape_translation_m.mean:.6f}" == odometry_ape
    # The same figure from kollagen's single-file view (2D records, agents concatenated) as the estimate.
    single = evaluate(res.dataset_dir, estimate=res.single_dir / f"{res.config.name}.g2o")
    assert single.overall.ape_translation_m.mean == ev.overall.ape_translation_m.mean


def test_kollagen_reference_dataset_scores_like_ours(kollagen_reference, tmp_path):
    """kollagen's own multi-g2o folder is a valid DATASET and gives our synth's numbers."""
    from studio.synth import load_synth_config

    theirs = evaluate(kollagen_reference / "outputs" / "small_three")
    ours = evaluate(
        synthesize(load_synth_config(kollagen_reference / "configs" / "small_three.json"), tmp_path).dataset_dir
    )
    assert theirs.to_dict()["agents"] == ours.to_dict()["agents"]
    assert theirs.overall.ape_translation_m.mean > 0
