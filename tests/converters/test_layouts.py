"""S3E- and AirMuseum-shaped folders made by the tests, converted end to end."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.converters.airmuseum import read_airmuseum
from studio.converters.s3e import read_s3e
from studio.core.errors import ConfigError, FormatError
from studio.io.multig2o import read_multi_g2o
from studio.samples import airmuseum_folder, s3e_folder
from tests.converters.synthetic import UTM_NORTH

runner = CliRunner()


def test_s3e_finds_alpha_bob_carol_in_any_case_and_reports_gaps(tmp_path):
    root = s3e_folder(tmp_path / "S3E_Square_1")
    trajs = read_s3e([root])
    assert [t.name for t in trajs] == ["alpha", "bob", "carol"]
    assert trajs[1].positions_xyz[0, 1] == pytest.approx(UTM_NORTH + 1 + 10 * np.sin(0.7), abs=1e-6)
    out = tmp_path / "ds"
    r = runner.invoke(app, ["convert", "s3e", str(root), "-o", str(out), "--max-gap", "1.0"])
    assert r.exit_code == 0, r.output
    assert r.output.count("gap: ") == 3
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["alpha", "bob", "carol"]
    assert np.abs(g.agents[2].ground_truth[:, :2]).max() < 30  # local coordinates, not UTM
    assert len(g.inter) > 0


def test_s3e_in_a_subfolder_and_partial_sets(tmp_path):
    root = tmp_path / "seq"
    s3e_folder(root / "gt", names=("bob_gt.txt",))
    assert [t.name for t in read_s3e([root])] == ["bob"]


def test_s3e_bad_layouts(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(FormatError, match="no S3E ground truth"):
        read_s3e([tmp_path / "empty"])
    with pytest.raises(FormatError, match="not a folder"):
        read_s3e([tmp_path / "nothing"])
    from studio.converters.registry import check_inputs

    with pytest.raises(ConfigError, match="takes one sequence folder, got 2 inputs"):  # checked by the registry
        check_inputs("s3e", [tmp_path, tmp_path], [])


def test_airmuseum_one_file_per_robot(tmp_path):
    root = airmuseum_folder(tmp_path / "airmuseum_seq")
    assert [t.name for t in read_airmuseum([root])] == ["drone", "robot_1", "robot_2", "robot_3"]
    out = tmp_path / "ds"
    r = runner.invoke(app, ["convert", "airmuseum", str(root), "-o", str(out), "--rendezvous", "2"])
    assert r.exit_code == 0, r.output
    g = read_multi_g2o(out)
    assert [a.name for a in g.agents] == ["drone", "robot_1", "robot_2", "robot_3"]
    dt = np.abs(
        np.array([g.agents[a].stamps_ns[v] for a, v in zip(g.inter.from_agent, g.inter.from_index)])
        - np.array([g.agents[a].stamps_ns[v] for a, v in zip(g.inter.to_agent, g.inter.to_index)])
    )
    assert len(dt) > 0 and dt.max() <= 2e9


def test_airmuseum_bad_layouts(tmp_path):
    root = tmp_path / "x"
    root.mkdir()
    (root / "readme.txt").write_text("hello\n")
    with pytest.raises(FormatError, match="no ground-truth file"):
        read_airmuseum([root])
    (root / "r1").mkdir()
    (root / "r1" / "gt.txt").write_text("1 0 0 0 0 0 0 1\n")
    (root / "r1" / "groundtruth.txt").write_text("1 0 0 0 0 0 0 1\n")
    with pytest.raises(FormatError, match="2 ground-truth files"):
        read_airmuseum([root])
