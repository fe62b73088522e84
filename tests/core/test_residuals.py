"""studio.core.residuals against g2o itself (g2opy), edge by edge, and against GTSAM for ``rotvec``."""

from __future__ import annotations

import numpy as np
import pytest

from studio.core.geometry import quat_from_rotvec
from studio.core.model import AgentGraph, Edges, InterAgentEdges, PoseGraph, PoseKind
from studio.core.residuals import chi2_parts, chi2_terms, edge_errors, graph_chi2

g2o = pytest.importorskip("g2opy")


def _se2(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.column_stack([rng.uniform(-20, 20, (n, 2)), rng.uniform(-np.pi, np.pi, n)])


def _se3(rng: np.random.Generator, n: int, spread: float = np.pi) -> np.ndarray:
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    q = quat_from_rotvec(axis * rng.uniform(0, spread, n)[:, None])
    return np.column_stack([rng.uniform(-20, 20, (n, 3)), q])


def _information(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    """Random symmetric positive-definite information, as upper triangles (row-major)."""
    a = rng.normal(size=(n, d, d))
    omega = np.einsum("nij,nkj->nik", a, a) + d * np.eye(d)
    rows, cols = np.triu_indices(d)
    return omega[:, rows, cols]


def _g2o_edges(kind: PoseKind, xi, xj, z, info):
    """g2o's own error vector and chi2 of each edge."""
    d = 3 if kind is PoseKind.SE2 else 6
    rows, cols = np.triu_indices(d)
    errors, chi2 = [], []
    for a, b, m, u in zip(xi, xj, z, info):
        if kind is PoseKind.SE2:
            v1, v2, e = g2o.VertexSE2(), g2o.VertexSE2(), g2o.EdgeSE2()
        else:
            v1, v2, e = g2o.VertexSE3(), g2o.VertexSE3(), g2o.EdgeSE3()
        v1.set_estimate_data(a)
        v2.set_estimate_data(b)
        e.set_vertex(0, v1)
        e.set_vertex(1, v2)
        e.set_measurement_data(m)
        omega = np.zeros((d, d))
        omega[rows, cols] = u
        omega[cols, rows] = u
        e.set_information(omega)
        e.compute_error()
        errors.append(np.array(e.error))
        chi2.append(e.chi2())
    return np.array(errors), np.array(chi2)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_errors_and_chi2_equal_g2os_edge_by_edge(kind):
    rng = np.random.default_rng(11)
    n = 300
    make = _se2 if kind is PoseKind.SE2 else _se3
    xi, xj, z = make(rng, n), make(rng, n), make(rng, n)
    d = 3 if kind is PoseKind.SE2 else 6
    info = _information(rng, n, d)
    theirs_e, theirs_chi2 = _g2o_edges(kind, xi, xj, z, info)
    ours_e = edge_errors(xi, xj, z)
    assert np.abs(ours_e - theirs_e).max() < 1e-9
    ours_chi2 = chi2_terms(ours_e, info)
    assert np.abs(ours_chi2 - theirs_chi2).max() < 1e-9 * np.maximum(1.0, theirs_chi2).max()
    # large errors included: the g2o rotation part is the quaternion's vector part, |.| <= 1
    if kind is PoseKind.SE3:
        assert np.linalg.norm(ours_e[:, 3:], axis=1).max() <= 1.0 + 1e-12
        assert np.linalg.norm(ours_e[:, 3:], axis=1).max() > 0.9


def test_rotvec_rotation_part_is_the_angle_and_about_twice_g2os():
    rng = np.random.default_rng(3)
    n = 200
    xi = _se3(rng, n)
    angles = rng.uniform(0.0, 3.0, n)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    z = np.column_stack([np.zeros((n, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))])
    # X_j = X_i * Exp(angle * axis): the error is that rotation (measurement identity)
    from studio.core.geometry import quat_mul

    xj = np.column_stack([xi[:, :3], quat_mul(xi[:, 3:], quat_from_rotvec(axis * angles[:, None]))])
    rv = edge_errors(xi, xj, z, convention="rotvec")[:, 3:]
    g = edge_errors(xi, xj, z, convention="g2o")[:, 3:]
    np.testing.assert_allclose(rv, axis * angles[:, None], atol=1e-9)
    np.testing.assert_allclose(g, axis * np.sin(angles / 2)[:, None], atol=1e-12)


def test_rotvec_equals_gtsams_between_factor_error():
    gtsam = pytest.importorskip("gtsam")
    rng = np.random.default_rng(4)
    n = 50
    xi, xj, z = _se3(rng, n, 2.5), _se3(rng, n, 2.5), _se3(rng, n, 2.5)
    ours = edge_errors(xi, xj, z, convention="rotvec")

    def pose(p):
        return gtsam.Pose3(gtsam.Rot3.Quaternion(p[6], p[3], p[4], p[5]), p[:3])

    for k in range(n):
        # GTSAM's Pose3 local coordinates are [rotation; translation] and its BetweenFactor error is
        # Logmap(Z^-1 Xi^-1 Xj); on the rotation part this is the rotation vector we compute
        d = pose(z[k]).between(pose(xi[k]).between(pose(xj[k])))
        np.testing.assert_allclose(ours[k, 3:], gtsam.Rot3.Logmap(d.rotation()), atol=1e-9)
        np.testing.assert_allclose(ours[k, :3], d.translation(), atol=1e-9)


def test_chi2_parts_split_the_diagonal_blocks():
    rng = np.random.default_rng(5)
    e = rng.normal(size=(40, 6))
    info = _information(rng, 40, 6)
    t, r = chi2_parts(e, info)
    rows, cols = np.triu_indices(6)
    omega = np.zeros((40, 6, 6))
    omega[:, rows, cols] = info
    omega[:, cols, rows] = info
    np.testing.assert_allclose(t, np.einsum("ni,nij,nj->n", e[:, :3], omega[:, :3, :3], e[:, :3]))
    np.testing.assert_allclose(r, np.einsum("ni,nij,nj->n", e[:, 3:], omega[:, 3:, 3:], e[:, 3:]))
    # block-diagonal information: the parts add up to the whole
    info_bd = np.where((rows < 3) == (cols < 3), info, 0.0)
    np.testing.assert_allclose(sum(chi2_parts(e, info_bd)), chi2_terms(e, info_bd), rtol=1e-12)


def test_graph_chi2_equals_g2os_active_chi2_on_a_two_agent_graph(tmp_path):
    rng = np.random.default_rng(6)
    n, kind = 30, PoseKind.SE2
    agents = []
    for name in ("a", "b"):
        gt = _se2(rng, n)
        odo = Edges(kind, np.arange(n - 1), np.arange(1, n), _se2(rng, n - 1), _information(rng, n - 1, 3))
        lc = Edges(kind, [0, 3], [20, 25], _se2(rng, 2), _information(rng, 2, 3))
        agents.append(AgentGraph(name, kind, np.arange(n, dtype=np.int64), gt, gt, odo, lc))
    inter = InterAgentEdges(kind, [0, 1, 0], [5, 7, 29], [1, 0, 1], [2, 9, 0], _se2(rng, 3), _information(rng, 3, 3))
    graph = PoseGraph(kind, tuple(agents), inter)
    parts = graph_chi2(graph)
    # the same edges in one g2o optimizer, vertex ids offset by agent
    opt = g2o.SparseOptimizer()
    vs = []
    for k, agent in enumerate(graph.agents):
        for i, p in enumerate(agent.ground_truth):
            v = g2o.VertexSE2()
            v.set_id(k * n + i)
            v.set_estimate_data(p)
            opt.add_vertex(v)
            vs.append(v)

    def add(i, j, m, u):
        e = g2o.EdgeSE2()
        e.set_vertex(0, vs[i])
        e.set_vertex(1, vs[j])
        e.set_measurement_data(m)
        rows, cols = np.triu_indices(3)
        om = np.zeros((3, 3))
        om[rows, cols] = u
        om[cols, rows] = u
        e.set_information(om)
        opt.add_edge(e)

    for k, agent in enumerate(graph.agents):
        for edges in (agent.odometry, agent.loop_closures):
            for i, j, m, u in zip(edges.from_index, edges.to_index, edges.measurements, edges.information_upper):
                add(k * n + i, k * n + j, m, u)
    for fa, fi, ta, ti, m, u in zip(
        inter.from_agent, inter.from_index, inter.to_agent, inter.to_index, inter.measurements, inter.information_upper
    ):
        add(fa * n + fi, ta * n + ti, m, u)
    opt.initialize_optimization()
    opt.compute_active_errors()
    assert parts["total"] == pytest.approx(opt.active_chi2(), rel=1e-9)
    assert parts["inter"] > 0 and parts["intra"] > 0 and parts["odometry"] > 0
    assert parts["total"] == pytest.approx(parts["odometry"] + parts["intra"] + parts["inter"])
