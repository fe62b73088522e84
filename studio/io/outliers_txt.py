"""``outliers.txt`` with the outliers' kinds, in the converters' format.

The rows are ``agent_from vertex_from agent_to vertex_to`` (agents 1-based as in
``inter_agent_lc.dat``, vertices 0-based), as ``studio convert`` writes them; every reader of that
format skips ``#`` lines, so the kind of each group of rows is a comment line ``# kind: NAME`` before
it (:func:`read_outlier_kinds` reads them back). :func:`write_outliers_txt` is the one writer (synth,
convert, the graph imports): one header, the rows grouped by kind (``random``, ``aliasing``: synth's
kinds; ``far``: convert's, a vertex at least two loop-closure radii from both true endpoints).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.core.errors import FormatError
from studio.core.types import PathLike

__all__ = [
    "write_outliers_txt",
    "read_outliers_txt",
    "read_outlier_kinds",
    "POTENTIAL_OUTLIERS_NAME",
    "POTENTIAL_HEAD",
]

#: The potential outliers of a dataset (JRL's ``potential_outlier_factors``: the measurements a
#: robust back-end may reject), in this file's rows, beside ``outliers.txt``.
POTENTIAL_OUTLIERS_NAME = "potential_outliers.txt"

#: A field: an optional minus sign and 1 to 18 digits (every such number fits int64).
_INTEGER = re.compile(r"-?[0-9]{1,18}")

_HEAD = (
    "# Loop closures that are outliers: they point at a wrong vertex (ground truth for robust\n"
    "# optimisers). Columns: agent_from vertex_from agent_to vertex_to; agents 1-based as in\n"
    "# inter_agent_lc.dat, vertices 0-based; equal agents: an intra-agent loop closure.\n"
    "# Each group of rows follows a line '# kind: random' (the to vertex drawn near the true one)\n"
    "# or '# kind: aliasing' (a far-away place with the same heading and local grid pattern).\n"
)

POTENTIAL_HEAD = (
    "# Measurements that may be outliers (JRL's potential_outlier_factors): a robust back-end may\n"
    "# reject them, every other measurement is a known inlier. Columns: agent_from vertex_from\n"
    "# agent_to vertex_to; agents 1-based as in inter_agent_lc.dat, vertices 0-based.\n"
)


def write_outliers_txt(path: PathLike, rows: np.ndarray, kinds: Sequence[str], *, head: str = _HEAD) -> None:
    """Write (k, 4) rows with 0-based agents, grouped by kind in order of first appearance, after
    ``head`` (the outliers' header; :data:`POTENTIAL_HEAD` for ``potential_outliers.txt``)."""
    rows = np.asarray(rows, dtype=np.int64).reshape(-1, 4)
    text = [head]
    for kind in dict.fromkeys(kinds):
        text.append(f"# kind: {kind}\n")
        text.extend(f"{a + 1} {b} {c + 1} {d}\n" for (a, b, c, d), k in zip(rows.tolist(), kinds) if k == kind)
    Path(path).write_text("".join(text), encoding="utf-8")


def read_outliers_txt(path: PathLike, agent_sizes: Sequence[int] | None = None) -> tuple[np.ndarray, list[str]]:
    """The one reader of ``outliers.txt``: (k, 4) int64 rows ``agent_from vertex_from agent_to
    vertex_to`` with 0-based agents, and each row's kind (``""`` before any ``# kind:`` line).

    The file is held to the text inputs' limits (size from the file, UTF-8, checked before
    parsing: :data:`studio.io.g2o.MAX_TEXT_BYTES`); every field is a decimal integer of at most 18
    digits; with ``agent_sizes`` (poses per agent) every agent must be in ``1..len(agent_sizes)`` and
    every vertex one of its agent's. Errors name ``file:line``.
    """
    from studio.io.g2o import _open_text

    text, name = _open_text(path)
    rows, kinds, kind = [], [], ""
    for n, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith("# kind:"):
            kind = stripped[len("# kind:") :].strip()
            continue
        body = stripped.split("#", 1)[0].strip()
        if not body:
            continue
        parts = body.split()
        if len(parts) != 4 or not all(_INTEGER.fullmatch(x) for x in parts):
            raise FormatError(
                f"{name}:{n}: expected four integers `agent_from vertex_from agent_to vertex_to`, got {body[:60]!r}"
            )
        a, v, b, w = (int(x) for x in parts)
        if agent_sizes is not None:
            for agent, vertex in ((a, v), (b, w)):
                if not 1 <= agent <= len(agent_sizes):
                    raise FormatError(f"{name}:{n}: agent {agent} is not in 1..{len(agent_sizes)}")
                if not 0 <= vertex < agent_sizes[agent - 1]:
                    raise FormatError(f"{name}:{n}: agent {agent} has no vertex {vertex}")
        rows.append((a - 1, v, b - 1, w))
        kinds.append(kind)
    return np.array(rows, dtype=np.int64).reshape(-1, 4), kinds


def read_outlier_kinds(path: PathLike) -> tuple[np.ndarray, list[str]]:
    """(k, 4) rows (0-based agents) and the kind of each (``""`` before any ``# kind:`` line)."""
    return read_outliers_txt(path)
