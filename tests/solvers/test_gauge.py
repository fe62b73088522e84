"""The gauge (studio/solvers/gauge.py) on files in the layouts the field ships: a COSMO-Bench JRL whose
robots are each held by a ``PriorFactorPose3`` and share no edge, Kimera-RPGO's ``ordered.g2o`` with
Symbol vertices no edge reaches, and Kimera-RPGO's ``robot_a.g2o``/``robot_b.g2o`` with no edge
between them. Each piece is solved as it would be alone: by its priors where it has them, else held
at its first pose; an isolated vertex keeps its value."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from studio.cli import app
from studio.core.outliers import outlier_scores
from studio.io.g2o import read_g2o
from studio.io.multig2o import read_multi_g2o
from tests.converters.jrl_files import PRIOR_SIGMAS, cosmo_team, key, write_cosmo_jrl

pytest.importorskip("gtsam")

runner = CliRunner()


def _run(*args: object) -> str:
    r = runner.invoke(app, [*map(str, args)])
    assert r.exit_code == 0, r.output
    return r.output


# ---------------------------------------------------------------- COSMO: priors hold each robot


def _without_inter_robot_closures(doc: dict) -> dict:
    """The COSMO-layout document with every factor between two robots left out (and its FactorIds,
    and the copies of other robots' poses in each robot's values): two robots sharing no edge."""
    for r, entries in doc["measurements"].items():
        gone = []
        for e, entry in enumerate(entries):
            keep = []
            for m, f in enumerate(entry["measurements"]):
                if f["type"] == "BetweenFactorPose3" and f["key1"] >> 56 != f["key2"] >> 56:
                    gone.append([e, m])
                else:
                    keep.append(f)
            entry["measurements"] = keep
        for section in ("potential_outlier_factors", "outlier_factors"):
            doc[section][r] = [fid for fid in doc[section][r] if fid not in gone]
        for section in ("groundtruth", "initialization"):
            doc[section][r] = [v for v in doc[section][r] if v["key"] >> 56 == ord(r)]
    return doc


def _one_robot(doc: dict, robot: str) -> dict:
    out = {k: ({robot: v[robot]} if isinstance(v, dict) else v) for k, v in doc.items()}
    out["robots"] = [ord(robot)]
    return out


@pytest.fixture(scope="module")
def cosmo_apart(tmp_path_factory):
    root = tmp_path_factory.mktemp("cosmo")
    doc, team = cosmo_team()
    doc = _without_inter_robot_closures(doc)
    write_cosmo_jrl(root / "apart.jrl", doc)
    _run("convert", "jrl", root / "apart.jrl", "-o", root / "apart", "--no-rrd", "-q")
    for r in ("a", "b"):
        write_cosmo_jrl(root / f"{r}.jrl", _one_robot(doc, r))
        _run("convert", "jrl", root / f"{r}.jrl", "-o", root / r, "--no-rrd", "-q")
    return root, team


def test_robots_sharing_no_edge_are_held_by_their_priors(cosmo_apart):
    root, team = cosmo_apart
    out = _run("solve", root / "apart", "-o", root / "solved")
    assert "gauge: 2 pieces, 2 priors; no anchor" in out
    report = json.loads((root / "solved" / "solve.json").read_text())
    assert report["gauge"]["pieces"] == 2 and report["gauge"]["anchored_vertices"] == []
    est = read_multi_g2o(root / "solved" / "estimate", edges=False)
    initial = read_multi_g2o(root / "apart", edges=False)
    sigma_t, sigma_r = PRIOR_SIGMAS[3], PRIOR_SIGMAS[0]
    for k, r in enumerate(("a", "b")):
        first = est.agents[k].initial[0]
        prior = team.truth[r][0]
        # the first pose lies within 3 sigma of its prior, translation and rotation
        assert np.linalg.norm(first[0:3] - prior[0:3]) < 3 * sigma_t * np.sqrt(3)
        angle = (Rotation.from_quat(first[3:7]).inv() * Rotation.from_quat(prior[3:7])).magnitude()
        assert angle < 3 * sigma_r * np.sqrt(3)
        # and the prior moved it: the dataset's initial value of it (dead reckoning) is off by far more
        assert np.linalg.norm(initial.agents[k].initial[0, 0:3] - prior[0:3]) > 100 * sigma_t


def test_each_robot_solved_with_its_prior_alone_gives_the_same_estimate(cosmo_apart):
    root, _ = cosmo_apart
    joint = root / "joint"
    _run("solve", root / "apart", "-o", joint)
    est = read_multi_g2o(joint / "estimate", edges=False)
    for k, r in enumerate(("a", "b")):
        _run("solve", root / r, "-o", root / f"{r}-solved")
        alone = read_multi_g2o(root / f"{r}-solved" / "estimate", edges=False).agents[0].initial
        np.testing.assert_allclose(est.agents[k].initial, alone, atol=1e-7)


def test_gnc_scores_its_rejections_against_the_labels(cosmo_apart):
    root, team = cosmo_apart
    out = _run("solve", root / "apart", "-o", root / "gnc", "-m", "gnc")
    report = json.loads((root / "gnc" / "solve.json").read_text())
    # the labelled intra-robot outlier a7 -> a1 is the only labelled one left, and GNC rejects it
    assert report["rejected_loop_closures"] == [[0, 7, 0, 1]]
    assert report["outliers"] == {
        "rejected": 1,
        "labelled": 1,
        "rejected_labelled": 1,
        "precision": 1.0,
        "recall": 1.0,
    }
    assert "labelled outliers: 1 of 1 rejected; precision 1.000, recall 1.000" in out
    assert ("a", key("a", 7), key("a", 1), True) in team.closures


def test_outlier_scores_count_a_closure_whichever_way_it_is_written():
    rejected = np.array([[0, 7, 0, 1], [1, 2, 0, 5], [0, 3, 1, 3]])
    labelled = np.array([[0, 1, 0, 7], [1, 4, 1, 0]])
    assert outlier_scores(rejected, labelled) == {
        "rejected": 3,
        "labelled": 2,
        "rejected_labelled": 1,
        "precision": 1 / 3,
        "recall": 0.5,
    }
    assert outlier_scores(np.zeros((0, 4)), labelled)["precision"] is None


# ---------------------------------------------------------------- Kimera-RPGO: pieces held at their first pose

_INFO = "100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400"


def _quat6(rotvec: np.ndarray) -> str:
    return " ".join(f"{x:.6f}" for x in Rotation.from_rotvec(rotvec).as_quat())


def _robot(prefix: str | None, n: int, seed: int, start: np.ndarray) -> list[str]:
    """A robot's graph in Kimera-RPGO's layout (six decimals, Symbol keys with ``prefix``): a noisy
    3D walk round a loop, its odometry and two loop closures, all drawn with the same noise."""
    rng = np.random.default_rng(seed)
    ids = [(ord(prefix) << 56 | i) if prefix else i for i in range(n)]
    rot = [Rotation.from_rotvec(start[3:])]
    pos = [start[:3]]
    for _ in range(n - 1):
        rot.append(rot[-1] * Rotation.from_rotvec([0.02, -0.01, 2 * np.pi / n]))
        pos.append(pos[-1] + rot[-2].apply([1.0, 0.0, 0.05]))
    lines = [
        f"VERTEX_SE3:QUAT {ids[i]} {' '.join(f'{x:.6f}' for x in pos[i])} {_quat6(rot[i].as_rotvec())}"
        for i in range(n)
    ]
    pairs = [(i, i + 1) for i in range(n - 1)] + [(n - 1, 0), (n - 2, 1)]
    for i, j in pairs:
        t = rot[i].inv().apply(pos[j] - pos[i]) + rng.normal(0, 0.05, 3)
        r = (rot[i].inv() * rot[j]).as_rotvec() + rng.normal(0, 0.02, 3)
        lines.append(f"EDGE_SE3:QUAT {ids[i]} {ids[j]} {' '.join(f'{x:.6f}' for x in t)} {_quat6(r)} {_INFO}")
    return lines


def _vertices(path: Path) -> dict[int, np.ndarray]:
    doc = read_g2o(path, edges=False)
    return dict(zip(doc.vertex_ids.tolist(), doc.vertex_poses))


def test_vertices_no_edge_reaches_keep_their_values(tmp_path):
    """ordered.g2o's layout: a graph, then three Symbol 'u' vertices no edge reaches."""
    graph = _robot(None, 12, 1, np.zeros(6))
    lonely = [
        f"VERTEX_SE3:QUAT {ord('u') << 56 | k} {k}.000000 5.000000 1.000000 {_quat6(np.array([0, 0, k]))}"
        for k in range(3)
    ]
    (tmp_path / "alone.g2o").write_text("\n".join(graph) + "\n")
    (tmp_path / "ordered.g2o").write_text("\n".join(graph[:12] + lonely + graph[12:]) + "\n")
    out = _run("solve", tmp_path / "ordered.g2o", "-o", tmp_path / "s")
    assert "gauge: 4 pieces, 0 priors; held at their first pose (no prior reaches them): vertex 0, " in out
    assert "3 isolated vertices keep their initial values" in out
    report = json.loads((tmp_path / "s" / "solve.json").read_text())["gauge"]
    assert report["pieces"] == 4 and report["isolated_vertices"] == 3 and report["anchored_vertices"] == [0, 12, 13, 14]
    _run("solve", tmp_path / "alone.g2o", "-o", tmp_path / "a")
    est, alone, given = (
        _vertices(p) for p in (tmp_path / "s/ordered.g2o", tmp_path / "a/alone.g2o", tmp_path / "ordered.g2o")
    )
    for v, pose in given.items():
        if v >> 56 == ord("u"):
            np.testing.assert_allclose(est[v], pose, rtol=0, atol=1e-15)  # held (to GTSAM's rotation matrix)
        else:
            np.testing.assert_allclose(est[v], alone[v], atol=1e-9)
    assert not np.allclose(est[5], given[5], atol=1e-3)  # the graph itself was optimized
    # check reads it too
    _run("check", tmp_path / "ordered.g2o")


