"""The ``dgs`` method: Distributed Gauss-Seidel (Choudhary et al., "Distributed mapping with privacy
and communication constraints: lightweight algorithms and object-based models", IJRR 2017), the
two-stage distributed pose-graph optimizer of DOOR-SLAM's back-end, on columns with scipy.sparse.

Each robot owns the vertices of one agent and solves only its own block of a linear system, holding
its neighbours' latest estimates of the vertices they share an edge with (the *separators*) fixed;
it then sends its own separator values to each neighbour. One *round* is every robot doing that once:
in robot order, each using the values its predecessors sent in the same round (``"gauss-seidel"``), or
all from the previous round's values (``"jacobi"``). The new block is over-relaxed,
``x <- (1 - gamma) x + gamma x_new`` (``gamma = 1``: plain Gauss-Seidel/Jacobi, the paper's default;
the pose stage defaults to 1.9, which converged fastest of 1, 1.3, 1.6 and 1.9 on kollagen's graphs).
With a *momentum* ``beta`` each robot first extrapolates its own block, ``x + beta (x - x_prev)``
(Nesterov), and solves from there; its neighbours receive the result as usual: no extra message.
The rotation stage's Gauss-Seidel rounds default to 0.9 (on Multi3500x8 it halves the rotations'
distance to the chordal solution after 100 rounds), the pose stage's to none (it diverges there).

1. **Rotation stage (chordal relaxation).** Every edge ``i -> j`` with measured rotation ``Z`` asks
   ``R_j = R_i Z``, i.e. ``R_j^T - Z^T R_i^T = 0``: linear in the entries of ``Y = R^T``, the ``d``
   columns of ``Y`` separate problems sharing one matrix. Weights are the edge's rotation information
   (its mean diagonal in 3D); the anchor's rotation is fixed. Each ``Y_i^T`` projected onto SO(d)
   (SVD) is the rotation estimate; the rounds stop when no entry of an estimated rotation matrix
   changes by more than ``rotation_tol`` (0.2: the paper's 1e-2 leaves the pose stage, where the
   estimate improves most, 16 rounds of 100 on kollagen's Multi3500x8; docs/replay.md).
2. **Pose stage.** Gauss-Newton on the full poses, linearized at the estimated rotations with every
   translation at the anchor's (the paper's single linearization point; ``warm_start`` keeps the
   given translations instead). Each Gauss-Newton system is solved by the same distributed rounds
   without holding the anchor (its gauge, a rigid motion of everyone, costs nothing; held by one
   vertex only it is the slowest mode of the rounds: on kollagen's tiny_shared_entry 171 rounds
   instead of more than 1000), the estimate then moved rigidly onto the anchor's pose (Jacobi rounds
   hold the anchor: on the singular system they would oscillate in the gauge). A system's
   rounds stop when no entry of the update changes by more than ``pose_tol``; then the poses are
   updated and relinearized (each robot can do that for its neighbours' separators with the updates it
   received), until an update moves no entry by more than ``pose_tol`` or the rounds run out. The
   paper stops after one linearization; here later ones are allowed because the first leaves the
   translation-rotation coupling of the inter-robot closures unresolved.

Errors are g2o's (planar: ``[D.x, D.y, D.theta]``; spatial: translation and the rotation vector of
``D.R``, the files' half-angle rotation information scaled as in ``gtsam_method``); planar poses are
updated additively, spatial ones by ``t <- t + dt``, ``R <- Exp(dphi) R``. Each robot's block is
factorised once per linear system (:func:`~studio.solvers.spd.spd_factor`) and reused across that
system's rounds; a stage works out once where its systems' numbers go (:class:`_Layout`,
:class:`_Pieces`) and factors each relinearization's blocks in place of the last's (same pattern,
same ordering).

Communication is counted as the paper's messages: per round, each robot sends each neighbour its
separator values (``d*d`` numbers per vertex in the rotation stage, 3 or 6 in the pose stage, plus
one pose per separator when the pose stage starts), 8 bytes a number.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from studio.core.errors import ConfigError, GraphError
from studio.core.geometry import normalize_angle, upper_to_matrix
from studio.core.model import PoseKind
from studio.solvers.options import (
    DEFAULT_COARSE_SIZE,
    DEFAULT_MAX_ROUNDS,
    DEFAULT_POSE_GAMMA,
    DEFAULT_POSE_MOMENTUM,
    DEFAULT_POSE_TOL,
    DEFAULT_ROTATION_GAMMA,
    DEFAULT_ROTATION_MOMENTUM,
    DEFAULT_ROTATION_TOL,
    DEFAULT_SCHEDULE,
    PLAIN_POSE_GAMMA,
    DgsOptions,
    Schedule,
)
from studio.solvers.problem import Iteration, Problem, Solution, SolveOptions, graph_chi2
from studio.solvers.spd import spd_factor

__all__ = [
    "Schedule",
    "DgsRound",
    "DgsResult",
    "dgs_rounds",
    "solve_dgs",
    "contiguous_robots",
    "DEFAULT_MAX_ROUNDS",
    "DEFAULT_ROTATION_TOL",
    "DEFAULT_POSE_TOL",
    "DEFAULT_ROTATION_GAMMA",
    "DEFAULT_POSE_GAMMA",
    "PLAIN_POSE_GAMMA",
    "DEFAULT_ROTATION_MOMENTUM",
    "DEFAULT_POSE_MOMENTUM",
    "DEFAULT_COARSE_SIZE",
    "BYTES_PER_NUMBER",
]

Stage = Literal["rotation", "pose"]

#: Bytes of one number in a message (float64).
BYTES_PER_NUMBER = 8


@dataclass(frozen=True)
class DgsRound:
    """One round: every robot solved its block once and sent its separators."""

    round: int
    """1-based, over both stages."""
    stage: Stage
    change: float
    """Largest change of an entry of the stage's unknowns in this round."""
    chi2: float | None
    """Pose stage: chi2 (g2o convention) of the current estimate; None in the rotation stage and
    where the caller did not ask for it (``dgs_rounds(score_rounds=False)``)."""
    bytes_sent: int
    """Bytes all robots sent in this round."""


@dataclass(frozen=True, eq=False)
class DgsResult:
    poses: np.ndarray
    """The estimate, same layout as the problem's poses."""
    rounds: tuple[DgsRound, ...]
    rotation_rounds: int
    pose_rounds: int
    linearizations: int
    """Gauss-Newton systems built in the pose stage."""
    converged: bool
    """Both stages met their tolerance within ``max_rounds``."""
    robots: int
    bytes_per_robot: np.ndarray
    """``(robots,)`` bytes each robot sent in total."""
    bytes_per_link: np.ndarray
    """``(robots, robots)``: ``[a, b]`` bytes robot a sent to robot b."""
    chi2_initial: float
    """chi2 of the pose stage's first linearization point."""
    seconds: float

    @property
    def num_rounds(self) -> int:
        return len(self.rounds)

    @property
    def chi2_history(self) -> tuple[float, ...]:
        """chi2 of the first linearization point, then after each pose-stage round."""
        return (self.chi2_initial, *(r.chi2 for r in self.rounds if r.chi2 is not None))

    def links(self) -> dict[str, int]:
        """Bytes per directed link ``"a->b"`` (robot indices), the links that carried any."""
        a, b = np.nonzero(self.bytes_per_link)
        return {f"{int(i)}->{int(j)}": int(self.bytes_per_link[i, j]) for i, j in zip(a, b)}


