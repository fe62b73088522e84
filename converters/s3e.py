"""S3E sequences: ground truth per robot as ``<agent>_gt.txt`` (alpha, bob, carol).

As S3E ships them: file names in any case (v1 has ``Alpha_gt.txt``), agents written lower case;
TUM-like text in UTM coordinates (``timestamp tx ty tz qx qy qz qw``), present only where the RTK
receiver had a fixed solution, so they have gaps; and **no orientation**: RTK gives positions only,
so every line carries the identity quaternion (``... 0 0 0 1``). ``studio convert`` derives headings
from the motion for such trajectories (``--orientation auto``, see
:mod:`studio.converters.transforms`). Indoor (Laboratory) sequences have only a start and an end pose
per robot: such an agent is left out with a warning naming its file, and the sequence is refused
when no agent is left. Files are looked for in ``DIR`` and its immediate sub-folders. An agent
without a ground-truth file is read from a ROS 2 bag found in the same places (a folder holding
``metadata.yaml``) through its ``/<agent>/fix`` + ``/<agent>/heading`` topics, matched in any case
(``/Alpha/fix``; see :mod:`studio.converters.rosbag`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from studio.converters.tum import read_tum_trajectory
from studio.core.errors import FormatError
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.io.tum import read_tum_rows
from studio.runtime.progress import Progress

__all__ = ["S3E_AGENTS", "read_s3e", "is_s3e_sequence"]

S3E_AGENTS = ("alpha", "bob", "carol")
#: A ground truth of this many poses or fewer is an indoor sequence's start and end only.
MIN_GT_POSES = 2
_GT = re.compile(r"^(alpha|bob|carol)_gt\.txt$", re.IGNORECASE)


def _candidates(root: Path) -> list[Path]:
    found = sorted(p for p in root.iterdir())
    for sub in sorted(p for p in root.iterdir() if p.is_dir()):
        found += sorted(sub.iterdir())
    return found


def is_s3e_sequence(path: Path) -> bool:
    """True for a folder holding (or with a subfolder holding) an ``<agent>_gt.txt`` of S3E's agents."""
    return path.is_dir() and any(_GT.match(q.name) for q in _candidates(path))


def read_s3e(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    """``studio convert s3e DIR``: alpha, bob and carol (those present), in that order."""
    root = Path(inputs[0])
    if not root.is_dir():
        raise FormatError(f"{root}: not a folder (expected an S3E sequence folder)")
    entries = _candidates(root)
    files: dict[str, Path] = {}
    for p in entries:
        m = _GT.match(p.name)
        if m and p.is_file():
            agent = m.group(1).lower()
            if agent in files:
                raise FormatError(f"{p}: a second ground-truth file for {agent} (first: {files[agent]})")
            files[agent] = p
    bags = [p for p in [root, *entries] if p.is_dir() and (p / "metadata.yaml").is_file()]
    out: list[Trajectory] = []
    missing = [a for a in S3E_AGENTS if a not in files]
    bag_trajs: dict[str, Trajectory] = {}
    if missing and bags:
        from studio.converters.rosbag import read_bag

        specs = {a: f"/{a}/fix+/{a}/heading" for a in missing}
        bag_trajs = {
            t.name: t
            for t in read_bag(bags[0], specs, warn=warn, skip_missing=True, progress=progress, ignore_case=True)
        }
    short = []
    for agent in S3E_AGENTS:
        if agent in files:
            stamps, _ = read_tum_rows(files[agent])
            n = len(np.unique(stamps))
            if n <= MIN_GT_POSES:
                short.append(files[agent])
                if warn is not None:
                    warn(
                        f"{files[agent]}: only {n} poses (an indoor S3E sequence has just its start and end); "
                        f"agent {agent} left out"
                    )
                continue
            out.append(read_tum_trajectory(files[agent], name=agent, warn=warn))
        elif agent in bag_trajs:
            out.append(bag_trajs[agent])
    if not out and short:
        raise FormatError(
            f"{short[0]}: only start and end poses in every ground-truth file of {root} "
            "(an indoor S3E sequence): nothing to convert"
        )
    if not out:
        raise FormatError(
            f"{root}: no S3E ground truth (alpha_gt.txt, bob_gt.txt, carol_gt.txt) "
            "and no ROS 2 bag with /<agent>/fix topics"
        )
    return out
