"""An incremental solver over a growing part of a :class:`~studio.solvers.problem.Problem`: GTSAM's
ISAM2 fed in batches (``pip install gtsam``), for the online back-ends of ``studio replay``.

The caller says which vertices and edges (global ids of the problem) have become known; new
vertices start from the current estimate of their agent's latest known pose composed with the
dataset's relative dead reckoning (``initial[last]^-1 * initial[v]``: the odometry chain), and
each batch is one ``ISAM2.update`` (plus ``extra_updates`` more, each a relinearization where
deltas exceed the threshold). Gauge: the first vertex of the first agent added gets a tight
prior at a given pose, every other agent's first vertex a loose one (sigma
:data:`LOOSE_PRIOR_SIGMA`), so that agents not yet tied by a loop closure keep their pose and
tied ones are free to move (its cost is negligible: 1 m off adds 0.01 to chi2; a looser one makes GTSAM call the system indeterminate).

Information is converted as :mod:`studio.solvers.gtsam_method` does (SE(3): tangent order and the
g2o rotation-error factor), so a batch of everything converges to the same optimum as
``studio solve``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from studio.core.errors import ConfigError
from studio.core.geometry import normalize_angle, quat_conj, quat_mul, quat_rotate, upper_to_matrix
from studio.core.model import PoseKind
from studio.solvers.isam_settings import IsamSettings
from studio.solvers.problem import Problem

__all__ = [
    "IsamSettings",
    "IncrementalSolver",
    "FixedEnds",
    "compose",
    "inverse",
    "gtsam_information",
    "LOOSE_PRIOR_SIGMA",
]

#: Sigma [m, rad] of the prior holding an agent's first pose until loop closures tie it to others.
LOOSE_PRIOR_SIGMA = 10.0
#: Sigma of the prior holding the gauge (the first agent's first pose).
TIGHT_PRIOR_SIGMA = 1e-4
_PERMUTE_SE3 = np.array([3, 4, 5, 0, 1, 2])


def _gtsam() -> Any:
    try:
        import gtsam
    except ImportError:
        raise ConfigError("studio replay needs GTSAM: pip install 'cslam-studio[solve]'") from None
    return gtsam


def compose(a: np.ndarray, b: np.ndarray, kind: PoseKind) -> np.ndarray:
    """Row-wise ``a * b`` of planar ``[x, y, theta]`` or spatial ``[x, y, z, qx, qy, qz, qw]`` poses."""
    if kind is PoseKind.SE2:
        c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
        return np.column_stack(
            [
                a[:, 0] + c * b[:, 0] - s * b[:, 1],
                a[:, 1] + s * b[:, 0] + c * b[:, 1],
                normalize_angle(a[:, 2] + b[:, 2]),
            ]
        )
    q = quat_mul(a[:, 3:7], b[:, 3:7])
    return np.column_stack([a[:, 0:3] + quat_rotate(a[:, 3:7], b[:, 0:3]), q / np.linalg.norm(q, axis=1)[:, None]])


def inverse(a: np.ndarray, kind: PoseKind) -> np.ndarray:
    if kind is PoseKind.SE2:
        c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
        return np.column_stack([-(c * a[:, 0] + s * a[:, 1]), -(-s * a[:, 0] + c * a[:, 1]), -a[:, 2]])
    qi = quat_conj(a[:, 3:7])
    return np.column_stack([-quat_rotate(qi, a[:, 0:3]), qi])


def gtsam_information(problem: Problem) -> np.ndarray:
    """Per edge, the information matrix in GTSAM's tangent order and error convention."""
    d = 3 if problem.kind is PoseKind.SE2 else 6
    omega = upper_to_matrix(problem.information_upper, d)
    if problem.kind is PoseKind.SE3:
        half = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
        omega = (omega * half[None, :, None] * half[None, None, :])[:, _PERMUTE_SE3][:, :, _PERMUTE_SE3]
    return omega