OnRound = Callable[[DgsRound, "np.ndarray | None"], None]


def contiguous_robots(num_vertices: int, robots: int) -> np.ndarray:
    """DPGO's split of a single g2o: ``robots`` contiguous runs of vertex ids, sizes differing by one at most."""
    if isinstance(robots, bool) or not isinstance(robots, int) or not 1 <= robots <= num_vertices:
        raise ConfigError(f"robots: expected an integer in 1..{num_vertices}, got {robots!r}")
    return (np.arange(num_vertices, dtype=np.int64) * robots) // num_vertices


# --------------------------------------------------------------------------------------------------
# sparse assembly and the distributed block solve


@dataclass(eq=False)
class _Layout:
    """Where the numbers of ``sum_e J_e^T Omega_e J_e`` over a problem's edges go (``b`` unknowns
    per vertex), found once: each linear system of a stage then only adds its numbers up, and each
    robot's pieces of the matrix are gathered by :class:`_Take` instead of sliced."""

    size: int
    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray
    """The place in the matrix's data of each number :func:`_products` gives, in its order."""

    def data(self, products: np.ndarray) -> np.ndarray:
        """The matrix's numbers (CSR order) from :func:`_products`'."""
        return np.bincount(self.slot, weights=products, minlength=len(self.indices))

    def rows(self) -> np.ndarray:
        """The row of each entry of the matrix's data."""
        return np.repeat(np.arange(self.size, dtype=np.int64), np.diff(self.indptr))


def _layout(fr: np.ndarray, to: np.ndarray, n: int, b: int) -> _Layout:
    """The layout of the products of edges ``fr -> to`` over ``n`` vertices: the vertex blocks they
    touch (each row's in column order, so the scalar pattern's too) and where each product's numbers
    land. A row's blocks are its pairs with smaller vertices, its diagonal, its pairs with larger
    ones: one sort of the distinct pairs places them all (the upper ones in its order, the lower
    ones in a stable sort of it by their larger vertex)."""
    import scipy.sparse as sp

    m = len(fr)
    lo, hi = np.minimum(fr, to), np.maximum(fr, to)
    pairs, pair_of = np.unique(lo * n + hi, return_inverse=True)
    pair_lo, pair_hi = pairs // n, pairs % n
    apart = pair_lo != pair_hi  # a self-loop's pair is its vertex's diagonal block
    upper_row, lower_row = pair_lo[apart], pair_hi[apart]
    touched = np.zeros(n, dtype=np.int64)
    touched[fr] = 1
    touched[to] = 1
    uppers = np.bincount(upper_row, minlength=n)
    lowers = np.bincount(lower_row, minlength=n)
    block_ptr = np.concatenate([[0], np.cumsum(lowers + touched + uppers)])
    diagonal = block_ptr[:-1] + lowers
    k = np.arange(len(upper_row))
    upper = diagonal[upper_row] + touched[upper_row] + k - (np.cumsum(uppers) - uppers)[upper_row]
    by_lower = np.argsort(lower_row, kind="stable")
    lower = np.empty_like(upper)
    lower[by_lower] = block_ptr[lower_row[by_lower]] + k - (np.cumsum(lowers) - lowers)[lower_row[by_lower]]
    columns = np.empty(int(block_ptr[-1]), dtype=np.int64)
    columns[diagonal[touched > 0]] = np.flatnonzero(touched)
    columns[upper], columns[lower] = lower_row, upper_row
    # each edge's four blocks [from, to] x [from, to]
    blocks = np.empty((m, 2, 2), dtype=np.int64)
    blocks[:, 0, 0] = blocks[:, 0, 1] = blocks[:, 1, 0] = diagonal[fr]
    blocks[:, 1, 1] = diagonal[to]
    e = np.flatnonzero(apart[pair_of])
    q = (np.cumsum(apart) - 1)[pair_of[e]]  # the edge's pair among those apart
    ahead = fr[e] < to[e]
    blocks[e, 0, 1] = np.where(ahead, upper[q], lower[q])
    blocks[e, 1, 0] = np.where(ahead, lower[q], upper[q])
    # entry (i, j) of block k of block row v: row v * b + i, which starts at b * b * block_ptr[v] +
    # i * b * degree(v), at (k - block_ptr[v]) * b + j in it
    degree = np.diff(block_ptr)
    rows = np.stack([fr, to], axis=1)
    start = b * b * block_ptr[rows][:, :, None] + (blocks - block_ptr[rows][:, :, None]) * b  # (m, 2, 2)
    step = b * degree[rows]  # (m, 2): the length of a scalar row of the block row
    i = np.arange(b)
    slot = start[:, :, None, :, None] + step[:, :, None, None, None] * i[None, None, :, None, None] + i
    pattern = sp.bsr_matrix((np.zeros((len(columns), b, b)), columns, block_ptr), shape=(n * b, n * b)).tocsr()
    return _Layout(n * b, pattern.indptr, pattern.indices, slot.reshape(-1))


