"""SE-Sync's published optima on SE-Sync's own benchmark files (Rosen et al., IJRR 2019, Tables 1-2).

Every ``*.g2o`` under ``$STUDIO_REAL_DATA`` whose name is one of SE-Sync's benchmarks (its
``data/`` folder, DPGO's copies of the same files) is solved with ``studio solve --method sesync``
as it ships (edge-only files, cubicle's few-decimal quaternions, ais2klinik's chain gap); the
answer must be certified and its ``f`` must equal the published f* to four significant digits.
Without ``$STUDIO_REAL_DATA`` the tests are skipped.

manhattan is the one exception: the published f* is 6.432e3, but SE-Sync's own C++ on its own
``data/manhattan.g2o`` (unchanged since 2016 but for a trailing newline) prints F(x) = 6431.39,
6.431e3 to four digits, as the studio finds; the only other copy in SE-Sync's history
(``data/2D/m3500.g2o``, isotropic information 44.72) has f* 204.94. The test holds the studio to
SE-Sync's own value there (docs/solve.md says so).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from studio.cli import app

runner = CliRunner()

#: f* to four significant digits, by file stem (SE-Sync's table calls parking-garage "garage").
PUBLISHED = {
    "CSAIL": 3.170e1,
    "intel": 5.235e1,
    "manhattan": 6.431e3,  # published 6.432e3; SE-Sync's own binary prints 6431.39 on this file
    "city10000": 6.386e2,
    "sphere2500": 1.687e3,
    "parking-garage": 1.263e0,
    "torus3D": 2.423e4,
    "cubicle": 7.171e2,
    "ais2klinik": 1.885e2,
}
#: edges of SE-Sync's copy of each file (its tables' m): DPGO's CSAIL.g2o lacks the closure 323 -> 855
#: (f* 31.4703, SE-Sync's C++ agrees), another graph, which is not held to the table
EDGES = {
    "CSAIL": 1172,
    "intel": 2512,
    "manhattan": 5453,
    "city10000": 20687,
    "sphere2500": 4949,
    "parking-garage": 6275,
    "torus3D": 9048,
    "cubicle": 16869,
    "ais2klinik": 16727,
}
#: files that take more than a few seconds on a loaded 2-core machine
SLOW = {"city10000", "sphere2500", "parking-garage", "torus3D", "cubicle", "ais2klinik"}


def _real_files(stem: str) -> list[Path]:
    root = os.environ.get("STUDIO_REAL_DATA")
    if not root:
        return []
    files = sorted(Path(root).rglob(f"{stem}.g2o"))
    return [p for p in files if sum(line.startswith("EDGE") for line in p.open()) == EDGES[stem]]


def _cases() -> list[object]:
    return [pytest.param(stem, marks=[pytest.mark.slow] if stem in SLOW else [], id=stem) for stem in PUBLISHED]


@pytest.mark.skipif(not os.environ.get("STUDIO_REAL_DATA"), reason="STUDIO_REAL_DATA names no real data folder")
@pytest.mark.parametrize("stem", _cases())
def test_the_certified_solve_reproduces_se_syncs_published_optimum(stem, tmp_path):
    files = _real_files(stem)
    if not files:
        pytest.skip(f"no {stem}.g2o under {os.environ['STUDIO_REAL_DATA']}")
    for n, path in enumerate(files):
        out = tmp_path / str(n)
        res = runner.invoke(app, ["solve", str(path), "-o", str(out), "--method", "sesync"])
        assert res.exit_code == 0, f"{path}: {res.output}"
        notes = json.loads((out / "solve.json").read_text())["notes"]
        assert notes["certified"] is True, f"{path}: {notes['verdict']}"
        assert notes["verdict"].startswith("certified globally optimal"), path
        assert float(f"{notes['sesync_f']:.4g}") == PUBLISHED[stem], f"{path}: f = {notes['sesync_f']}"
