"""How ISAM2 is driven by ``studio replay``'s incremental back-ends (:class:`IsamSettings`), without
numpy: the command line declares ``--relinearize-skip`` and its neighbours from these defaults, and
:mod:`studio.solvers.incremental` (which re-exports it) reads them.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["IsamSettings"]


@dataclass(frozen=True)
class IsamSettings:
    """How ISAM2 is driven (``studio replay --relinearize-skip/--relinearize-threshold``)."""

    relinearize_threshold: float = 0.1
    """Relinearize a variable whose delta exceeds this (GTSAM's default)."""
    relinearize_skip: int = 10
    """Check for relinearization every this many updates (GTSAM's default 10)."""
    extra_updates: int = 0
    """Further ``update()`` calls after each batch (more Gauss-Newton steps)."""
    final_updates: int = 3
    """Further ``update()`` calls at the end of the replay."""
    polish: bool = True
    """At the end, Gauss-Newton to convergence (at most 10 iterations) on the factors ISAM2 holds
    but the loose priors (kept where the graph needs them to be determinate), from its estimate: ISAM2 relinearizes only where a delta exceeds the threshold, which leaves
    a big graph short of its optimum (Multi3500x8: chi2 0.2 % high, APE up to 40 % higher)."""
