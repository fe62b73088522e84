"""studio check: consistent data passes, kollagen's Exact odometry and mis-scaled or outlier-ridden
data are flagged with their factor."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.check import check, format_check
from studio.cli import app
from studio.convert import ConvertConfig, convert
from studio.converters.build import GraphOptions
from studio.io.multig2o import read_multi_g2o, write_multi_g2o
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"
TRAJ = [str(DATA / "trajectories" / f"{n}.tum") for n in ("alpha", "bob", "carol")]
runner = CliRunner()


def _converted(root: Path, name: str, **options) -> Path:
    cfg = ConvertConfig("tum", tuple(TRAJ), (), GraphOptions(seed=3, **options))
    return convert(cfg, root / name, rrd=False).dataset_dir


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    return _converted(tmp_path_factory.mktemp("check"), "clean")


def test_a_dataset_whose_noise_follows_its_information_is_consistent(converted):
    report = check(converted)
    assert report.kind.value == "SE3" and report.convention == "g2o"
    for name in ("odometry", "intra", "inter"):
        c = report.summary(name)
        assert c.edges > 30
        assert c.verdicts["total"] == "consistent", format_check(report)
        assert 0.75 < c.total.factor < 1.3
        assert 0.7 < c.rotation.factor < 1.4  # rotation information in g2o's quaternion convention
    assert len(report.outliers) == 0


def test_the_rotation_convention_changes_the_rotation_factor_fourfold(converted):
    g2o = check(converted).summary("odometry").rotation
    rotvec = check(converted, convention="rotvec").summary("odometry").rotation
    assert rotvec.factor / g2o.factor == pytest.approx(4.0, rel=0.02)
    assert check(converted, convention="rotvec").summary("odometry").verdicts["rotation"].startswith("over-confident")


def test_information_four_times_too_small_is_under_confident(converted, tmp_path):
    graph = read_multi_g2o(converted)
    agents = tuple(
        dataclasses.replace(
            a, odometry=dataclasses.replace(a.odometry, information_upper=a.odometry.information_upper / 4)
        )
        for a in graph.agents
    )
    scaled = dataclasses.replace(graph, agents=agents)
    (tmp_path / "scaled").mkdir()
    write_multi_g2o(scaled, tmp_path / "scaled", precision="full")
    c = check(tmp_path / "scaled").summary("odometry")
    assert c.verdicts["total"].startswith("under-confident x 0.2")
    assert c.total.factor == pytest.approx(check(converted).summary("odometry").total.factor / 4, rel=1e-6)


def test_planted_outliers_are_flagged_and_matched_against_outliers_txt(tmp_path):
    ds = _converted(tmp_path, "outliers", outlier_fraction=0.05)
    report = check(ds)
    assert report.listed_outliers and report.listed_outliers >= 4
    assert report.listed_flagged == report.listed_outliers
    assert len(report.outliers) == report.listed_outliers  # and nothing else
    # the rare candidates are left out of the class sums, which stay consistent
    inter = report.summary("inter")
    assert inter.excluded > 0 and inter.verdicts["total"] == "consistent"


def test_kollagen_exact_odometry_information_is_flagged_over_confident(tmp_path):
    cfg = load_synth_config(DATA / "configs" / "small3x100.json")
    exact = dataclasses.replace(cfg, exact_information_matrix=True, name="exact")
    res = synthesize(exact, tmp_path, rrd=False, jobs=1)
    single = res.single_dir / "exact.g2o"
    report = check(single)
    odo = report.summary("odometry")
    assert odo.verdicts["total"].startswith("over-confident")
    assert odo.total.factor > 5
    assert report.summary("loop closures").verdicts["total"] == "consistent"
    # the multi-g2o folder holds kollagen's diagonal information: the same edges are not over-confident
    assert not check(res.dataset_dir).summary("odometry").verdicts["total"].startswith("over-confident")


def test_cli_check_json_and_errors(converted, tmp_path):
    res = runner.invoke(app, ["check", str(converted), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert {c["class"] for c in data["classes"]} == {"odometry", "intra", "inter"}
    assert data["rotation_convention"] == "g2o"
    table = runner.invoke(app, ["check", str(converted), "--per-agent"])
    assert table.exit_code == 0 and "alpha" in table.output and "consistent" in table.output
    (tmp_path / "nogt").mkdir()
    g = read_multi_g2o(converted)
    write_multi_g2o(
        dataclasses.replace(g, agents=tuple(dataclasses.replace(a, ground_truth=None) for a in g.agents)),
        tmp_path / "nogt",
    )
    # without ground truth (distributed-mapper's examples): checked at the agents' own poses, said so
    own = runner.invoke(app, ["check", str(tmp_path / "nogt"), "--json"])
    assert own.exit_code == 0, own.output
    report = json.loads(own.output)
    assert any(n.startswith("no ground truth for 3 of 3 agents (the first: alpha)") for n in report["notes"])
    odometry = next(c for c in report["classes"] if c["class"] == "odometry")
    assert odometry["total"]["factor"] < 1e-9  # the initial estimate is the odometry's dead reckoning
    assert np.isfinite([c["total"]["factor"] for c in data["classes"]]).all()


def rotate_into_g2o_error_frame(info_upper: np.ndarray, theta_z: np.ndarray) -> np.ndarray:
    """Omega' = D^T Omega D, D = blkdiag(R(theta_z), 1): planar information given in the frame of the
    edge's start pose (kollagen's derivation) moved into the frame of g2o's EDGE_SE2 error (the measured
    end pose). Upper triangles ``I11 I12 I13 I22 I23 I33``."""
    i11, i12, i13, i22, i23, i33 = info_upper.T
    c, s = np.cos(theta_z), np.sin(theta_z)
    return np.column_stack(
        [
            c * c * i11 + 2 * c * s * i12 + s * s * i22,
            -c * s * i11 + (c * c - s * s) * i12 + c * s * i22,
            c * i13 + s * i23,
            s * s * i11 - 2 * c * s * i12 + c * c * i22,
            -s * i13 + c * i23,
            i33,
        ]
    )


def test_kollagen_exact_information_rotated_into_g2os_error_frame_is_consistent(tmp_path):
    """The finding behind the flag: rotating each Exact odometry information by its measured heading
    change makes the same edges consistent; the opposite rotation does not."""
    from studio.io.g2o import read_g2o, write_g2o

    cfg = load_synth_config(DATA / "configs" / "small3x100.json")
    # 1000 steps: the rotated Exact model is nearly singular (lateral position and heading almost fully
    # correlated), its per-edge chi2 is heavy-tailed, so a few hundred edges give a noisy factor
    exact = dataclasses.replace(cfg, exact_information_matrix=True, name="exact", number_of_steps=1000)
    res = synthesize(exact, tmp_path, rrd=False, jobs=1)
    doc = read_g2o(res.single_dir / "exact.g2o")
    odo = np.abs(doc.edge_to - doc.edge_from) == 1
    theta_z = doc.edge_measurements[odo, 2]
    assert np.count_nonzero(np.abs(theta_z) > 1.0) >= 10  # there are turning edges to fix

    def checked(sign: float) -> object:
        info = doc.edge_information_upper.copy()
        info[odo] = rotate_into_g2o_error_frame(info[odo], sign * theta_z)
        folder = tmp_path / f"rotated{sign:+.0f}"
        folder.mkdir()
        write_g2o(folder / "exact.g2o", dataclasses.replace(doc, edge_information_upper=info))
        (folder / "exact_GT.tum").write_bytes((res.single_dir / "exact_GT.tum").read_bytes())
        return check(folder / "exact.g2o").summary("odometry")

    fixed = checked(+1.0)
    assert fixed.verdicts["total"] == "consistent", fixed.verdicts
    assert 0.9 < fixed.total.factor < 1.1
    assert fixed.excluded < 0.01 * fixed.edges
    as_written = check(res.single_dir / "exact.g2o").summary("odometry")
    assert as_written.total.factor > 20 * fixed.total.factor
    # the opposite rotation leaves the quarter turns wrong: hundreds of them become outlier candidates
    wrong = checked(-1.0)
    assert wrong.excluded > 0.05 * wrong.edges or wrong.verdicts["total"].startswith("over-confident")
