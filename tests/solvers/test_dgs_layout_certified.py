"""The studio's optimum of a graph in distributed-mapper's layout (CogRob/distributed-mapper
``data/example_4robots``: per-robot ``0.g2o`` ... ``3.g2o``, GTSAM ``Symbol`` keys whose indices
skip, each robot's own vertices, every inter-robot edge in both robots' files, identity
information, six-significant-digit numbers) is certified, and bounds every back-end's answer
from below (docs/solve.md, "distributed-mapper's numbers")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from studio.cli import app

runner = CliRunner()
IDENTITY = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"


def _key(robot: int, index: int) -> int:
    return (ord("a") + robot) << 56 | index


def _pose_line(tag: str, t: np.ndarray, rot: Rotation) -> str:
    return f"{tag} " + " ".join(f"{v:.6g}" for v in (*t, *rot.as_quat()))


def _write_folder(root: Path, seed: int = 3) -> Path:
    """Four robots, each a column of a 2 x 2 x 4 lattice (2 m spacing) walked bottom to top; each
    robot's pose k sees the next robot's pose k (inter-robot edges)."""
    rng = np.random.default_rng(seed)
    truth = {}
    for r in range(4):
        for k in range(4):
            truth[(r, k)] = (
                np.array([2.0 * (r % 2), 2.0 * (r // 2), 2.0 * k]),
                Rotation.from_rotvec(0.1 * rng.normal(size=3)),
            )
    edges = [((r, k), (r, k + 1)) for r in range(4) for k in range(3)]
    inter = [((r, k), ((r + 1) % 4, k)) for r in range(4) for k in range(4)]

    def edge(a: tuple[int, int], b: tuple[int, int]) -> str:
        (ta, ra), (tb, rb) = truth[a], truth[b]
        rel_r = ra.inv() * rb * Rotation.from_rotvec(0.05 * rng.normal(size=3))
        rel_t = ra.inv().apply(tb - ta) + 0.2 * rng.normal(size=3)
        body = _pose_line("EDGE_SE3:QUAT", rel_t, rel_r).split(" ", 1)[1]
        return f"EDGE_SE3:QUAT {_key(a[0], 4 * a[1])} {_key(b[0], 4 * b[1])} {body} {IDENTITY}"

    lines_inter = {e: edge(*e) for e in inter}
    for r in range(4):
        lines = []
        for k in range(4):
            t, rot = truth[(r, k)]
            noisy = Rotation.from_rotvec(0.1 * rng.normal(size=3)) * rot
            lines.append(_pose_line(f"VERTEX_SE3:QUAT {_key(r, 4 * k)}", t + 0.3 * rng.normal(size=3), noisy))
        lines += [edge(a, b) for a, b in edges if a[0] == r]
        lines += [text for (a, b), text in lines_inter.items() if r in (a[0], b[0])]
        (root / f"{r}.g2o").write_text("\n".join(lines) + "\n")
    return root


def _run(*args: object) -> str:
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res.output


def test_the_studios_optimum_of_a_distributed_mapper_graph_is_certified(tmp_path):
    src = tmp_path / "example_4robots"
    src.mkdir()
    _write_folder(src)
    ds = tmp_path / "ds"
    _run("convert", "symbols", src, "-o", ds, "--no-rrd")
    counts = json.loads((ds / "import.json").read_text())["counts"]
    assert counts["inter_loop_closures"] == 16  # each written in two robots' files, read once
    _run("solve", ds, "-o", tmp_path / "certified", "--method", "sesync")
    notes = json.loads((tmp_path / "certified" / "solve.json").read_text())["notes"]
    assert notes["certified"] is True
    best = json.loads(_run("check", ds, "--certify", tmp_path / "certified", "--json"))
    assert best["certified"] is True
    assert best["sesync_f"] == notes["sesync_f"] or abs(best["sesync_f"] - notes["sesync_f"]) < 1e-9 * notes["sesync_f"]
    for method in ("gtsam", "dgs"):
        _run("solve", ds, "-o", tmp_path / method, "--method", method)
        other = json.loads(_run("check", ds, "--certify", tmp_path / method, "--json"))
        # every estimate lies above the certified optimum, and its lower bound is below it
        assert other["sesync_f"] >= best["sesync_f"] - 1e-9
        assert other["lower_bound"] <= best["sesync_f"] + 1e-9