@dataclass(frozen=True, eq=False)
class FixedEnds:
    """Edges of the problem with one end held at a given pose (a neighbour's pose another robot
    shared): each enters as a unary factor on its other end, the edge's measurement composed with
    the held pose; exactly the edge's factor with that end fixed (the information moved through the
    measurement's adjoint where the held end is the edge's ``to``)."""

    edges: np.ndarray
    """Global edge ids."""
    held_poses: np.ndarray
    """``(len(edges), w)``: the pose at which each edge's held end is fixed."""
    held_is_from: np.ndarray
    """Per edge, True where the held end is the edge's ``from`` (the factor is then on ``to``)."""
    information_scale: float = 1.0
    """The edge's information times this (1: the edge's own noise)."""


class EdgeTerms:
    """What GTSAM needs of each edge of a problem, made once and shared by every solver of it:
    the information in GTSAM's order (:func:`gtsam_information`), the measurement as a GTSAM pose,
    and a noise model per distinct information matrix (a dataset's edges share a few): a swarm
    builds a new solver for every new group, and making these anew for each edge took more than
    half of adding the edges to it."""

    def __init__(self, problem: Problem) -> None:
        gtsam = _gtsam()
        self.omega = gtsam_information(problem)
        m, d = len(self.omega), 3 if problem.kind is PoseKind.SE2 else 6
        distinct, which = np.unique(self.omega.reshape(m, d * d), axis=0, return_inverse=True)
        models = [gtsam.noiseModel.Gaussian.Information(row.reshape(d, d)) for row in distinct]
        self.noise = [models[k] for k in np.ravel(which).tolist()]
        self.measurements = gtsam_poses(gtsam, problem.kind, problem.measurements)


def gtsam_poses(gtsam: Any, kind: PoseKind, rows: np.ndarray) -> list[Any]:
    """GTSAM poses of pose rows (planar ``x y theta``, spatial ``x y z qx qy qz qw``)."""
    if kind is PoseKind.SE2:
        return [gtsam.Pose2(x, y, t) for x, y, t in rows.tolist()]
    return [
        gtsam.Pose3(gtsam.Rot3.Quaternion(qw, qx, qy, qz), gtsam.Point3(x, y, z))
        for x, y, z, qx, qy, qz, qw in rows.tolist()
    ]


