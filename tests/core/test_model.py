import numpy as np
import pytest

from studio.core.errors import GraphError
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind, graphs_equal


def _agent(name="a", n=4, kind=PoseKind.SE2):
    w = kind.pose_width
    poses = np.zeros((n, w))
    if kind is PoseKind.SE3:
        poses[:, 6] = 1.0
    poses[:, 0] = np.arange(n)
    meas = np.zeros((n - 1, w))
    meas[:, 0] = 1.0
    if kind is PoseKind.SE3:
        meas[:, 6] = 1.0
    odo = Edges(kind, np.arange(n - 1), np.arange(1, n), meas, np.ones((n - 1, kind.information_width)))
    return AgentGraph(name, kind, np.arange(n) * 10**9, poses, poses.copy(), odo, Edges.empty(kind))


def test_valid_graph_and_counts():
    g = PoseGraph(
        PoseKind.SE2,
        (_agent("a"), _agent("b", 3)),
        InterAgentEdges(PoseKind.SE2, [1], [2], [0], [3], [[0.1, 0.2, 0.3]], [[1, 0, 0, 1, 0, 1]]),
    )
    assert g.num_poses == 7
    assert g.edge_counts() == {"odometry": 5, "intra_loop_closures": 0, "inter_loop_closures": 1}


def test_edge_to_unknown_vertex_is_refused():
    a = _agent()
    bad = Edges(PoseKind.SE2, [0], [9], [[0, 0, 0]], [[1, 0, 0, 1, 0, 1]])
    with pytest.raises(GraphError, match="loop closure edge 0 refers to vertex 9, but the agent has 4 poses"):
        AgentGraph("a", PoseKind.SE2, a.stamps_ns, a.initial, None, a.odometry, bad)


def test_inter_edge_to_unknown_vertex_is_refused():
    inter = InterAgentEdges(PoseKind.SE2, [0], [0], [1], [5], [[0, 0, 0]], [[1, 0, 0, 1, 0, 1]])
    with pytest.raises(GraphError, match="refers to vertex 5 of agent b, which has 3 poses"):
        PoseGraph(PoseKind.SE2, (_agent("a"), _agent("b", 3)), inter)


@pytest.mark.parametrize(
    "to_index, message",
    [
        ([1, 2, 3, 3], None),  # agent a (4 poses) may take vertex 3, beyond the smaller agent b
        ([1, 2, 3, -1], "inter-agent edge 3 refers to vertex -1 of agent a, which has 4 poses"),
        ([1, 2, 4, 3], "inter-agent edge 2 refers to vertex 4 of agent a, which has 4 poses"),
        ([1, 2, 2, 3], None),
    ],
)
def test_inter_edge_vertices_are_checked_against_their_own_agent(to_index, message):
    # edges into agents of different sizes: the first edge outside its own agent is named
    n = len(to_index)
    inter = InterAgentEdges(PoseKind.SE2, [1] * n, [0] * n, [0] * n, to_index, np.zeros((n, 3)), np.ones((n, 6)))
    agents = (_agent("a", 4), _agent("b", 3))
    if message is None:
        assert len(PoseGraph(PoseKind.SE2, agents, inter).inter) == n
    else:
        with pytest.raises(GraphError, match=message):
            PoseGraph(PoseKind.SE2, agents, inter)


def test_inter_edge_to_unknown_agent_and_negative_vertex_are_refused():
    inter = InterAgentEdges(PoseKind.SE2, [0, 2], [0, 0], [1, 1], [0, 0], np.zeros((2, 3)), np.ones((2, 6)))
    with pytest.raises(GraphError, match="inter-agent edge 1 refers to unknown agent 2"):
        PoseGraph(PoseKind.SE2, (_agent("a"), _agent("b", 3)), inter)
    a = _agent()
    bad = Edges(PoseKind.SE2, [0, -2], [1, 1], np.zeros((2, 3)), np.ones((2, 6)))
    with pytest.raises(GraphError, match="loop closure edge 1 refers to vertex -2, but the agent has 4 poses"):
        AgentGraph("a", PoseKind.SE2, a.stamps_ns, a.initial, None, a.odometry, bad)


def test_stamps_must_increase():
    a = _agent()
    with pytest.raises(GraphError, match="stamps must increase"):
        AgentGraph("a", PoseKind.SE2, [0, 2, 2, 3], a.initial, None, a.odometry, a.loop_closures)


def test_non_unit_quaternion_is_refused():
    a = _agent(kind=PoseKind.SE3)
    poses = a.initial.copy()
    poses[2, 3:7] = [0, 0, 0, 2.0]
    with pytest.raises(GraphError, match="initial row 2 has a non-unit quaternion"):
        AgentGraph("a", PoseKind.SE3, a.stamps_ns, poses, None, a.odometry, a.loop_closures)


def test_nan_is_refused_and_lengths_must_match():
    a = _agent()
    poses = a.initial.copy()
    poses[1, 1] = np.nan
    with pytest.raises(GraphError, match="a: initial row 1 is not finite"):
        AgentGraph("a", PoseKind.SE2, a.stamps_ns, poses, None, a.odometry, a.loop_closures)
    with pytest.raises(GraphError, match="3 ground-truth poses for 4 poses"):
        AgentGraph("a", PoseKind.SE2, a.stamps_ns, a.initial, a.initial[:3], a.odometry, a.loop_closures)


def test_duplicate_agent_names_are_refused():
    with pytest.raises(GraphError, match="agent names must be unique"):
        PoseGraph(PoseKind.SE2, (_agent("a"), _agent("a")), InterAgentEdges.empty(PoseKind.SE2))


def test_lift_to_se3_keeps_xy_and_turns_yaw_into_quaternion():
    a = _agent()
    poses = a.initial.copy()
    poses[:, 2] = [0.0, np.pi / 2, -np.pi / 2, 1.0]
    g = PoseGraph(
        PoseKind.SE2,
        (AgentGraph("a", PoseKind.SE2, a.stamps_ns, poses, poses, a.odometry, a.loop_closures),),
        InterAgentEdges.empty(PoseKind.SE2),
    )
    lifted = g.to_se3()
    assert lifted is g.to_se3()  # cached
    q = lifted.agents[0].initial[:, 3:7]
    np.testing.assert_allclose(q[1], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    info = lifted.agents[0].odometry.information_upper[0]
    # diag(I11, I22, 1e6, I33, I33, I33) in upper-triangle order
    assert info[[0, 6, 11, 15, 18, 20]].tolist() == [1.0, 1.0, 1e6, 1.0, 1.0, 1.0]
    assert graphs_equal(g, g) and not graphs_equal(g, lifted)
