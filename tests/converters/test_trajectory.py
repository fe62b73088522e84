"""studio.converters.names (safe agent names) and the quaternion helpers of studio.core.geometry."""

from __future__ import annotations

import numpy as np
import pytest

from studio.converters.names import check_agent_name, safe_agent_name
from studio.core.errors import ConfigError
from studio.core.geometry import quat_angle, quat_from_rotvec, quat_mul, quat_rotate


@pytest.mark.parametrize(
    "raw, safe",
    [
        ("alpha", "alpha"),
        ("../../etc", "etc"),
        ("..", "agent"),
        ("/", "agent"),
        ("a/b", "a_b"),
        (".hidden", "hidden"),
        ("robot 1", "robot_1"),
        ("convert.json", "agent_convert.json"),
        ("", "agent"),
        ("a\\b", "a_b"),
        ("Ünïcode", "n_code"),
        ("a..b", "a_b"),
    ],
)
def test_safe_agent_name(raw, safe):
    assert safe_agent_name(raw) == safe


@pytest.mark.parametrize("name", ["../x", "a/b", "..", ".x", "", "inter_agent_lc.dat", "a b"])
def test_typed_names_must_already_be_safe(name):
    with pytest.raises(ConfigError, match="not a safe folder name"):
        check_agent_name(name, "--agent")
    assert check_agent_name("robot_1", "--agent") == "robot_1"


def test_quaternion_helpers():
    r = np.array([[0.0, 0.0, np.pi / 2], [0.3, -0.2, 0.1]])
    q = quat_from_rotvec(r)
    np.testing.assert_allclose(quat_rotate(q[:1], np.array([[1.0, 0, 0]])), [[0, 1, 0]], atol=1e-15)
    np.testing.assert_allclose(quat_angle(q), np.linalg.norm(r, axis=1), rtol=1e-12)
    np.testing.assert_allclose(quat_angle(quat_mul(q[:1], q[:1])), [np.pi], rtol=1e-12)
