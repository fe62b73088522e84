"""Per-robot g2o files as the tools name them (issue 37): Kimera-RPGO's ``robot_a.g2o, robot_b.g2o``
with GTSAM Symbol keys (``char << 56 | index``) and six-decimal quaternions, beside its other test
graphs; Swarm-SLAM's GTSAM ``LabeledSymbol`` keys (``'g' << 56 | ('A' + robot) << 48 | index``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from studio.cli import app
from studio.io.multig2o import read_multi_g2o
from studio.io.symbol_g2o import read_symbol_g2o_folder

runner = CliRunner()

_INFO = "2.50044 0 0 0 0 0 2.50044 0 0 0 0 2.50044 0 0 0 10.0144 0 0 10.0144 0 10.0144"
# a yaw of 0.1 rad written with six decimals, as Kimera-RPGO's files write them (norm off ~4e-7)
_Q = "0.000000 0.000000 0.049979 0.998750"


def _symbol(char: str, index: int) -> int:
    return ord(char) << 56 | index


def _labeled(robot: int, index: int) -> int:
    return ord("g") << 56 | (ord("A") + robot) << 48 | index


def _robot_lines(keys: list[int], *, closure: tuple[int, int] | None = None) -> list[str]:
    lines = [f"VERTEX_SE3:QUAT {k} {i:.6f} 0.000000 0.000000 {_Q}" for i, k in enumerate(keys)]
    lines += [f"EDGE_SE3:QUAT {a} {b} 1.000000 0.000000 0.000000 {_Q} {_INFO}" for a, b in zip(keys, keys[1:])]
    if closure is not None:
        lines.append(f"EDGE_SE3:QUAT {closure[0]} {closure[1]} 3.000000 0.000000 0.000000 {_Q} {_INFO}")
    return lines


def _kimera_folder(root: Path) -> Path:
    """Kimera-RPGO's tests/data: robot_a.g2o (5 poses, a loop closure), robot_b.g2o (4 poses and an
    edge to robot a's pose 4, which robot a's file holds too), and ordered.g2o of plain ids."""
    folder = root / "data"
    folder.mkdir()
    a = [_symbol("a", i) for i in range(5)]
    b = [_symbol("b", i) for i in range(4)]
    inter = f"EDGE_SE3:QUAT {b[3]} {a[4]} 0.500000 0.000000 0.000000 {_Q} {_INFO}"
    (folder / "robot_a.g2o").write_text("\n".join(_robot_lines(a, closure=(a[0], a[3])) + [inter]) + "\n")
    (folder / "robot_b.g2o").write_text("\n".join(_robot_lines(b) + [inter]) + "\n")
    (folder / "ordered.g2o").write_text("\n".join(_robot_lines(list(range(6)))) + "\n")
    return folder


def test_kimera_robot_files_are_found_with_their_symbol_prefixes(tmp_path):
    folder = _kimera_folder(tmp_path)
    warnings: list[str] = []
    graph = read_symbol_g2o_folder(folder, warn=warnings.append)
    assert [a.name for a in graph.agents] == ["a", "b"]
    assert [a.num_poses for a in graph.agents] == [5, 4]
    assert [len(a.odometry) for a in graph.agents] == [4, 3]
    assert [len(a.loop_closures) for a in graph.agents] == [1, 0]
    inter = graph.inter
    assert len(inter) == 1  # in both files, taken once
    assert (int(inter.from_agent[0]), int(inter.from_index[0]), int(inter.to_agent[0]), int(inter.to_index[0])) == (
        1,
        3,
        0,
        4,
    )
    # every quaternion read: 9 vertices, 7 odometry, 1 closure, the inter-robot edge in both files
    assert len(warnings) == 1 and "normalised 19 quaternions" in warnings[0]
    np.testing.assert_allclose(np.linalg.norm(graph.agents[0].initial[:, 3:7], axis=1), 1.0, atol=1e-15)
    r = runner.invoke(app, ["convert", "symbols", str(folder), "-o", str(tmp_path / "ds"), "--no-rrd", "-q"])
    assert r.exit_code == 0, r.output
    back = read_multi_g2o(tmp_path / "ds")
    assert [a.name for a in back.agents] == ["a", "b"] and len(back.inter) == 1


def test_the_folder_is_detected_as_symbols(tmp_path):
    folder = _kimera_folder(tmp_path)
    r = runner.invoke(app, ["convert", str(folder), "-o", str(tmp_path / "ds"), "--no-rrd", "-q"])
    assert r.exit_code == 0, r.output
    assert len(read_multi_g2o(tmp_path / "ds").agents) == 2


def test_swarm_slam_labeled_symbol_keys_name_the_robots(tmp_path):
    """Swarm-SLAM's graph: every robot in one file, keys LabeledSymbol('g', 'A' + id, index)."""
    r0 = [_labeled(0, i) for i in range(4)]
    r1 = [_labeled(1, i) for i in range(3)]
    r2 = [_labeled(2, i) for i in range(3)]
    inter = [
        f"EDGE_SE3:QUAT {r0[1]} {r1[0]} 0.200000 0.000000 0.000000 {_Q} {_INFO}",
        f"EDGE_SE3:QUAT {r2[2]} {r0[3]} 0.300000 0.000000 0.000000 {_Q} {_INFO}",
    ]
    path = tmp_path / "optimized_global_pose_graph.g2o"
    path.write_text("\n".join(_robot_lines(r0) + _robot_lines(r1) + _robot_lines(r2) + inter) + "\n")
    graph = read_symbol_g2o_folder(path)
    assert [a.name for a in graph.agents] == ["gA", "gB", "gC"]
    assert [a.num_poses for a in graph.agents] == [4, 3, 3]
    assert [len(a.odometry) for a in graph.agents] == [3, 2, 2]
    rows = np.column_stack([graph.inter.from_agent, graph.inter.from_index, graph.inter.to_agent, graph.inter.to_index])
    assert rows.tolist() == [[0, 1, 1, 0], [2, 2, 0, 3]]
    folder = tmp_path / "swarm"
    folder.mkdir()
    (folder / "fullGraph.g2o").write_text(path.read_text())
    r = runner.invoke(app, ["convert", "symbols", str(folder), "-o", str(tmp_path / "ds"), "--no-rrd", "-q"])
    assert r.exit_code == 0, r.output
    assert [a.name for a in read_multi_g2o(tmp_path / "ds").agents] == ["gA", "gB", "gC"]
