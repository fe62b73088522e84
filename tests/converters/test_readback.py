"""Converted datasets read back with GTSAM's g2o reader (where installed), and progress stays quiet."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from studio.cli import app
from studio.convert import ConvertConfig, convert
from studio.converters.build import GraphOptions
from tests.converters.synthetic import UTM_EAST, UTM_NORTH, loop_trajectory, write_tum_file


@pytest.fixture
def two_files(tmp_path):
    files = []
    for k in range(2):
        s, p, q = loop_trajectory(500, centre=(UTM_EAST + k, UTM_NORTH, 20.0), phase=k, climb=2.0)
        files.append(write_tum_file(tmp_path / f"r{k}.txt", s, p, q))
    return files


def test_gtsam_reads_every_agent_file(tmp_path, two_files):
    gtsam = pytest.importorskip("gtsam")
    res = convert(ConvertConfig("tum", two_files, options=GraphOptions(lc_prob_intra=1.0)), tmp_path / "ds")
    for k, agent in enumerate(res.build.graph.agents):
        graph, values = gtsam.readG2o(str(tmp_path / "ds" / f"agent{k + 1}" / "posegraph.g2o"), True)
        assert values.size() == agent.num_poses
        assert graph.size() == len(agent.odometry) + len(agent.loop_closures)
        last = values.atPose3(agent.num_poses - 1)
        np.testing.assert_allclose(last.translation(), agent.initial[-1, :3], atol=1e-9)


def test_progress_is_quiet_when_not_a_terminal(tmp_path, two_files):
    r = CliRunner().invoke(app, ["convert", "tum", *map(str, two_files), "-o", str(tmp_path / "ds")])
    assert r.exit_code == 0
    assert "\r" not in r.output and "reading" not in r.output and "keyframes and odometry" not in r.output
    r = CliRunner().invoke(app, ["convert", "tum", *map(str, two_files), "-o", str(tmp_path / "ds2"), "-q"])
    assert r.exit_code == 0 and r.output == ""
