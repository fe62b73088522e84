"""``outliers.txt`` with the outliers' kinds, in the converters' format.

The rows are ``agent_from vertex_from agent_to vertex_to`` (agents 1-based as in
``inter_agent_lc.dat``, vertices 0-based), as ``studio convert`` writes them; every reader of that
format skips ``#`` lines, so the kind of each group of rows is a comment line ``# kind: NAME`` before
it (:func:`read_outlier_kinds` reads them back).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.core.errors import FormatError
from studio.core.types import PathLike

__all__ = ["write_outliers_txt", "read_outlier_kinds"]

_HEAD = (
    "# Loop closures that are outliers: they point at a wrong vertex (ground truth for robust\n"
    "# optimisers). Columns: agent_from vertex_from agent_to vertex_to; agents 1-based as in\n"
    "# inter_agent_lc.dat, vertices 0-based; equal agents: an intra-agent loop closure.\n"
    "# Each group of rows follows a line '# kind: random' (the to vertex drawn near the true one)\n"
    "# or '# kind: aliasing' (a far-away place with the same heading and local grid pattern).\n"
)


def write_outliers_txt(path: PathLike, rows: np.ndarray, kinds: Sequence[str]) -> None:
    """Write (k, 4) rows with 0-based agents, grouped by kind in order of first appearance."""
    rows = np.asarray(rows, dtype=np.int64).reshape(-1, 4)
    text = [_HEAD]
    for kind in dict.fromkeys(kinds):
        text.append(f"# kind: {kind}\n")
        text.extend(f"{a + 1} {b} {c + 1} {d}\n" for (a, b, c, d), k in zip(rows.tolist(), kinds) if k == kind)
    Path(path).write_text("".join(text), encoding="utf-8")


def read_outlier_kinds(path: PathLike) -> tuple[np.ndarray, list[str]]:
    """(k, 4) rows (0-based agents) and the kind of each (``""`` before any ``# kind:`` line)."""
    path = Path(path)
    rows, kinds, kind = [], [], ""
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if text.startswith("# kind:"):
            kind = text[len("# kind:") :].strip()
            continue
        if not text or text.startswith("#"):
            continue
        try:
            a, b, c, d = (int(x) for x in text.split())
        except ValueError:
            raise FormatError(
                f"{path}:{n}: expected four integers `agent_from vertex_from agent_to vertex_to`"
            ) from None
        rows.append((a - 1, b, c - 1, d))
        kinds.append(kind)
    return np.array(rows, dtype=np.int64).reshape(-1, 4), kinds
