"""``priors.txt``: pose priors beside a multi-g2o folder (JRL's ``PriorFactorPose2/3``).

``studio convert jrl`` writes it when the file has priors (COSMO-Bench anchors every robot at its
first pose); ``studio export --format jrl`` writes them back. ``#`` lines are comments; every other
line is one prior::

    agent vertex POSE INFORMATION

Agents are 1-based as in ``inter_agent_lc.dat`` (``agentK``), vertices 0-based within their agent.
``POSE`` is the prior's value in the dataset's records (``x y theta`` for planar datasets, ``x y z
qx qy qz qw`` for 3D ones) and ``INFORMATION`` the upper triangle of its information matrix in the
g2o edges' order (6 values over ``x y theta``; 21 over ``x y z`` and the quaternion's vector part),
the same convention as the dataset's edges. Numbers are written with ``%.17g``: reading gives every
bit back.
"""

from __future__ import annotations

import numpy as np

from studio.core.errors import FormatError, GraphError
from studio.core.model import PoseGraph, Priors
from studio.core.types import PathLike
from studio.io.g2o import _open_text
from studio.io.outliers_txt import _INTEGER

__all__ = ["PRIORS_NAME", "priors_text", "write_priors_txt", "read_priors_txt"]

#: The file's name inside a dataset folder.
PRIORS_NAME = "priors.txt"
_HEADER = (
    "# Pose priors (cslam-studio; docs/formats.md): agent vertex POSE INFORMATION\n"
    "# agents 1-based (agentK), vertices 0-based; POSE as the dataset's records; INFORMATION the upper\n"
    "# triangle of the prior's information matrix in the g2o edges' order.\n"
)


def priors_text(priors: Priors) -> str:
    """The file's text (header included)."""
    lines = [_HEADER]
    for a, v, pose, info in zip(
        priors.agent.tolist(), priors.index.tolist(), priors.poses.tolist(), priors.information_upper.tolist()
    ):
        lines.append(" ".join([str(a + 1), str(v), *(f"{x:.17g}" for x in (*pose, *info))]) + "\n")
    return "".join(lines)


def write_priors_txt(path: PathLike, priors: Priors) -> None:
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(priors_text(priors))


def read_priors_txt(path: PathLike, graph: PoseGraph) -> Priors:
    """The priors of ``path`` on the poses of ``graph`` (its kind sets the columns); errors name
    ``file:line``."""
    text, name = _open_text(path)
    kind = graph.kind
    width = 2 + kind.pose_width + kind.information_width
    ints: list[tuple[int, int]] = []
    floats: list[list[float]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].split()
        if not body:
            continue
        if len(body) != width:
            raise FormatError(f"{name}:{n}: expected {width} columns for a {kind.value} prior, found {len(body)}")
        if not (_INTEGER.fullmatch(body[0]) and _INTEGER.fullmatch(body[1])) or int(body[0]) < 1:
            raise FormatError(f"{name}:{n}: expected a 1-based agent and a vertex, got {' '.join(body[:2])!r}")
        try:
            row = [float(x) for x in body[2:]]
        except ValueError:
            raise FormatError(f"{name}:{n}: not a number in {line.strip()[:60]!r}") from None
        if not np.isfinite(row).all():
            raise FormatError(f"{name}:{n}: a value is not finite")
        ints.append((int(body[0]) - 1, int(body[1])))
        floats.append(row)
    if not ints:
        return Priors.empty(kind)
    idx = np.array(ints, dtype=np.int64)
    values = np.array(floats, dtype=np.float64)
    try:
        priors = Priors(kind, idx[:, 0], idx[:, 1], values[:, : kind.pose_width], values[:, kind.pose_width :])
        priors.check_against(graph)
    except GraphError as err:
        raise FormatError(f"{name}: {err}") from None
    return priors
