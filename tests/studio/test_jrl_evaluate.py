"""studio evaluate with a .jrr: jrl's metric summary of a small JRL dataset, worked out by hand, written
as a .jrm; bad results refused in one line with exit 2 and nothing written."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.evaluate import evaluate
from studio.io.jrm import read_jrm
from studio.io.jrr import read_jrr
from studio.io.multig2o import read_multi_g2o
from studio.jrl_evaluate import evaluate_jrr, factor_ids_of_edges, load_dataset_view
from studio.solve import solve
from studio.synth import load_synth_config, synthesize

DATA = Path(__file__).resolve().parent.parent / "data"
runner = CliRunner()
A, B = ord("a") << 56, ord("b") << 56
I3 = [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0]


def pose2(key: int, x: float, y: float, theta: float) -> dict:
    return {"key": key, "type": "Pose2", "x": x, "y": y, "theta": theta}


def between(k1: int, k2: int, x: float, y: float, theta: float) -> dict:
    m = {"type": "Pose2", "x": x, "y": y, "theta": theta}
    return {"type": "BetweenFactorPose2", "key1": k1, "key2": k2, "measurement": m, "covariance": I3}


def prior(k: int, x: float, y: float, theta: float) -> dict:
    m = {"type": "Pose2", "x": x, "y": y, "theta": theta}
    return {"type": "PriorFactorPose2", "key": k, "measurement": m, "covariance": I3}


DATASET = {
    "name": "tiny",
    "robots": [97, 98],
    "measurements": {
        "a": [
            {"stamp": 0, "measurements": [prior(A, 0, 0, 0)]},
            {"stamp": 1, "measurements": [between(A, A + 1, 1, 0, 0)]},
            {"stamp": 2, "measurements": [between(A + 1, B, 0, 1, 0)]},
        ],
        "b": [
            {"stamp": 0, "measurements": [prior(B, 1, 1, 0)]},
            {"stamp": 1, "measurements": [between(B, B + 1, 1, 0, 0)]},
        ],
    },
    # robot a's ground truth holds its copy of b0, which it shares through its closure
    "groundtruth": {
        "a": [pose2(A, 0, 0, 0), pose2(A + 1, 1, 0, 0), pose2(B, 1, 1, 0)],
        "b": [pose2(B, 1, 1, 0), pose2(B + 1, 2, 1, 0)],
    },
    "potential_outlier_factors": {"a": [[2, 0]], "b": [[1, 0]]},
    "outlier_factors": {"a": [[2, 0]], "b": []},
}

RESULTS = {
    "dataset_name": "tiny",
    "method_name": "hand",
    "robots": [97, 98],
    "solutions": {
        # every pose at its ground truth but robot a's copy of b0, turned by 0.3 rad
        "a": [pose2(A, 0, 0, 0), pose2(A + 1, 1, 0, 0), pose2(B, 1, 1, 0.3)],
        "b": [pose2(B, 1, 1, 0), pose2(B + 1, 2, 1, 0)],
    },
    "outliers": {"a": [[2, 0]], "b": []},
}


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    data, res = tmp_path / "tiny.jrl", tmp_path / "run.jrr"
    data.write_text(json.dumps(DATASET))
    res.write_text(json.dumps(RESULTS))
    return data, res


def test_the_metrics_of_a_small_case_equal_the_hand_computation(files):
    data, res = files
    out = runner.invoke(app, ["evaluate", str(data), "--estimate", str(res)])
    assert out.exit_code == 0, out.output
    m = read_jrm(res.with_suffix(".jrm"))
    # positions exact, so the Umeyama fit is the identity; robot a: one of 3 poses 0.3 rad off
    assert m.robot_ate is not None and m.total_ate is not None
    assert m.robot_ate["a"] == pytest.approx((0.0, math.sqrt(0.09 / 3)), abs=1e-12)
    assert m.robot_ate["b"] == pytest.approx((0.0, 0.0), abs=1e-12)
    assert m.total_ate == pytest.approx((0.0, math.sqrt(0.03)), abs=1e-12)
    assert m.joint_aligned_ate == pytest.approx((0.0, 0.0), abs=1e-12)  # own poses only
    # b0 is the one shared variable: a's and b's estimates 0.3 rad apart
    assert m.sve == pytest.approx((0.0, 0.3), abs=1e-12)
    # GTSAM's 0.5 |r|^2 (unit covariances), averaged over the copies of b0 (a's, b's):
    # a1 -> b0: (0.045 + 0) / 2; prior b0: (0.045 + 0) / 2;
    # b0 -> b1 with a's b0: z^-1 b0^-1 b1 = (cos 0.3 - 1, -sin 0.3, -0.3), with b's: 0
    b0_b1 = 0.5 * ((math.cos(0.3) - 1) ** 2 + math.sin(0.3) ** 2 + 0.09) / 2
    assert m.mean_residual == pytest.approx(0.0225 + 0.0225 + b0_b1, abs=1e-12)
    # a rejected its labelled outlier (a true negative), b kept its inlier (a true positive)
    assert m.precision_recall == (1.0, 1.0)
    assert m.robot_precision_recall == {"a": (-1.0, -1.0), "b": (1.0, 1.0)}
    assert "SVE:                0, 0.3" in out.output


def test_partial_results_score_the_poses_each_robot_holds(files):
    data, res = files
    doc = json.loads(res.read_text())
    doc["solutions"]["a"].pop(2)  # robot a never received b0
    res.write_text(json.dumps(doc))
    full = runner.invoke(app, ["evaluate", str(data), "--estimate", str(res)])
    assert full.exit_code == 2 and "partial results score only the poses each robot holds" in full.output
    out = runner.invoke(app, ["evaluate", str(data), "--estimate", str(res), "--partial"])
    assert out.exit_code == 0, out.output
    m = read_jrm(res.with_suffix(".jrm"))
    # jrl's allow_partial_results: a is scored on a0, a1 only (both exact); b0 is b's alone now
    assert m.robot_ate == {"a": (0.0, 0.0), "b": (0.0, 0.0)}
    assert m.sve is not None and all(math.isnan(x) for x in m.sve)
    assert m.mean_residual == pytest.approx(0.0, abs=1e-15)


def test_the_jrm_goes_through_the_output_guard(files, tmp_path: Path):
    data, res = files
    target = tmp_path / "named.jrm"
    assert runner.invoke(app, ["evaluate", str(data), "-e", str(res), "--jrm", str(target)]).exit_code == 0
    again = runner.invoke(app, ["evaluate", str(data), "-e", str(res), "--jrm", str(target)])
    assert again.exit_code == 2 and "--force" in again.output
    assert runner.invoke(app, ["evaluate", str(data), "-e", str(res), "--jrm", str(target), "--force"]).exit_code == 0


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda r: r["solutions"]["a"].pop(2), r"run.jrr: solutions.a: robot 'a' has no estimate of b0"),
        (lambda r: r["solutions"]["b"][1].update(x=float("inf")), r"run.jrr: solutions.b\[1\]: not a finite number"),
        (lambda r: r["solutions"].update(c=[]), "run.jrr: solutions.c: robot 'c' is not in robots"),
        (lambda r: r.update(robots=[97, 98, 99]), r"run.jrr: robots\[2\]: robot 'c' is not in the dataset's robots"),
    ],
)
def test_bad_results_get_one_line_and_exit_2_with_nothing_written(files, edit, message):
    data, res = files
    doc = json.loads(res.read_text())
    edit(doc)
    res.write_text(json.dumps(doc))
    out = runner.invoke(app, ["evaluate", str(data), "--estimate", str(res)])
    assert out.exit_code == 2
    lines = out.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), out.output
    assert re.search(message, lines[0]), lines[0]
    assert not res.with_suffix(".jrm").exists()


def test_factor_ids_of_rejected_edges_follow_the_documents_order():
    doc = {
        "measurements": {
            "a": [
                {"stamp": 0, "measurements": [prior(A, 0, 0, 0), between(A, A + 1, 1, 0, 0)]},
                {"stamp": 1, "measurements": [between(A + 1, B, 0, 1, 0), between(A + 1, B, 0, 1, 0)]},
            ],
            "b": [{"stamp": 0, "measurements": [between(B, A + 1, 0, -1, 0)]}],
        }
    }
    # the pair (a1, b0) rejected twice takes both repeated measurements; (b0, a1) is b's factor
    found = factor_ids_of_edges(doc, np.array([[A + 1, B], [A + 1, B], [B, A + 1]]))
    assert found["a"].tolist() == [[1, 0], [1, 1]] and found["b"].tolist() == [[0, 0]]


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    root = tmp_path_factory.mktemp("jrr")
    small = synthesize(load_synth_config(DATA / "configs" / "small3x100.json"), root, rrd=False, jobs=1)
    solve(small.dataset_dir, root / "est")
    return small.dataset_dir, root / "est" / "small3x100.jrr"


def test_solve_writes_a_jrr_whose_ate_is_evos_aligned_ape(solved, tmp_path):
    dataset, jrr = solved
    res = read_jrr(jrr)
    assert res.robots == ("a", "b", "c") and res.method_name == "gtsam" and res.outliers is None
    scored = evaluate_jrr(dataset, jrr, jrm=tmp_path / "m.jrm")
    m = scored.summary
    assert m.robot_ate is not None and m.joint_aligned_ate is not None
    # jrl's ATE is the RMSE after a rigid Umeyama fit: evo's se3-aligned APE on the same poses
    tum = jrr.parent / "estimate" / "tum"
    joint = evaluate(dataset, estimate=tum, align="se3").overall
    assert m.joint_aligned_ate[0] == pytest.approx(joint.ape_translation_m.rmse, rel=1e-9)
    assert m.joint_aligned_ate[1] == pytest.approx(math.radians(joint.ape_rotation_deg.rmse), rel=1e-9)
    # per robot, over the keys of its ground truth (its own poses, and its copies of shared ones
    # where the dataset's JRL lists them): evo's Umeyama on the same positions
    from evo.core.geometry import umeyama_alignment

    view = load_dataset_view(dataset)
    assert view.groundtruth is not None
    for c, ref, sol in zip("abc", view.groundtruth, res.solutions):
        est = sol.take(ref.keys)[:, 0:3]
        r, t, _ = umeyama_alignment(est.T, ref.poses[:, 0:3].T, False)
        rmse = np.sqrt(np.mean(np.sum((est @ r.T + t - ref.poses[:, 0:3]) ** 2, axis=1)))
        assert m.robot_ate[c][0] == pytest.approx(rmse, rel=1e-9)
    assert m.total_ate == pytest.approx(tuple(map(sum, zip(*m.robot_ate.values()))))
    # each robot also holds the far ends of its inter-robot closures, at the one central estimate
    g = read_multi_g2o(dataset)
    copies = []
    for k, sol in enumerate(res.solutions):
        mine = g.inter.from_agent == k
        far = {(int(a), int(i)) for a, i in zip(g.inter.to_agent[mine], g.inter.to_index[mine])}
        copies.append(int(((sol.keys >> 56) != ord("abc"[k])).sum()))
        assert copies[-1] == len(far)
    assert sum(copies) > 0
    assert m.sve == (0.0, 0.0)  # shared, and in perfect agreement


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["measurements"].update(c=[]), r"tiny.jrl: measurements.c: robot 'c' is not in robots"),
        (
            lambda d: d["measurements"]["a"][1]["measurements"][0].update(covariance=[1.0]),
            r"measurements.a\[1\]"
            r".measurements\[0\].covariance: expected 9 numbers",
        ),
        (
            lambda d: d["measurements"]["b"][1]["measurements"][0].update(key2=-5),
            r"measurements.b\[1\].measurements"
            r"\[0\]: expected GTSAM keys",
        ),
        (lambda d: d["groundtruth"]["b"][0].update(x="1"), r"groundtruth.b\[0\]: not a finite number"),
    ],
)
def test_a_bad_jrl_dataset_is_one_line_naming_the_json_path(files, edit, message):
    data, res = files
    doc = json.loads(data.read_text())
    edit(doc)
    data.write_text(json.dumps(doc))
    out = runner.invoke(app, ["evaluate", str(data), "--estimate", str(res)])
    assert out.exit_code == 2 and len(out.output.strip().splitlines()) == 1
    assert re.search(message, out.output), out.output
    assert not res.with_suffix(".jrm").exists()


def test_the_mean_residual_is_gtsams_error_of_the_jrl_graph(solved):
    """With one estimate per key, jrl's mean residual is GTSAM's NonlinearFactorGraph::error of the
    dataset's JRL factors at the solution: checked with GTSAM itself on the studio's JRL export."""
    gtsam = pytest.importorskip("gtsam")
    from studio.io.jrl import jrl_document

    dataset, jrr = solved
    doc = jrl_document(read_multi_g2o(dataset), name="small3x100")
    graph = gtsam.NonlinearFactorGraph()
    for entries in doc["measurements"].values():
        for entry in entries:
            for f in entry["measurements"]:
                z = f["measurement"]
                w, x, y, q = z["rotation"]
                pose = gtsam.Pose3(gtsam.Rot3.Quaternion(w, x, y, q), np.array(z["translation"]))
                noise = gtsam.noiseModel.Gaussian.Covariance(np.array(f["covariance"]).reshape(6, 6))
                graph.add(gtsam.BetweenFactorPose3(f["key1"], f["key2"], pose, noise))
    values = gtsam.Values()
    for sol in read_jrr(jrr).solutions:
        for key, p in zip(sol.keys.tolist(), sol.poses):
            if not values.exists(key):  # a central solve's copies are its one estimate
                values.insert(key, gtsam.Pose3(gtsam.Rot3.Quaternion(p[6], p[3], p[4], p[5]), p[0:3]))
    ours = evaluate_jrr(dataset, jrr, jrm=jrr.with_name("gtsam-check.jrm")).summary.mean_residual
    assert ours == pytest.approx(graph.error(values), rel=1e-9)


def test_a_single_g2o_dataset_is_one_robot_with_its_edges(tmp_path):
    small = synthesize(load_synth_config(DATA / "configs" / "tiny_three.json"), tmp_path, rrd=False, jobs=1)
    single = small.single_dir / "tiny_three.g2o"  # 2D records, NAME_GT.tum beside it
    res = solve(single, tmp_path / "est")
    m = evaluate_jrr(single, tmp_path / "est" / "tiny_three.jrr").summary
    # a planar between factor's GTSAM 4.2 residual is g2o's EDGE_SE2 error: half the chi2
    assert m.mean_residual == pytest.approx(res.chi2_final / 2, rel=1e-9)
    assert m.robot_ate is not None and m.sve is None  # one robot: no SVE, as jrl
    bare = tmp_path / "bare" / "tiny_three.g2o"
    bare.parent.mkdir()
    bare.write_bytes(single.read_bytes())
    m = evaluate_jrr(bare, tmp_path / "est" / "tiny_three.jrr", jrm=tmp_path / "bare.jrm").summary
    assert m.robot_ate is None and m.mean_residual == pytest.approx(res.chi2_final / 2, rel=1e-9)
