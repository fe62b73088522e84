"""studio synth with labelled outliers: outliers.txt is read by the recording and check tools, and the
recording draws them in their own entity."""

from __future__ import annotations

import copy

from studio.check import check
from studio.io.synth_config import parse_synth_config
from studio.recording.dataset import read_outliers
from studio.recording.entities import LOOP_CLOSURES_OUTLIERS
from studio.synth import synthesize
from tests.generator.test_extensions import _small
from tests.recording.test_recording import read_back


def test_synth_outliers_are_recorded_apart_and_flagged_by_check(tmp_path):
    doc = _small(steps=200, studio={"outliers": {"intra_fraction": 0.05, "inter_fraction": 0.05, "seed": 5}})
    res = synthesize(parse_synth_config(copy.deepcopy(doc), name="o"), tmp_path, jobs=1)
    rows = read_outliers(res.dataset_dir / "outliers.txt", res.output.graph)
    assert len(rows) == len(res.outliers.rows) > 0
    data = read_back(res.rrd_path)
    assert len(data[("/" + LOOP_CLOSURES_OUTLIERS, "LineStrips3D:strips")]) == len(rows)
    report = check(res.dataset_dir)
    assert report.listed_outliers == len(rows) and report.listed_flagged == len(rows)
