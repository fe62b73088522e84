"""SE-Sync's objective, certificate and staircase (studio/solvers/sesync*.py) on small graphs the
tests build: a noiseless graph (f* = 0), a noisy one whose optimum a second, independent minimizer
finds, a perturbed estimate the certificate refuses, and a ring where Gauss-Newton from a wound
start ends in a worse basin than the default method now returns."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from studio.core.model import PoseKind
from studio.solvers import METHODS, gtsam_method
from studio.solvers.problem import Problem, SolveOptions, graph_chi2
from studio.solvers.sesync import solve_sesync
from studio.solvers.sesync_problem import build, certify_rotations, rotation_matrices
from tests.solvers.test_solvers import _relative, make_problem

pytest.importorskip("pymanopt")


def _sync(p: Problem):
    return build(p.kind, p.num_vertices, p.edge_from, p.edge_to, p.measurements, p.information_upper)


def _certify(p: Problem, poses: np.ndarray):
    sync = _sync(p)
    rot, trans = rotation_matrices(p.kind, poses)
    rows = rot.transpose(1, 0, 2).reshape(sync.d, -1)
    return certify_rotations(sync, rows, sync.full_objective(rot, trans))[0]


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_a_noiseless_graph_is_solved_to_zero_and_certified(kind):
    p, gt = make_problem(kind, n=40, closures=15)[:2]
    sol = solve_sesync(p, SolveOptions(max_iterations=500))
    assert sol.notes["certified"] is True
    assert sol.notes["sesync_f"] < 1e-8
    assert sol.notes["verdict"].startswith("certified globally optimal")
    cert = _certify(p, sol.poses)
    assert cert.certified and cert.objective < 1e-8 and cert.lambda_min > -1e-6
    # the ground truth is the optimum too
    assert _certify(p, gt).certified


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_a_perturbed_estimate_is_not_certified_and_its_bound_holds(kind):
    p, gt = make_problem(kind, n=40, closures=15)[:2]
    rng = np.random.default_rng(3)
    bad = gt.copy()
    if kind is PoseKind.SE2:
        bad[:, 2] += rng.normal(0, 0.3, len(bad))
    else:
        rot = Rotation.from_quat(bad[:, 3:7]) * Rotation.from_rotvec(rng.normal(0, 0.3, (len(bad), 3)))
        bad[:, 3:7] = rot.as_quat()
    cert = _certify(p, bad)
    assert not cert.certified
    assert cert.lambda_min < -1e-3
    assert cert.verdict().startswith("not certified, at most")
    # f* = 0: the bound must cover the whole of f, and the lower bound must not exceed f*
    assert cert.lower_bound <= 1e-9
    assert cert.gap_bound >= cert.objective - 1e-9 > 0
    # translations alone off (rotations optimal): refused too
    shifted = gt.copy()
    shifted[5:, 0] += 0.5
    cert = _certify(p, shifted)
    assert not cert.certified and cert.objective > 0


def _noisy(p: Problem, sigma: float = 0.05, seed: int = 2) -> Problem:
    """``p`` with every measurement moved by noise of ``sigma`` (metres, radians)."""
    rng = np.random.default_rng(seed)
    z = p.measurements.copy()
    if p.kind is PoseKind.SE2:
        z += rng.normal(0, sigma, z.shape)
    else:
        z[:, 0:3] += rng.normal(0, sigma, (len(z), 3))
        rot = Rotation.from_quat(z[:, 3:7]) * Rotation.from_rotvec(rng.normal(0, sigma, (len(z), 3)))
        z[:, 3:7] = rot.as_quat()
    return Problem(p.kind, p.initial, p.edge_from, p.edge_to, z, p.information_upper, p.robust)


def _direct_minimum(p: Problem, start: np.ndarray) -> float:
    """SE-Sync's objective minimized over poses directly (scipy's least squares, rotations as
    rotation vectors) from ``start``: a second way to the same optimum."""
    sync = _sync(p)
    d, n = sync.d, sync.n
    r0, t0 = rotation_matrices(p.kind, start)
    x0 = np.concatenate([t0.ravel(), start[:, 2] if d == 2 else Rotation.from_matrix(r0).as_rotvec().ravel()])
    r_ij, t_ij = rotation_matrices(p.kind, p.measurements)
    fr, to = p.edge_from, p.edge_to
    sk, st = np.sqrt(sync.kappa), np.sqrt(sync.tau)

    def residuals(x: np.ndarray) -> np.ndarray:
        t = x[: n * d].reshape(n, d)
        if d == 2:
            th = x[n * d :]
            c, s = np.cos(th), np.sin(th)
            r = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], 1)
        else:
            r = Rotation.from_rotvec(x[n * d :].reshape(n, 3)).as_matrix()
        er = (r[to] - r[fr] @ r_ij) * sk[:, None, None]
        et = (t[to] - t[fr] - np.einsum("eij,ej->ei", r[fr], t_ij)) * st[:, None]
        return np.concatenate([er.ravel(), et.ravel()])

    res = least_squares(residuals, x0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return float(2 * res.cost)


@pytest.mark.parametrize("kind", [PoseKind.SE2, PoseKind.SE3])
def test_f_star_matches_a_direct_minimization(kind):
    p, gt = make_problem(kind, n=16, closures=6)[:2]
    p = _noisy(p)
    sol = solve_sesync(p, SolveOptions(max_iterations=500))
    assert sol.notes["certified"] is True
    f_star = float(sol.notes["sesync_f"])
    assert f_star > 1e-3  # noisy: a real optimum, not zero
    direct = _direct_minimum(p, sol.poses)
    assert abs(direct - f_star) <= 1e-4 * f_star
    # and from the ground truth, the direct minimizer finds no lower value
    assert _direct_minimum(p, gt) >= f_star * (1 - 1e-4)


def _wound_ring(n: int = 5, winding: int = 2) -> Problem:
    """A ring of ``n`` poses whose initial headings wind ``winding`` extra turns: Gauss-Newton from
    them ends in a local minimum far above the optimum."""
    rng = np.random.default_rng(0)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    gt = np.column_stack([5 * np.cos(ang), 5 * np.sin(ang), ang + np.pi / 2])
    fr = np.arange(n)
    to = (fr + 1) % n
    z = _relative(PoseKind.SE2, gt[fr], gt[to]) + rng.normal(0, 0.05, (n, 3))
    init = gt.copy()
    init[:, 2] += winding * ang
    info = np.tile([1.0, 0, 0, 1.0, 0, 100.0], (n, 1))
    return Problem(PoseKind.SE2, init, fr, to, z, info, np.zeros(n, dtype=bool))


def test_the_default_method_returns_the_better_basin(monkeypatch):
    p = _wound_ring()
    options = SolveOptions(init="odometry", max_iterations=100)
    best = METHODS["gtsam"].solve(p, options)
    chosen = best.notes["certified_start"]
    assert chosen["chosen"] == "certified start"
    assert chosen["chi2_local"] > 100 * chosen["chi2_certified_start"]
    assert graph_chi2(p, best.poses) == pytest.approx(chosen["chi2_certified_start"])
    assert best.chi2_history[-1] == pytest.approx(chosen["chi2_certified_start"])
    # without the comparison, the same run ends in the local minimum
    monkeypatch.setattr(gtsam_method, "_from_certified", lambda *a, **k: {"poses": None})
    local = METHODS["gtsam"].solve(p, options)
    assert graph_chi2(p, local.poses) == pytest.approx(chosen["chi2_local"])
    assert graph_chi2(p, local.poses) > 100 * graph_chi2(p, best.poses)


def test_sesync_is_a_registered_method():
    entry = METHODS["sesync"]
    assert entry.options == ("max_iterations",)
    assert entry.default("max_iterations") == 1000


def _without_qdldl(monkeypatch) -> None:
    """Imports of ``qdldl`` fail from here on, as on a machine without the ``solve`` extra."""
    import builtins

    real_import = builtins.__import__

    def no_qdldl(name, *args, **kwargs):
        if name == "qdldl":
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_qdldl)


def test_spd_factor_solves_alike_with_qdldl_and_with_superlu(monkeypatch):
    import scipy.sparse as sp

    from studio.solvers.sesync_problem import spd_factor

    rng = np.random.default_rng(1)
    b = sp.random(40, 40, density=0.1, random_state=2)
    a = (b @ b.T + 40 * sp.identity(40)).tocsc()
    rhs = rng.standard_normal((40, 3))
    expected = np.linalg.solve(a.toarray(), rhs)
    np.testing.assert_allclose(spd_factor(a).solve(rhs), expected, rtol=1e-10)
    np.testing.assert_allclose(spd_factor(a).solve(rhs[:, 0]), expected[:, 0], rtol=1e-10)
    _without_qdldl(monkeypatch)
    lu = spd_factor(a)
    assert type(lu.lu).__name__ == "SuperLU"
    np.testing.assert_allclose(lu.solve(rhs), expected, rtol=1e-10)


@pytest.mark.parametrize("method", ["qdldl", "superlu", "cholmod"])
def test_spd_factor_reads_an_upper_triangle_and_updates_in_place(monkeypatch, method):
    """A factor given only the upper triangle solves the whole matrix; ``update`` with a matrix
    of the same pattern solves the new one (QDLDL and CHOLMOD keep their ordering, SuperLU factors
    anew)."""
    import scipy.sparse as sp

    from studio.solvers.spd import spd_factor

    if method == "cholmod":
        pytest.importorskip("cvxopt")
    if method == "superlu":
        _without_qdldl(monkeypatch)
    rng = np.random.default_rng(3)
    b = sp.random(30, 30, density=0.15, random_state=4)
    a = (b @ b.T + 30 * sp.identity(30)).tocsc()
    rhs = rng.standard_normal(30)
    lu = spd_factor(sp.triu(a, format="csc"), upper=True, supernodal=method == "cholmod")
    assert type(lu).__name__ == {"qdldl": "_Ldl", "superlu": "_Lu", "cholmod": "_Cholmod"}[method]
    np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(a.toarray(), rhs), rtol=1e-10)
    a2 = a.copy()
    a2.data = a2.data * (1.0 + rng.random(a2.nnz))  # same pattern, other numbers
    a2 = (a2 + a2.T) / 2
    lu.update(sp.triu(a2, format="csc"))
    np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(a2.toarray(), rhs), rtol=1e-10)


def test_a_supernodal_factor_hands_a_matrix_that_is_not_positive_definite_to_ldl():
    """CHOLMOD refuses a pivot that is not positive, LDL^T takes any nonzero one: a matrix of the
    pattern that is symmetric but indefinite is still solved, by QDLDL's factor from then on."""
    import scipy.sparse as sp

    pytest.importorskip("cvxopt")
    from studio.solvers.spd import spd_factor

    upper = sp.csc_matrix(np.triu([[4.0, 0.0, 1.0], [0.0, 3.0, 0.0], [1.0, 0.0, 5.0]]))
    lu = spd_factor(upper, upper=True, supernodal=True)
    assert lu.ldl is None
    indefinite = upper.copy()
    indefinite.data = np.array([1.0, 3.0, 2.0, 1.0])  # [[1, 0, 2], [0, 3, 0], [2, 0, 1]]: eigenvalue -1
    lu.update(indefinite)
    assert lu.ldl is not None
    full = np.array([[1.0, 0.0, 2.0], [0.0, 3.0, 0.0], [2.0, 0.0, 1.0]])
    rhs = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(lu.solve(rhs), np.linalg.solve(full, rhs), rtol=1e-12)