def _products(jacobians: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``J^T Omega J`` of each edge, ``J = [J_from, J_to]`` its Jacobian blocks of shape (m, r,
    2b), raveled (the order of :attr:`_Layout.slot`)."""
    return np.asarray((np.transpose(jacobians, (0, 2, 1)) @ (omega @ jacobians)).reshape(-1))


@dataclass(eq=False)
class _Take:
    """A piece of a layout's matrix: its pattern and where its numbers are in the whole's data."""

    pattern: Any
    take: np.ndarray

    def of(self, data: np.ndarray) -> Any:
        p = self.pattern
        return type(p)((data[self.take], p.indices, p.indptr), shape=p.shape)


def _gradient(
    fr: np.ndarray, to: np.ndarray, jacobians: np.ndarray, omega: np.ndarray, e0: np.ndarray, n: int
) -> np.ndarray:
    """``-sum_e J_e^T Omega_e e_e`` as a vector of length ``n * b`` (Jacobians as in :func:`_products`)."""
    b = jacobians.shape[2] // 2
    each = (np.transpose(jacobians, (0, 2, 1)) @ (omega @ e0[:, :, None]))[:, :, 0]
    rows = (np.concatenate([fr, to])[:, None] * b + np.arange(b)[None, :]).ravel()
    return -np.bincount(rows, weights=np.concatenate([each[:, :b], each[:, b:]]).ravel(), minlength=n * b)


@dataclass(eq=False)
class _Coarse:
    """The two-level correction of a linear system ``h x = g``: ``x[free] += P (P^T h P)^-1 P^T r``
    with the residual ``r = g - h x`` on the free unknowns, ``P`` the coarse space's columns."""

    free: np.ndarray
    matrix: Any
    """``h`` (csr; its free rows give the residual, row by row as ``h[free]`` would)."""
    basis: Any
    """``P``: ``(len(free), m)`` (csr)."""
    lu: Any
    per_robot: np.ndarray
    """``(robots, 2)``: coarse unknowns of each robot's vertices, entries of their coarse rows (of
    its structure: a number that happens to cancel to zero is sent too)."""

    def correct(self, x: np.ndarray, g: np.ndarray) -> None:
        """``x`` (in place) moved by the coarse system's solution for its residual."""
        r = (g - self.matrix @ x)[self.free]
        x[self.free] += self.basis @ self.lu.solve(np.asarray(self.basis.T @ r))


@dataclass(eq=False)
class _Blocks:
    """Each robot's free unknowns, its factorised diagonal block and its coupling to the rest."""

    dofs: list[np.ndarray]
    others: list[np.ndarray]
    lus: list[Any]
    couplings: list[Any]
    coarse: _Coarse | None = None


@dataclass(eq=False)
class _CoarseSpace:
    """A stage's coarse space: runs of ``size`` consecutive free vertices of one robot
    (*aggregates*), ``c`` coarse unknowns each, a free vertex's ``b`` unknowns tied to its
    aggregate's by a ``(b, c)`` block of ``P``. The coarse matrix ``P^T h P`` is the sum over the
    edges of ``(J_e P_e)^T Omega_e (J_e P_e)``, so a layout over the aggregates adds it up as the
    fine one adds ``h``: its pattern is every entry those products can give, whatever the numbers
    (some cancel to zero, and which ones depends on the order of the arithmetic), the same for
    every system of the stage: its factor is ordered once and each robot sends its rows of it."""

    vertex: np.ndarray
    """Each free vertex's id, in the order of the robots' unknowns concatenated."""
    aggregate: np.ndarray
    """Each free vertex's aggregate."""
    count: int
    c: int
    edges: np.ndarray
    """The edges with a free end; each end's place in :attr:`vertex` (-1 where held) below."""
    at_from: np.ndarray
    at_to: np.ndarray
    layout: _Layout
    upper: _Take
    """The coarse matrix's upper triangle (csc) in the layout's data."""
    diagonal: np.ndarray
    """The places of the coarse matrix's diagonal in the layout's data."""
    basis_indices: np.ndarray
    """Column indices of ``P`` (csr, each free vertex's rows a full ``(b, c)`` block)."""
    per_robot: np.ndarray
    """As :attr:`_Coarse.per_robot`."""
    pinned: np.ndarray
    """The free vertices (places in :attr:`vertex`) of the anchor's aggregate where the anchor is
    free (an anchor-free system, singular in the gauge), else none: their aggregate is held still,
    which takes the gauge, a rigid motion of everyone, out of the coarse system."""
    pinned_diagonal: np.ndarray
    """The places in the layout's data of the held aggregate's diagonal."""
    factors: list[Any] = field(default_factory=list)


def _coarse_space(
    fr: np.ndarray, to: np.ndarray, n: int, robot_dofs: list[np.ndarray], b: int, c: int, size: int, anchor: int
) -> _CoarseSpace | None:
    """The coarse space over the robots' free unknowns ``robot_dofs`` (``b`` per vertex) of a stage
    whose edges are ``fr -> to`` over ``n`` vertices and whose gauge is held by vertex ``anchor``
    (if it is free); None with ``size`` 0 or no free unknowns."""
    if not size:
        return None
    aggregate, vertex, count = _aggregates(robot_dofs, b, size)
    if not count:
        return None
    place = np.full(n, -1, dtype=np.int64)
    place[vertex] = np.arange(len(vertex))
    at_from, at_to = place[fr], place[to]
    edges = np.flatnonzero((at_from >= 0) | (at_to >= 0))
    at_from, at_to = at_from[edges], at_to[edges]
    # a held end adds nothing but to the free end's own block: it stands at the free end's aggregate
    a_from = np.where(at_from >= 0, aggregate[at_from], aggregate[at_to])
    a_to = np.where(at_to >= 0, aggregate[at_to], aggregate[at_from])
    layout = _layout(a_from, a_to, count, c)
    row = layout.rows()
    lower = np.flatnonzero(layout.indices <= row)  # as csc: the upper triangle (see _pieces)
    upper = _compressed("csc", lower, row[lower], layout.indices[lower], (layout.size, layout.size))
    diagonal = np.flatnonzero(layout.indices == row)
    if len(diagonal) != layout.size:
        raise GraphError("dgs: a run of a robot's poses has no edge; is every robot tied to the graph?")
    per_row = np.diff(layout.indptr)
    robots = len(robot_dofs)
    first = np.cumsum([0] + [len(d) // b for d in robot_dofs])
    owner = np.repeat(np.arange(robots), np.diff(first))
    owner_of_aggregate = np.zeros(count, dtype=np.int64)
    owner_of_aggregate[aggregate] = owner
    per_robot = np.zeros((robots, 2), dtype=np.int64)
    per_robot[:, 0] = np.bincount(owner_of_aggregate, minlength=robots) * c
    per_robot[:, 1] = np.bincount(np.repeat(owner_of_aggregate, c), weights=per_row, minlength=robots).astype(np.int64)
    basis_indices = np.repeat(aggregate * c, b)[:, None] + np.arange(c)[None, :]
    pinned = np.zeros(0, dtype=np.int64)
    pinned_diagonal = np.zeros(0, dtype=np.int64)
    if place[anchor] >= 0:
        held = aggregate[place[anchor]]
        pinned = np.flatnonzero(aggregate == held)
        pinned_diagonal = diagonal[held * c : (held + 1) * c]
    return _CoarseSpace(
        vertex,
        aggregate,
        count,
        c,
        edges,
        at_from,
        at_to,
        layout,
        upper,
        diagonal,
        basis_indices.ravel(),
        per_robot,
        pinned,
        pinned_diagonal,
    )


def _compressed(kind: str, take: np.ndarray, major: np.ndarray, minor: np.ndarray, shape: tuple[int, int]) -> _Take:
    """The piece holding the entries ``take`` of a layout's data, each in compressed ``kind``
    (``"csr"`` or ``"csc"``) row or column ``major`` and at ``minor`` in it, ``take`` ordered by
    ``major`` and then ``minor``."""
    import scipy.sparse as sp

    indptr = np.concatenate([[0], np.cumsum(np.bincount(major, minlength=shape[0 if kind == "csr" else 1]))])
    make = sp.csr_matrix if kind == "csr" else sp.csc_matrix
    return _Take(make((np.zeros(len(take)), minor, indptr), shape=shape), take)


def _coarse(pieces: _Pieces, data: np.ndarray, jacobians: np.ndarray, omega: np.ndarray, blocks: np.ndarray) -> _Coarse:
    """The two-level correction of the linear system with ``data`` (of the pieces' layout), from
    the edges' Jacobian blocks and information (as :func:`_products`) and ``P``'s ``(b, c)`` block
    of each free vertex (the order of :attr:`_CoarseSpace.vertex`)."""
    import scipy.sparse as sp

    space = pieces.coarse
    assert space is not None
    b, c = jacobians.shape[2] // 2, space.c
    padded = np.concatenate([blocks, np.zeros((1, b, c))])  # place -1, a held end: no coarse unknowns
    # the anchor-free system's gauge: the anchor's aggregate does not move (zero columns of P), its
    # coarse unknowns stand alone with a unit diagonal and a zero right-hand side
    padded[space.pinned] = 0.0
    every = len(space.edges) == len(jacobians)  # no edge between held vertices: no copies to take
    jac = jacobians if every else jacobians[space.edges]
    coarse_jacobians = np.empty((len(jac), jac.shape[1], 2 * c))
    np.matmul(jac[:, :, :b], padded[space.at_from], out=coarse_jacobians[:, :, :c])
    np.matmul(jac[:, :, b:], padded[space.at_to], out=coarse_jacobians[:, :, c:])
    hc = space.layout.data(_products(coarse_jacobians, omega if every else omega[space.edges]))
    hc[space.pinned_diagonal] = 1.0
    try:
        lu = _factor(space.factors, 0, space.upper.of(hc), supernodal=True)
    except RuntimeError as err:  # SuperLU's "Factor is exactly singular", QDLDL's zero pivot
        raise GraphError(f"dgs: the coarse system is singular ({err}); is every robot tied to the graph?") from None
    rows = blocks.shape[0] * b
    indptr = np.arange(0, rows * c + 1, c)
    basis = sp.csr_matrix((padded[:-1].ravel(), space.basis_indices, indptr), shape=(rows, space.count * c))
    layout = pieces.layout
    matrix = sp.csr_matrix((data, layout.indices, layout.indptr), shape=(layout.size, layout.size))
    return _Coarse(pieces.free, matrix, basis, lu, space.per_robot)


@dataclass(eq=False)
class _Pieces:
    """A stage's robots' pieces of its layout's matrix: each robot's block (upper triangle) and
    coupling to the rest; and the factors of the stage's last system, factored again in place for
    the next (same pattern, same ordering)."""

    layout: _Layout
    dofs: list[np.ndarray]
    free: np.ndarray
    """The robots' free unknowns, ``dofs`` concatenated."""
    others: list[np.ndarray]
    """Each robot's coupled unknowns: the others its block's rows reach."""
    blocks: list[_Take]
    couplings: list[_Take]
    factors: list[Any]
    coarse: _CoarseSpace | None = None


def _pieces(layout: _Layout, robot_dofs: list[np.ndarray]) -> _Pieces:
    """Each robot's pieces of ``layout``'s matrix (``robot_dofs`` sorted), picked from its data by
    which robot each entry's row and column belong to: its block's upper triangle (csc) is its
    lower triangle's entries as the csr data holds them (a column of the one is a row of the other)."""
    size, col = layout.size, layout.indices
    row = layout.rows()
    robots = len(robot_dofs)
    owner = np.full(size, robots, dtype=np.int16)  # ``robots``: a held unknown
    position = np.zeros(size, dtype=np.int64)
    for r, dofs in enumerate(robot_dofs):
        owner[dofs] = r
        position[dofs] = np.arange(len(dofs))
    orow, ocol = owner[row], owner[col]
    inside = _by_robot(np.flatnonzero((orow == ocol) & (orow < robots) & (col <= row)), orow, robots)
    across = _by_robot(np.flatnonzero((orow != ocol) & (orow < robots)), orow, robots)
    blocks, couplings, others = [], [], []
    for r, dofs in enumerate(robot_dofs):
        take = inside[r]
        blocks.append(_compressed("csc", take, position[row[take]], position[col[take]], (len(dofs), len(dofs))))
        take = across[r]
        reached = np.zeros(size, dtype=bool)  # the unknowns its rows reach: its neighbours' separators
        reached[col[take]] = True
        others.append(np.flatnonzero(reached))
        at = np.cumsum(reached) - 1
        shape = (len(dofs), len(others[-1]))
        couplings.append(_compressed("csr", take, position[row[take]], at[col[take]], shape))
    free = np.concatenate(robot_dofs) if robot_dofs else np.zeros(0, dtype=np.int64)
    return _Pieces(layout, list(robot_dofs), free, others, blocks, couplings, [])


def _stage_pieces(run: _Run, b: int, fix_anchor: bool = True) -> _Pieces:
    """A stage's layout (``b`` unknowns per vertex), its robots' pieces and its coarse space."""
    problem = run.problem
    fr, to, n = problem.edge_from, problem.edge_to, problem.num_vertices
    pieces = _pieces(_layout(fr, to, n, b), run.dofs_of(b, fix_anchor=fix_anchor))
    pieces.coarse = _coarse_space(fr, to, n, pieces.dofs, b, b, run.coarse_size, problem.anchor)
    return pieces


def _by_robot(entries: np.ndarray, owner: np.ndarray, robots: int) -> list[np.ndarray]:
    """``entries`` split by ``owner[entries]`` (``0..robots-1``), each part in the order given."""
    whose = owner[entries]
    order = np.argsort(whose, kind="stable")
    counts = np.bincount(whose, minlength=robots)[:robots]
    return np.split(entries[order], np.cumsum(counts)[:-1])


def _factor(factors: list[Any], k: int, a: Any, supernodal: bool = False) -> Any:
    """Factor ``k`` of ``factors`` for ``a`` (the upper triangle): the one there factored again, or
    a new one (``supernodal``: one that fills in, see :func:`~studio.solvers.spd.spd_factor`)."""
    if k < len(factors):
        factors[k].update(a)
    else:
        factors.append(spd_factor(a, permc_spec="COLAMD", upper=True, supernodal=supernodal))
    return factors[k]


def _aggregates(robot_dofs: list[np.ndarray], b: int, size: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Each free vertex's aggregate (runs of ``size`` consecutive free vertices of one robot) and
    its vertex id, in the order of ``robot_dofs`` concatenated; the number of aggregates."""
    agg, verts, count = [], [], 0
    for dofs in robot_dofs:
        v = dofs[::b] // b
        k = np.arange(len(v)) // size
        agg.append(count + k)
        verts.append(v)
        count += int(k[-1]) + 1 if len(v) else 0
    if not agg:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), 0
    return np.concatenate(agg), np.concatenate(verts), count


def _rigid_blocks(kind: PoseKind, lin: np.ndarray, space: _CoarseSpace) -> np.ndarray:
    """Each aggregate moved rigidly: a translation and a rotation about its centroid (3 coarse
    unknowns in the plane, 6 in space), in the pose stage's update coordinates at ``lin``: each
    free vertex's ``(b, b)`` block of ``P``."""
    agg, count = space.aggregate, space.count
    tw = 2 if kind is PoseKind.SE2 else 3
    t = lin[space.vertex, 0:tw]
    centre = np.zeros((count, tw))
    np.add.at(centre, agg, t)
    centre /= np.maximum(np.bincount(agg, minlength=count), 1)[:, None]
    rel = t - centre[agg]
    b = 3 if kind is PoseKind.SE2 else 6
    out = np.zeros((len(agg), b, b))
    out[:, np.arange(b), np.arange(b)] = 1.0
    if kind is PoseKind.SE2:  # rotation w about the centroid: dx = -w ry, dy = w rx, dtheta = w
        out[:, 0, 2], out[:, 1, 2] = -rel[:, 1], rel[:, 0]
    else:  # dphi = w, dt = w x rel = -[rel]x w
        out[:, 0:3, 3:6] = -_skew(rel)
    return out


def _factorise(data: np.ndarray, pieces: _Pieces) -> _Blocks:
    """Each robot's block of the matrix with ``data`` (of the pieces' layout) factored."""
    lus = []
    for k, block in enumerate(pieces.blocks):
        try:
            lus.append(_factor(pieces.factors, k, block.of(data)))
        except RuntimeError as err:  # SuperLU's "Factor is exactly singular", QDLDL's zero pivot
            raise GraphError(f"dgs: a robot's block is singular ({err}); is every robot tied to the graph?") from None
    return _Blocks(pieces.dofs, pieces.others, lus, [c.of(data) for c in pieces.couplings])


def _round(
    x: np.ndarray,
    g: np.ndarray,
    blocks: _Blocks,
    schedule: Schedule,
    gamma: float,
    previous: np.ndarray | None = None,
    momentum: float = 0.0,
) -> float:
    """One round in place on ``x`` (``(N,)`` or ``(N, k)``); returns the largest change of an entry.

    With ``momentum`` (and ``previous``, the iterate before this one, updated here), every robot
    first extrapolates its own block, ``x + momentum (x - previous)`` (Nesterov), and its
    neighbours use the extrapolated values: each robot still needs only its own and its neighbours'
    latest values."""
    extrapolate = bool(momentum) and previous is not None
    # the change is measured against the iterate before the round when the blocks' own changes
    # do not tell it (extrapolated, or moved by the coarse correction afterwards)
    before = x.copy() if extrapolate or blocks.coarse is not None else None
    if extrapolate and previous is not None and before is not None:
        x += momentum * (x - previous)
        previous[:] = before
    source = x if schedule == "gauss-seidel" else x.copy()
    change = 0.0
    for dofs, other, lu, coupling in zip(blocks.dofs, blocks.others, blocks.lus, blocks.couplings):
        if len(dofs) == 0:
            continue
        rhs = g[dofs] - coupling @ source[other]
        new = lu.solve(np.asarray(rhs))
        if gamma != 1.0:
            new = (1.0 - gamma) * x[dofs] + gamma * new
        change = max(change, float(np.abs(new - x[dofs]).max()))
        x[dofs] = new
    if blocks.coarse is not None:
        blocks.coarse.correct(x, g)
    if before is not None:
        change = float(np.abs(x - before).max()) if x.size else 0.0
    return change


# --------------------------------------------------------------------------------------------------
# geometry on columns


def _rotations(kind: PoseKind, poses: np.ndarray) -> np.ndarray:
    """``(n, d, d)`` rotation matrices of planar or spatial pose rows."""
    if kind is PoseKind.SE2:
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        return np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_quat(poses[:, 3:7]).as_matrix())


def _project_so(m: np.ndarray) -> np.ndarray:
    """The nearest rotation to each ``(d, d)`` matrix (planar: in closed form; else SVD, determinant +1)."""
    if m.shape[1] == 2:
        theta = np.arctan2(m[:, 1, 0] - m[:, 0, 1], m[:, 0, 0] + m[:, 1, 1])
        c, s = np.cos(theta), np.sin(theta)
        return np.stack([np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)
    u, _, vt = np.linalg.svd(m)
    det = np.linalg.det(u @ vt)
    u[:, :, -1] *= np.where(det < 0, -1.0, 1.0)[:, None]
    return np.asarray(u @ vt)


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(len(v))
    return np.stack(
        [np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1), np.stack([-v[:, 1], v[:, 0], z], 1)],
        axis=1,
    )


def _jr_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse right Jacobian of SO(3) at rotation vectors ``phi`` (m, 3)."""
    theta = np.linalg.norm(phi, axis=1)
    k = _skew(phi)
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    coef = np.where(small, 1.0 / 12.0, 1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)))
    return np.asarray(np.eye(3)[None] + 0.5 * k + coef[:, None, None] * (k @ k))


def _rotation_weights(problem: Problem) -> np.ndarray:
    d = 3 if problem.kind is PoseKind.SE2 else 6
    omega = upper_to_matrix(problem.information_upper, d)
    if problem.kind is PoseKind.SE2:
        w = omega[:, 2, 2]
    else:
        w = np.trace(omega[:, 3:6, 3:6], axis1=1, axis2=2) / 3.0
    return np.asarray(np.maximum(w, 0.0))


def _pose_information(problem: Problem) -> np.ndarray:
    """Per edge, the information of the pose stage's errors (spatial: the files' half-angle
    rotation information scaled to the rotation vector's)."""
    if problem.kind is PoseKind.SE2:
        return upper_to_matrix(problem.information_upper, 3)
    half = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
    return np.asarray(upper_to_matrix(problem.information_upper, 6) * half[None, :, None] * half[None, None, :])


def _pose_linearization(problem: Problem, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per edge: the Jacobian ``[J_from, J_to]`` (m, r, 2b) of the error w.r.t. the two poses and
    the error."""
    fr, to, z = problem.edge_from, problem.edge_to, problem.measurements
    m = len(fr)
    if problem.kind is PoseKind.SE2:
        xi, xj = poses[fr], poses[to]
        ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
        cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
        dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
        ux, uy = ci * dx + si * dy, -si * dx + ci * dy
        rx, ry = ux - z[:, 0], uy - z[:, 1]
        e0 = np.column_stack([cz * rx + sz * ry, -sz * rx + cz * ry, normalize_angle(xj[:, 2] - xi[:, 2] - z[:, 2])])
        rzt = np.stack([np.stack([cz, sz], 1), np.stack([-sz, cz], 1)], axis=1)  # Rz^T
        rit = np.stack([np.stack([ci, si], 1), np.stack([-si, ci], 1)], axis=1)  # Ri^T
        a = rzt @ rit
        jacobians = np.zeros((m, 3, 6))
        ji, jj = jacobians[:, :, 0:3], jacobians[:, :, 3:6]
        ji[:, 0:2, 0:2] = -a
        jj[:, 0:2, 0:2] = a
        ji[:, 0:2, 2] = np.einsum("mij,mj->mi", rzt, np.column_stack([uy, -ux]))
        ji[:, 2, 2] = -1.0
        jj[:, 2, 2] = 1.0
        return jacobians, e0
    from scipy.spatial.transform import Rotation

    ri = Rotation.from_quat(poses[fr, 3:7])
    rj = Rotation.from_quat(poses[to, 3:7])
    rz = Rotation.from_quat(z[:, 3:7])
    d = poses[to, 0:3] - poses[fr, 0:3]
    rit = ri.inv().as_matrix()
    rzt = rz.inv().as_matrix()
    a = rzt @ rit
    e_t = np.einsum("mij,mj->mi", a, d) - rz.inv().apply(z[:, 0:3])
    e_r = (rz.inv() * ri.inv() * rj).as_rotvec()
    jinv = _jr_inv(e_r)
    rjt = rj.inv().as_matrix()
    jacobians = np.zeros((m, 6, 12))
    ji, jj = jacobians[:, :, 0:6], jacobians[:, :, 6:12]
    ji[:, 0:3, 0:3] = -a
    jj[:, 0:3, 0:3] = a
    ji[:, 0:3, 3:6] = a @ _skew(d)
    ji[:, 3:6, 3:6] = -jinv @ rjt
    jj[:, 3:6, 3:6] = jinv @ rjt
    return jacobians, np.column_stack([e_t, e_r])


def _retract(kind: PoseKind, poses: np.ndarray, delta: np.ndarray) -> np.ndarray:
    if kind is PoseKind.SE2:
        out = poses + delta
        out[:, 2] = normalize_angle(out[:, 2])
        return np.asarray(out)
    from scipy.spatial.transform import Rotation

    q = (Rotation.from_rotvec(delta[:, 3:6]) * Rotation.from_quat(poses[:, 3:7])).as_quat()
    q[q[:, 3] < 0] *= -1.0
    return np.column_stack([poses[:, 0:3] + delta[:, 0:3], q])


def _reanchor(kind: PoseKind, poses: np.ndarray, anchor: int, target: np.ndarray) -> np.ndarray:
    """``poses`` moved by the one rigid transform that puts vertex ``anchor`` on ``target``."""
    from studio.core.geometry import quat_conj, quat_mul, quat_rotate

    a = poses[anchor]
    if kind is PoseKind.SE2:
        dth = target[2] - a[2]
        c, s = np.cos(dth), np.sin(dth)
        xy = (poses[:, 0:2] - a[0:2]) @ np.array([[c, s], [-s, c]]) + target[0:2]
        out = np.column_stack([xy, normalize_angle(poses[:, 2] + dth)])
    else:
        dq = np.repeat(quat_mul(target[None, 3:7], quat_conj(a[None, 3:7])), len(poses), axis=0)
        q = quat_mul(dq, poses[:, 3:7])
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        q[q[:, 3] < 0] *= -1.0
        out = np.column_stack([quat_rotate(dq, poses[:, 0:3] - a[0:3]) + target[0:3], q])
    out[anchor] = target
    return out


def _with_rotations(kind: PoseKind, translations: np.ndarray, rot: np.ndarray) -> np.ndarray:
    if kind is PoseKind.SE2:
        return np.column_stack([translations, np.arctan2(rot[:, 1, 0], rot[:, 0, 0])])
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(rot).as_quat()
    q[q[:, 3] < 0] *= -1.0
    return np.column_stack([translations, q])


# --------------------------------------------------------------------------------------------------
# communication


def _separators(problem: Problem, robot: np.ndarray, robots: int) -> np.ndarray:
    """``(robots, robots)``: ``[a, b]`` vertices of robot a that share an edge with a vertex of robot b."""
    fr, to = problem.edge_from, problem.edge_to
    cross = robot[fr] != robot[to]
    n = problem.num_vertices
    senders = np.concatenate([robot[fr[cross]], robot[to[cross]]])
    receivers = np.concatenate([robot[to[cross]], robot[fr[cross]]])
    vertices = np.concatenate([fr[cross], to[cross]])
    keys = np.unique((senders * robots + receivers) * n + vertices)
    pairs = keys // n
    counts = np.bincount(pairs, minlength=robots * robots)
    return counts.reshape(robots, robots)


def _check_connected(problem: Problem) -> None:
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    n = problem.num_vertices
    adj = sp.csr_matrix((np.ones(problem.num_edges), (problem.edge_from, problem.edge_to)), shape=(n, n))
    parts, labels = connected_components(adj, directed=False)
    if parts > 1:
        lonely = int(np.flatnonzero(labels != labels[problem.anchor])[0])
        raise GraphError(
            f"dgs: the graph falls apart into {parts} pieces (vertex {lonely} is not connected to the anchor)"
        )


# --------------------------------------------------------------------------------------------------
# the two stages


@dataclass(frozen=True)
class _StageOptions:
    tol: float
    gamma: float
    momentum: float


@dataclass(eq=False)
class _Run:
    """What both stages share: the problem split into robots, the rounds so far and the bytes sent."""

    problem: Problem
    members: list[np.ndarray]
    separators: np.ndarray
    links: np.ndarray
    rounds: list[DgsRound]
    max_rounds: int
    schedule: Schedule
    on_round: OnRound | None
    fixed: np.ndarray | None = None
    """Vertices held at their starting values (no one's unknowns: a replay's neighbour poses)."""
    handshake: int = 0
    """Bytes still to be counted with the next pose round (the separator poses at the first point)."""
    step: float = 0.0
    """Largest entry of the last pose system's update."""
    coarse_size: int = 0
    """Vertices per aggregate of the two-level correction (0: none, plain DGS)."""
    score_rounds: bool = True
    """Each pose round's chi2 is computed (:attr:`DgsRound.chi2`)."""

    @property
    def robots(self) -> int:
        return len(self.members)

    @property
    def left(self) -> int:
        return self.max_rounds - len(self.rounds)

    def send(self, numbers_per_vertex: int) -> int:
        """Every robot sends each neighbour that many numbers per separator vertex; the bytes sent."""
        sent = self.separators * (numbers_per_vertex * BYTES_PER_NUMBER)
        self.links[:] += sent
        return int(sent.sum())

    def send_coarse(self, coarse: _Coarse | None, columns: int) -> int:
        """A round's two-level correction: each robot sends the coordinator (robot 0) its coarse
        unknowns' residuals and receives their corrections, ``columns`` numbers each; the bytes."""
        if coarse is None:
            return 0
        each = coarse.per_robot[1:, 0] * (columns * BYTES_PER_NUMBER)
        self.links[1:, 0] += each
        self.links[0, 1:] += each
        return 2 * int(each.sum())

    def send_coarse_matrix(self, coarse: _Coarse | None) -> int:
        """Once per linear system: each robot sends the coordinator its rows of the coarse matrix."""
        if coarse is None:
            return 0
        each = coarse.per_robot[1:, 1] * BYTES_PER_NUMBER
        self.links[1:, 0] += each
        return int(each.sum())

    def dofs_of(self, b: int, fix_anchor: bool = True) -> list[np.ndarray]:
        """Each robot's unknowns, ``b`` per vertex (without the anchor's with ``fix_anchor``, never
        the fixed vertices')."""
        out = []
        for verts in self.members:
            if fix_anchor:
                verts = verts[verts != self.problem.anchor]
            if self.fixed is not None:
                verts = verts[~self.fixed[verts]]
            out.append((verts[:, None] * b + np.arange(b)[None, :]).ravel())
        return out

    def record(self, stage: Stage, change: float, chi2: float | None, sent: int, poses: np.ndarray | None) -> None:
        self.rounds.append(DgsRound(len(self.rounds) + 1, stage, change, chi2, sent))
        if self.on_round is not None:
            self.on_round(self.rounds[-1], poses)


def _robot_indices(problem: Problem, agent_of_vertex: np.ndarray) -> np.ndarray:
    n = problem.num_vertices
    robot = np.asarray(agent_of_vertex)
    if robot.shape != (n,) or not np.issubdtype(robot.dtype, np.integer):
        raise ConfigError(f"agent_of_vertex: expected {n} integers, one per vertex, got shape {robot.shape}")
    if n and robot.min() < 0:
        raise ConfigError("agent_of_vertex: robot indices must be 0 or more")
    return robot.astype(np.int64)


def _fixed_mask(problem: Problem, fixed: np.ndarray | None) -> np.ndarray | None:
    if fixed is None:
        return None
    mask = np.asarray(fixed, dtype=bool)
    if mask.shape != (problem.num_vertices,):
        raise ConfigError(f"fixed: expected a mask of {problem.num_vertices} vertices, got shape {mask.shape}")
    return mask


def _check_options(max_rounds: int, tols: dict[str, float], gammas: dict[str, float], schedule: str) -> None:
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, int) or max_rounds < 2:
        raise ConfigError(f"max_rounds: expected an integer of at least 2, got {max_rounds!r}")
    for name, tol in tols.items():
        if not (isinstance(tol, (int, float)) and 0 < tol < 1):
            raise ConfigError(f"{name}: expected a number in (0, 1), got {tol!r}")
    for name, gamma in gammas.items():
        if isinstance(gamma, bool) or not (isinstance(gamma, (int, float)) and 0 < gamma < 2):
            raise ConfigError(f"{name}: over-relaxation expects a number in (0, 2), got {gamma!r}")
    if schedule not in ("gauss-seidel", "jacobi"):
        raise ConfigError(f"schedule: expected gauss-seidel or jacobi, got {schedule!r}")


def _defaults(
    pose_gamma: float | None, rotation_momentum: float | None, coarse_size: int, schedule: str
) -> tuple[float, float]:
    """The pose stage's over-relaxation and the rotation stage's momentum where not given."""
    if pose_gamma is None:
        pose_gamma = DEFAULT_POSE_GAMMA if coarse_size else PLAIN_POSE_GAMMA
    if rotation_momentum is None:  # Jacobi rounds with momentum diverge on kollagen's graphs
        rotation_momentum = DEFAULT_ROTATION_MOMENTUM if schedule == DEFAULT_SCHEDULE else 0.0
    return pose_gamma, rotation_momentum


def _check_momenta_and_coarse(rotation_momentum: float, pose_momentum: float, coarse_size: int) -> None:
    for name, beta in (("rotation_momentum", rotation_momentum), ("pose_momentum", pose_momentum)):
        if isinstance(beta, bool) or not (isinstance(beta, (int, float)) and 0 <= beta < 1):
            raise ConfigError(f"{name}: expected a number in [0, 1), got {beta!r}")
    if isinstance(coarse_size, bool) or not isinstance(coarse_size, int) or coarse_size < 0:
        raise ConfigError(f"coarse_size: expected 0 (plain DGS) or a count of vertices, got {coarse_size!r}")


def _rotation_stage(run: _Run, start: np.ndarray, opt: _StageOptions) -> tuple[np.ndarray, bool]:
    """The chordal relaxation in rounds: ``Y = R^T``, rows ``Y_j - Z^T Y_i``, ``d`` right-hand sides.
    Returns the ``(n, d, d)`` rotations (the anchor's as given) and whether ``tol`` was met."""
    problem = run.problem
    n, kind, anchor = problem.num_vertices, problem.kind, problem.anchor
    d = 2 if kind is PoseKind.SE2 else 3
    rz = _rotations(kind, problem.measurements)
    w = _rotation_weights(problem)
    omega_r = w[:, None, None] * np.eye(d)[None]
    eye = np.broadcast_to(np.eye(d), rz.shape).copy()
    pieces = _stage_pieces(run, d)
    jacobians = np.concatenate([-np.transpose(rz, (0, 2, 1)), eye], axis=2)
    h_rot = pieces.layout.data(_products(jacobians, omega_r))
    blocks = _factorise(h_rot, pieces)
    if pieces.coarse is not None:
        identity = np.broadcast_to(np.eye(d), (len(pieces.coarse.vertex), d, d))
        blocks.coarse = _coarse(pieces, h_rot, jacobians, omega_r, identity)
    setup = run.send_coarse_matrix(blocks.coarse)
    y = np.transpose(_rotations(kind, start), (0, 2, 1)).reshape(n * d, d).copy()
    zero_rhs = np.zeros((n * d, d))
    converged = False
    projected = _project_so(np.transpose(y.reshape(n, d, d), (0, 2, 1)))
    previous = y.copy()
    while run.left > 1:
        _round(y, zero_rhs, blocks, run.schedule, opt.gamma, previous, opt.momentum)
        # the relaxation's iterates also shrink (its optimum has entries far below 1 where the
        # rotations disagree), which matters to no one: the change is measured on the rotations
        now = _project_so(np.transpose(y.reshape(n, d, d), (0, 2, 1)))
        change = float(np.abs(now - projected).max())
        projected = now
        run.record("rotation", change, None, run.send(d * d) + run.send_coarse(blocks.coarse, d) + setup, None)
        setup = 0
        if change <= opt.tol:
            converged = True
            break
    rot = projected
    rot[anchor] = _rotations(kind, start[anchor : anchor + 1])[0]
    return rot, converged


def _pose_start(
    problem: Problem, start: np.ndarray, rot: np.ndarray, warm_start: bool, fixed: np.ndarray | None = None
) -> np.ndarray:
    """The pose stage's first linearization point: the estimated rotations, every translation at the
    anchor's (the paper's) or, with ``warm_start``, the given translations; the anchor and the
    ``fixed`` vertices as given."""
    n, kind, anchor = problem.num_vertices, problem.kind, problem.anchor
    tw = 2 if kind is PoseKind.SE2 else 3
    translations = start[:, 0:tw].copy() if warm_start else np.repeat(start[anchor : anchor + 1, 0:tw], n, axis=0)
    lin = _with_rotations(kind, translations, rot)
    lin[anchor] = start[anchor]
    if fixed is not None:
        lin[fixed] = start[fixed]
    return lin


def _pose_system(
    run: _Run, lin: np.ndarray, anchor_pose: np.ndarray, opt: _StageOptions, pieces: _Pieces, omega: np.ndarray
) -> np.ndarray:
    """One Gauss-Newton system at ``lin`` solved in rounds (until ``tol`` or the budget); the poses
    (``omega``: the edges' :func:`_pose_information`)."""
    problem = run.problem
    n, kind = problem.num_vertices, problem.kind
    fr, to, anchor = problem.edge_from, problem.edge_to, problem.anchor
    b = 3 if kind is PoseKind.SE2 else 6
    jacobians, e0 = _pose_linearization(problem, lin)
    h = pieces.layout.data(_products(jacobians, omega))
    g = _gradient(fr, to, jacobians, omega, e0, n)
    blocks = _factorise(h, pieces)
    if pieces.coarse is not None:
        blocks.coarse = _coarse(pieces, h, jacobians, omega, _rigid_blocks(kind, lin, pieces.coarse))
        run.handshake += run.send_coarse_matrix(blocks.coarse)
    delta = np.zeros(n * b)
    previous = delta.copy()
    # a round's poses are only needed where someone reads them (they stay the same otherwise)
    each_round = run.score_rounds or run.on_round is not None
    first = len(run.rounds)
    poses = lin
    while run.left > 0:
        change = _round(delta, g, blocks, run.schedule, opt.gamma, previous, opt.momentum)
        if each_round:
            poses = _reanchor(kind, _retract(kind, lin, delta.reshape(n, b)), anchor, anchor_pose)
        sent = run.send(b) + run.send_coarse(blocks.coarse, 1) + run.handshake
        run.record("pose", change, graph_chi2(problem, poses) if run.score_rounds else None, sent, poses)
        run.handshake = 0
        if change <= opt.tol:
            break
    if not each_round and len(run.rounds) > first:
        poses = _reanchor(kind, _retract(kind, lin, delta.reshape(n, b)), anchor, anchor_pose)
    run.step = float(np.abs(delta).max()) if delta.size else 0.0
    return poses


def _pose_stage(
    run: _Run, lin: np.ndarray, anchor_pose: np.ndarray, opt: _StageOptions
) -> tuple[np.ndarray, int, bool]:
    """Gauss-Newton from ``lin``, each system solved in rounds, relinearized until an update moves no
    entry by more than ``opt.tol`` or the rounds run out: the poses, the systems built, convergence."""
    run.handshake = run.send(run.problem.kind.pose_width)  # each robot's separator poses at ``lin``
    # Jacobi rounds on the anchor-free (singular) system would keep oscillating in its gauge
    # with fixed vertices the anchor is held too: the rigid move onto it would move them
    hold = run.robots == 1 or run.schedule == "jacobi" or (run.fixed is not None and bool(run.fixed.any()))
    pieces = _stage_pieces(run, 3 if run.problem.kind is PoseKind.SE2 else 6, fix_anchor=hold)
    omega = _pose_information(run.problem)
    linearizations = 0
    poses = lin
    while run.left > 0:
        poses = _pose_system(run, lin, anchor_pose, opt, pieces, omega)
        linearizations += 1
        lin = poses
        if run.step <= opt.tol and run.rounds[-1].change <= opt.tol:
            return poses, linearizations, True
    return poses, linearizations, False


def _start_values(problem: Problem, initial: np.ndarray | None) -> np.ndarray:
    start = problem.initial if initial is None else np.asarray(initial, dtype=np.float64)
    if start.shape != problem.initial.shape:
        raise ConfigError(f"initial: expected shape {problem.initial.shape}, got {start.shape}")
    return np.asarray(start)


def dgs_rounds(
    problem: Problem,
    agent_of_vertex: np.ndarray,
    *,
    initial: np.ndarray | None = None,
    max_rounds: int = DEFAULT_MAX_ROUNDS,
    rotation_tol: float = DEFAULT_ROTATION_TOL,
    pose_tol: float = DEFAULT_POSE_TOL,
    rotation_gamma: float = DEFAULT_ROTATION_GAMMA,
    pose_gamma: float | None = None,
    rotation_momentum: float | None = None,
    pose_momentum: float = DEFAULT_POSE_MOMENTUM,
    schedule: Schedule = DEFAULT_SCHEDULE,
    warm_start: bool = False,
    rotation_stage: bool = True,
    fixed: np.ndarray | None = None,
    on_round: OnRound | None = None,
    coarse_size: int = DEFAULT_COARSE_SIZE,
    score_rounds: bool = True,
) -> DgsResult:
    """Run DGS on ``problem`` with vertex ``v`` owned by robot ``agent_of_vertex[v]`` (ints ``0..R-1``).

    ``initial`` (default: the problem's poses) gives the rotation stage's starting rotations and, with
    ``warm_start``, the pose stage's translations (a replay continuing from an earlier estimate); without it the
    pose stage starts with every translation at the anchor's, as the paper. Without ``rotation_stage`` the pose
    stage starts at ``initial`` itself (a replay's later solves, whose rotations are already refined: a chordal
    stage cut short would only move them away). ``on_round(round, poses)`` is called after each round, ``poses``
    the current estimate in the pose stage and None in the rotation stage. At most ``max_rounds`` rounds over
    both stages. ``fixed`` (a mask over the vertices) holds vertices at ``initial``, no robot's unknowns (the
    anchor is then held too): a replay's neighbour poses, each in the block of the robot its edges tie it to.
    Without ``score_rounds`` no pose round's chi2 is computed (the rounds are the same)."""
    t0 = time.perf_counter()
    robot = _robot_indices(problem, agent_of_vertex)
    robots = int(robot.max()) + 1 if problem.num_vertices else 0
    tols = {"rotation_tol": rotation_tol, "pose_tol": pose_tol}
    pose_gamma, rotation_momentum = _defaults(pose_gamma, rotation_momentum, coarse_size, schedule)
    _check_options(max_rounds, tols, {"rotation_gamma": rotation_gamma, "pose_gamma": pose_gamma}, schedule)
    _check_momenta_and_coarse(rotation_momentum, pose_momentum, coarse_size)
    start = _start_values(problem, initial)
    fixed = _fixed_mask(problem, fixed)
    _check_connected(problem)
    if robots == 1:  # one block is the whole system, solved exactly: over-relaxing it only overshoots
        rotation_gamma = pose_gamma = 1.0
        rotation_momentum = pose_momentum = 0.0
        coarse_size = 0
    run = _Run(
        problem,
        [np.flatnonzero(robot == r) for r in range(robots)],
        _separators(problem, robot, robots),
        np.zeros((robots, robots), dtype=np.int64),
        [],
        max_rounds,
        schedule,
        on_round,
        fixed,
        coarse_size=coarse_size,
        score_rounds=score_rounds,
    )
    if rotation_stage:
        rot, converged_rot = _rotation_stage(run, start, _StageOptions(rotation_tol, rotation_gamma, rotation_momentum))
        lin = _pose_start(problem, start, rot, warm_start, fixed)
    else:
        lin, converged_rot = start.copy(), True
    rotation_rounds = len(run.rounds)
    chi2_initial = graph_chi2(problem, lin)
    pose = _StageOptions(pose_tol, pose_gamma, pose_momentum)
    poses, linearizations, converged_pose = _pose_stage(run, lin, start[problem.anchor], pose)
    return DgsResult(
        poses=poses,
        rounds=tuple(run.rounds),
        rotation_rounds=rotation_rounds,
        pose_rounds=len(run.rounds) - rotation_rounds,
        linearizations=linearizations,
        converged=converged_rot and converged_pose,
        robots=robots,
        bytes_per_robot=run.links.sum(axis=1),
        bytes_per_link=run.links,
        chi2_initial=chi2_initial,
        seconds=time.perf_counter() - t0,
    )


def solve_dgs(problem: Problem, options: SolveOptions, on_iteration: Iteration | None = None) -> Solution:
    """The ``dgs`` method (see the module doc): robots from ``problem.agent_of_vertex``, else a
    contiguous split into ``robots`` (:class:`DgsOptions`, ``options.own``);
    ``options.max_iterations`` rounds at most.

    Iteration 0 is the dataset's values (DGS has no separate initial guess: each robot starts from
    its own odometry), iteration ``i >= 1`` the estimate after the ``i``-th pose-stage round (round
    ``rotation_rounds + i``; the rotation stage's rounds have no poses): ``on_iteration`` gets them
    and ``chi2_history`` holds their chi2."""
    own = options.own_options(DgsOptions)
    robot = problem.agent_of_vertex
    if robot is None:
        robot = contiguous_robots(problem.num_vertices, own.robots or min(8, problem.num_vertices))
    if on_iteration is not None:
        on_iteration(0, problem.initial)

    pose_rounds = [0]

    def on_round(r: DgsRound, poses: np.ndarray | None) -> None:
        if on_iteration is not None and poses is not None:
            pose_rounds[0] += 1
            on_iteration(pose_rounds[0], poses)

    result = dgs_rounds(
        problem,
        robot,
        max_rounds=max(options.max_iterations, 2),
        rotation_tol=own.rotation_tol,
        pose_tol=own.pose_tol,
        rotation_gamma=own.rotation_gamma,
        pose_gamma=own.pose_gamma,
        rotation_momentum=own.rotation_momentum,
        pose_momentum=own.pose_momentum,
        schedule=own.schedule,
        on_round=on_round,
        coarse_size=own.coarse_size,
    )
    history = (graph_chi2(problem, problem.initial), *(r.chi2 for r in result.rounds if r.chi2 is not None))
    # the values the rounds used where the options left them open
    pose_gamma, rotation_momentum = _defaults(own.pose_gamma, own.rotation_momentum, own.coarse_size, own.schedule)
    return Solution(
        result.poses,
        result.num_rounds,
        history,
        notes={
            "chi2_first_linearization": result.chi2_initial,
            "robots": result.robots,
            "rounds": result.num_rounds,
            "rotation_rounds": result.rotation_rounds,
            "pose_rounds": result.pose_rounds,
            "linearizations": result.linearizations,
            "converged": result.converged,
            "schedule": own.schedule,
            "rotation_gamma": own.rotation_gamma,
            "pose_gamma": pose_gamma,
            "rotation_momentum": rotation_momentum,
            "pose_momentum": own.pose_momentum,
            "coarse_size": own.coarse_size if result.robots > 1 else 0,
            "rotation_tol": own.rotation_tol,
            "pose_tol": own.pose_tol,
            "round_stage": [r.stage for r in result.rounds],
            "round_change": [r.change for r in result.rounds],
            "round_chi2": [r.chi2 for r in result.rounds],
            "round_bytes": [r.bytes_sent for r in result.rounds],
            "bytes_total": int(result.bytes_per_robot.sum()),
            "bytes_per_robot": result.bytes_per_robot.tolist(),
            "bytes_per_link": result.links(),
            "dgs_s": result.seconds,
        },
    )