class IncrementalSolver:
    """ISAM2 over the vertices and edges of ``problem`` added so far (module doc)."""

    def __init__(
        self,
        problem: Problem,
        agent_of_vertex: np.ndarray,
        settings: IsamSettings,
        *,
        terms: EdgeTerms | None = None,
    ) -> None:
        self._gtsam = gtsam = _gtsam()
        self.problem = problem
        self.kind = problem.kind
        self.agent_of_vertex = agent_of_vertex
        self.settings = settings
        self.terms = EdgeTerms(problem) if terms is None else terms
        params = gtsam.ISAM2Params()
        params.relinearizeSkip = int(settings.relinearize_skip)
        params.setRelinearizeThreshold(float(settings.relinearize_threshold))
        self.isam = gtsam.ISAM2(params)
        self.vertices = np.zeros(problem.num_vertices, dtype=bool)
        self.edges = np.zeros(problem.num_edges, dtype=bool)
        self.estimate = problem.initial.copy()
        """The latest estimate of every vertex added (rows of others: the dataset's initial)."""
        self._anchored = False
        self._loose_factors: set[int] = set()
        self.seconds = 0.0
        """Wall time spent in GTSAM (building factors, updates, estimates)."""

    def _pose(self, row: np.ndarray) -> Any:
        return gtsam_poses(self._gtsam, self.kind, np.asarray(row, dtype=np.float64)[None])[0]

    def _poses(self, values: Any) -> np.ndarray:
        gtsam = self._gtsam
        if self.kind is PoseKind.SE2:
            return np.asarray(gtsam.utilities.extractPose2(values), dtype=np.float64).reshape(-1, 3)
        from scipy.spatial.transform import Rotation

        m = np.asarray(gtsam.utilities.extractPose3(values), dtype=np.float64).reshape(-1, 12)
        quat = Rotation.from_matrix(m[:, 0:9].reshape(-1, 3, 3)).as_quat()
        quat[quat[:, 3] < 0] *= -1.0
        return np.column_stack([m[:, 9:12], quat])

    def dead_reckon(self, new: np.ndarray, known: np.ndarray) -> np.ndarray:
        """Starting values for vertices ``new`` (global ids, sorted): each agent's chain continued
        from its latest vertex in ``known`` (a bool mask) by the dataset's relative initial poses;
        an agent with no known vertex starts at its dataset values."""
        p = self.problem
        out = p.initial[new].copy()
        agents = self.agent_of_vertex[new]
        for a in np.unique(agents).tolist():
            rows = np.flatnonzero(agents == a)
            mine = np.flatnonzero(known & (self.agent_of_vertex == a))
            if not len(mine):
                continue
            last = int(mine[-1])
            base = compose(self.estimate[last : last + 1], inverse(p.initial[last : last + 1], self.kind), self.kind)
            out[rows] = compose(np.repeat(base, len(rows), axis=0), p.initial[new[rows]], self.kind)
        return np.asarray(out)

    def add(
        self,
        vertices: np.ndarray,
        edges: np.ndarray,
        *,
        start: np.ndarray | None = None,
        anchor_pose: np.ndarray | None = None,
        fixed: FixedEnds | None = None,
    ) -> None:
        """Add ``vertices`` and ``edges`` (global ids not yet added) in one batch and update.

        ``start`` gives their starting values (default :meth:`dead_reckon`); ``anchor_pose`` the
        pose at which the gauge is held (default: the first vertex's starting value); ``fixed``
        edges whose other end is added now or was before enter as unary factors."""
        gtsam = self._gtsam
        t0 = time.perf_counter()
        p = self.problem
        vertices = np.asarray(vertices, dtype=np.int64)
        edges = np.asarray(edges, dtype=np.int64)
        if start is None:
            start = self.dead_reckon(vertices, self.vertices)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        d = 3 if self.kind is PoseKind.SE2 else 6
        prior = gtsam.PriorFactorPose2 if self.kind is PoseKind.SE2 else gtsam.PriorFactorPose3
        for v, pose in zip(vertices.tolist(), gtsam_poses(gtsam, self.kind, start)):
            values.insert(v, pose)
        # each agent's first vertex ever added holds its gauge: the first agent's tightly
        seen_agents = set(np.unique(self.agent_of_vertex[self.vertices]).tolist())
        agents, first = np.unique(self.agent_of_vertex[vertices], return_index=True)
        loose: list[int] = []
        for k in sorted(k for a, k in zip(agents.tolist(), first.tolist()) if a not in seen_agents):
            v = int(vertices[k])
            if not self._anchored:
                pose = start[k] if anchor_pose is None else anchor_pose
                noise = gtsam.noiseModel.Isotropic.Sigma(d, TIGHT_PRIOR_SIGMA)
                self._anchored = True
            else:
                pose = start[k]
                noise = gtsam.noiseModel.Isotropic.Sigma(d, LOOSE_PRIOR_SIGMA)
                loose.append(graph.size())
            graph.add(prior(v, self._pose(pose), noise))
        factor = gtsam.BetweenFactorPose2 if self.kind is PoseKind.SE2 else gtsam.BetweenFactorPose3
        measured, noise_of = self.terms.measurements, self.terms.noise
        for f, t, e in zip(p.edge_from[edges].tolist(), p.edge_to[edges].tolist(), edges.tolist()):
            graph.add(factor(f, t, measured[e], noise_of[e]))
        if fixed is not None:
            self._add_fixed(graph, fixed)
        self.vertices[vertices] = True
        self.edges[edges] = True
        self.estimate[vertices] = start
        if graph.size() or values.size():
            result = self.isam.update(graph, values, self._unconstrained())
            indices = list(result.getNewFactorsIndices())
            self._loose_factors.update(int(indices[i]) for i in loose)
            for _ in range(self.settings.extra_updates):
                self.isam.update()
        self.seconds += time.perf_counter() - t0

    def _unconstrained(self) -> Any:
        """An update that orders the re-eliminated part by plain COLAMD. GTSAM's default puts the
        batch's new variables last, at the root, expecting the next measurements to touch only
        them; a team's batch holds every robot's newest poses and closures that reach back across
        the whole map, and that constraint made the root clique, and the separators under it,
        several times larger (docs/replay.md, "ISAM2 settings and the final polish")."""
        params = self._gtsam.ISAM2UpdateParams()
        params.constrainedKeys = self._gtsam.KeyGroupMap()
        return params

    def _add_fixed(self, graph: Any, fixed: FixedEnds) -> None:
        """The unary factors of :class:`FixedEnds` into ``graph``. GTSAM's between error is
        ``Log(z^-1 a^-1 b)``: with ``a`` held it is the prior ``a z`` on ``b`` as is; with ``b``
        held, ``-Ad(z^-1) Log((b z^-1)^-1 a)``, the prior ``b z^-1`` on ``a`` with information
        ``Ad^T omega Ad``."""
        gtsam = self._gtsam
        p = self.problem
        prior = gtsam.PriorFactorPose2 if self.kind is PoseKind.SE2 else gtsam.PriorFactorPose3
        gaussian = gtsam.noiseModel.Gaussian.Information
        edges = np.asarray(fixed.edges, dtype=np.int64)
        held_poses = gtsam_poses(gtsam, self.kind, fixed.held_poses)
        for k, e in enumerate(edges.tolist()):
            z, held = self.terms.measurements[e], held_poses[k]
            omega = self.terms.omega[e] * fixed.information_scale
            if fixed.held_is_from[k]:
                graph.add(prior(int(p.edge_to[e]), held.compose(z), gaussian(omega)))
            else:
                ad = np.asarray(z.inverse().AdjointMap())
                graph.add(prior(int(p.edge_from[e]), held.compose(z.inverse()), gaussian(ad.T @ omega @ ad)))

    def refine(self, updates: int) -> None:
        t0 = time.perf_counter()
        for _ in range(updates):
            self.isam.update()
        self.seconds += time.perf_counter() - t0

    def polish(self, max_iterations: int = 10) -> None:
        """Gauss-Newton on every factor added, from ISAM2's estimate; the result is :attr:`estimate`.
        The last call on a solver: ISAM2 is let go before the Gauss-Newton runs (its Bayes tree is
        most of a replay's memory, which the batch system's factors then reuse), so no update may
        follow."""
        gtsam = self._gtsam
        t0 = time.perf_counter()
        ids = np.flatnonzero(self.vertices)
        if len(ids):
            params = gtsam.GaussNewtonParams()
            params.setMaxIterations(max_iterations)
            params.setRelativeErrorTol(1e-9)
            held = self.isam.getFactorsUnsafe()
            start = self.isam.calculateEstimate()
            # without the loose priors when the graph holds together without them: the batch optimum
            tight, every = gtsam.NonlinearFactorGraph(), gtsam.NonlinearFactorGraph()
            for k in range(held.size()):
                if held.exists(k):
                    every.add(held.at(k))
                    if k not in self._loose_factors:
                        tight.add(held.at(k))
            # ``held`` keeps the ISAM2 alive (pybind ties it to its owner): the factors go into graphs
            # of their own, then both go
            del held
            self.isam = None
            try:
                result = gtsam.GaussNewtonOptimizer(tight, start, params).optimize()
            except RuntimeError:  # robots no closure ties to the first one: keep their priors
                result = gtsam.GaussNewtonOptimizer(every, start, params).optimize()
            self.estimate[ids] = self._poses(result)
        self.seconds += time.perf_counter() - t0

    def solve(self) -> np.ndarray:
        """The current estimate of the added vertices (rows in global id order), stored in
        :attr:`estimate` too."""
        t0 = time.perf_counter()
        ids = np.flatnonzero(self.vertices)
        if len(ids):
            self.estimate[ids] = self._poses(self.isam.calculateEstimate())
        self.seconds += time.perf_counter() - t0
        return np.asarray(self.estimate[ids])