def test_two_robots_with_no_shared_edge_are_each_held_at_their_first_pose(tmp_path):
    """Kimera-RPGO's robot_a.g2o and robot_b.g2o, as ``studio convert symbols`` reads them."""
    folder = tmp_path / "data"
    folder.mkdir()
    robots = {"a": _robot("a", 10, 2, np.zeros(6)), "b": _robot("b", 8, 3, np.array([4.0, -3.0, 0.5, 0.0, 0.0, 1.0]))}
    for r, lines in robots.items():
        (folder / f"robot_{r}.g2o").write_text("\n".join(lines) + "\n")
    _run("convert", "symbols", folder, "-o", tmp_path / "ds", "--no-rrd", "-q")
    out = _run("solve", tmp_path / "ds", "-o", tmp_path / "s")
    assert "gauge: 2 pieces, 0 priors; held at their first pose (no prior reaches them): a vertex 0, b vertex 0" in out
    est = read_multi_g2o(tmp_path / "s" / "estimate", edges=False)
    given = read_multi_g2o(tmp_path / "ds", edges=False)
    for k, r in enumerate(("a", "b")):
        np.testing.assert_allclose(est.agents[k].initial[0], given.agents[k].initial[0], rtol=0, atol=1e-15)
        _run("solve", folder / f"robot_{r}.g2o", "-o", tmp_path / r)
        alone = read_g2o(tmp_path / r / f"robot_{r}.g2o", edges=False)
        # the file alone is one piece, where the default also runs Gauss-Newton from SE-Sync's
        # certified start: both runs stop at Gauss-Newton's relative tolerance, equal to a micrometre
        np.testing.assert_allclose(
            est.agents[k].initial, alone.vertex_poses[np.argsort(alone.vertex_ids)], rtol=0, atol=1e-6
        )
    _run("check", tmp_path / "ds")
    # a method that holds one anchor alone still refuses it, in one line
    r = runner.invoke(app, ["solve", str(tmp_path / "ds"), "-o", str(tmp_path / "g"), "-m", "g2o"])
    assert r.exit_code == 2 and "the graph is not connected" in r.output


def test_check_scores_the_priors_at_the_ground_truth(cosmo_apart, tmp_path):
    """studio check reads the priors as measurements of the first poses from the origin: one class."""
    import shutil

    from studio.check import check

    root, _ = cosmo_apart
    ds = tmp_path / "ds"
    shutil.copytree(root / "apart", ds)
    report = check(ds)
    assert report.summary("priors").edges == 2 and report.summary("priors").total.chi2 < 1e-12
    lines = (ds / "priors.txt").read_text().splitlines()
    fields = lines[-1].split()
    fields[2] = repr(float(fields[2]) + 1e-3)  # robot b's prior 1 mm off in x: chi2 (1e-3)^2 * 1e8 = 100
    (ds / "priors.txt").write_text("\n".join(lines[:-1] + [" ".join(fields)]) + "\n")
    priors = check(ds).summary("priors")
    assert priors.total.dof == 12 and priors.translation.dof == 6
    assert priors.total.chi2 == pytest.approx(100.0, rel=1e-6)
    assert priors.translation.chi2 == pytest.approx(100.0, rel=1e-6) and priors.rotation.chi2 < 1e-12
