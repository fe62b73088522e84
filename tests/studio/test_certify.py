"""``studio check --certify ESTIMATE`` and :func:`studio.certify.certify` on a small single g2o the
test writes: SE-Sync's certified solve is certified, a perturbed estimate is not, and an estimate
that misses poses, holds non-finite values or belongs to another graph is one line, exit 2."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.certify import certify
from studio.cli import app
from studio.core.model import PoseKind
from studio.io.g2o import G2oDocument, read_g2o, write_g2o
from tests.solvers.test_solvers import make_problem

pytest.importorskip("pymanopt")
runner = CliRunner()


def _noisy_planar_g2o(path):
    p, gt = make_problem(PoseKind.SE2, n=30, closures=10)[:2]
    z = p.measurements + np.random.default_rng(4).normal(0, 0.05, p.measurements.shape)
    write_g2o(
        path, G2oDocument(PoseKind.SE2, np.arange(len(gt)), p.initial, p.edge_from, p.edge_to, z, p.information_upper)
    )
    return path


def _vertices(path, poses, kind=PoseKind.SE2):
    write_g2o(
        path, G2oDocument(kind, np.arange(len(poses)), poses, *(np.zeros((0,) + s) for s in ((), (), (3,), (6,))))
    )
    return path


def test_the_certified_solve_is_certified_and_a_perturbed_one_is_not(tmp_path):
    dataset = _noisy_planar_g2o(tmp_path / "ring.g2o")
    res = runner.invoke(app, ["solve", str(dataset), "-o", str(tmp_path / "solved"), "--method", "sesync"])
    assert res.exit_code == 0, res.output
    notes = json.loads((tmp_path / "solved" / "solve.json").read_text())["notes"]
    assert notes["certified"] is True and notes["staircase"][0]["rank"] == 2
    res = runner.invoke(app, ["check", str(dataset), "--certify", str(tmp_path / "solved"), "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads(res.output)
    assert report["certified"] is True and report["verdict"] == "certified globally optimal"
    assert report["sesync_f"] == pytest.approx(notes["sesync_f"], rel=1e-9)
    solved = read_g2o(tmp_path / "solved" / "ring.g2o", edges=False).vertex_poses
    bad = solved.copy()
    bad[:, 2] += np.random.default_rng(5).normal(0, 0.2, len(bad))
    cert = certify(dataset, _vertices(tmp_path / "bad.g2o", bad))
    assert not cert.certified
    assert cert.objective > notes["sesync_f"]
    assert cert.lower_bound <= notes["sesync_f"] * (1 + 1e-9)  # a true lower bound on the optimum
    assert cert.verdict().startswith("not certified, at most")


def test_bad_estimates_are_one_line_naming_the_file(tmp_path):
    dataset = _noisy_planar_g2o(tmp_path / "ring.g2o")
    poses = read_g2o(dataset, edges=False).vertex_poses
    cases = {
        "short.g2o": _vertices(tmp_path / "short.g2o", poses[:-3]),
        "spatial.g2o": _vertices(
            tmp_path / "spatial.g2o",
            np.column_stack([poses[:, :2], np.zeros((len(poses), 4)), np.ones(len(poses))]),
            PoseKind.SE3,
        ),
    }
    nan = tmp_path / "nan.g2o"
    nan.write_text("".join(f"VERTEX_SE2 {k} {'nan' if k == 3 else 0.0} 0 0\n" for k in range(len(poses))))
    cases["nan.g2o"] = nan
    for name, path in cases.items():
        res = runner.invoke(app, ["check", str(dataset), "--certify", str(path)])
        assert res.exit_code == 2, (name, res.output)
        lines = res.output.strip().splitlines()
        assert len(lines) == 1 and name in lines[0] and "Traceback" not in res.output, (name, res.output)


@pytest.mark.parametrize("method", ["gtsam", "sesync"])
def test_a_noiseless_graph_solves_without_warning_lines(tmp_path, method):
    """At f = 0 pymanopt's trust-region ratio is 0/0; its RuntimeWarning must not reach the user."""
    path = tmp_path / "exact.g2o"
    path.write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
        "EDGE_SE2 0 1 1 0 0 100 0 0 100 0 100\nEDGE_SE2 1 2 1 0 0 100 0 0 100 0 100\n"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning that would be printed fails the run
        res = runner.invoke(app, ["solve", str(path), "-o", str(tmp_path / "out"), "--method", method])
    assert res.exit_code == 0, (res.stderr, res.exception)
    assert res.stderr == "", res.stderr
