"""Kimera-Multi ground truth: a folder of ``<robot>_gt_odom.csv`` files (e.g. ``acl_jackal_gt_odom.csv``),
each a header ``#timestamp_kf,x,y,z,qw,qx,qy,qz`` then one pose per line: **nanosecond** stamps and
the quaternion **scalar first**. Every robot of the folder is an agent, named after its file without
``_gt_odom`` (``acl_jackal``), in name order.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from studio.converters.names import safe_agent_name
from studio.converters.text import read_table
from studio.core.errors import ConfigError, FormatError
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike

__all__ = ["read_kimera_multi", "kimera_files", "SUFFIX"]

SUFFIX = "_gt_odom.csv"
_WHAT = "Kimera-Multi ground truth: timestamp_kf [ns], x, y, z, qw, qx, qy, qz"


def kimera_files(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(
        (p for p in folder.iterdir() if p.is_file() and p.name.endswith(SUFFIX)), key=lambda p: p.name[: -len(SUFFIX)]
    )


def read_kimera_multi(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: object = None,
) -> list[Trajectory]:
    """``studio convert kimera-multi GT_FOLDER`` (or the csv files themselves)."""
    files: list[Path] = []
    for raw in inputs:
        p = Path(raw)
        found = kimera_files(p) if p.is_dir() else [p] if p.is_file() else []
        if not found:
            raise FormatError(f"{p}: no Kimera-Multi ground truth (<robot>{SUFFIX})")
        files += found
    if not files:
        raise ConfigError("studio convert kimera-multi needs a ground-truth folder or <robot>_gt_odom.csv files")
    out = []
    for f in files:
        table, stamps = read_table(f, 8, what=_WHAT, int_first=True, quaternion="wxyz")
        assert stamps is not None
        name = safe_agent_name(f.name[: -len(SUFFIX)] if f.name.endswith(SUFFIX) else f.stem)
        out.append(clean_trajectory(name, stamps, table[:, 1:4], table[:, [5, 6, 7, 4]], str(f), warn))
    names = [t.name for t in out]
    for n in names:
        if names.count(n) > 1:
            raise ConfigError(f"two Kimera-Multi files would both be agent {n!r}")
    return out
