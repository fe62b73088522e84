"""AirMuseum sequences: one ground-truth text file per robot (``# timestamp tx ty tz qx qy qz qw``).

As AirMuseum ships them, a scenario folder holds ``<Scenario>/data/{robotA,robotB,robotC,drone}/
body_stamped_groundtruth.txt`` (one ``#`` header line, then ``t x y z qx qy qz qw``). A ground-truth
file is a ``.txt``, ``.tum`` or ``.csv`` file whose name contains ``gt``, ``groundtruth`` or
``ground_truth`` (any case), in ``DIR``, one of its sub-folders, or a sub-folder of ``DIR/data``
(search depth 2). The agent is named after its folder (``data/robotA/...`` -> ``robotA``) or, for a
file directly in ``DIR``, after the file without the ground-truth word (``drone_gt.txt`` -> ``drone``).

The robots' body frames differ (the drone's is FLU: x forward, y left, z up; robots A and B's
"UFL": x up, y forward, z left; robot C's "FUR"): :data:`BODY_FRAMES` holds these documented
defaults, which the convert pipeline applies (``--body-frame NAME=CODE`` overrides) so that a planar
conversion takes yaw about the true up axis.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from studio.converters.names import safe_agent_name
from studio.converters.tum import read_tum_trajectory
from studio.core.errors import FormatError
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike
from studio.runtime.progress import Progress

__all__ = ["read_airmuseum", "find_ground_truth_files", "is_airmuseum_sequence", "BODY_FRAMES"]

#: AirMuseum's body frames per robot name, lower case (x, y, z axes as Forward/Left/Up/Right/Down/Back).
BODY_FRAMES = {"drone": "flu", "robota": "ufl", "robotb": "ufl", "robotc": "fur"}

_GT_WORD = re.compile(r"(ground[_-]?truth|(?<![a-z])gt(?![a-z]))", re.IGNORECASE)
_EXT = (".txt", ".tum", ".csv")


def find_ground_truth_files(root: Path) -> list[tuple[str, Path]]:
    """(agent name, file) pairs, in natural order of the agent names."""
    found: list[tuple[str, Path]] = []
    data = root / "data"
    if data.is_dir() and not any(p.is_file() and _GT_WORD.search(p.stem) for p in root.iterdir()):
        shipped = find_ground_truth_files(data)  # the shipped scenario layout: <Scenario>/data/<robot>/
        if shipped:
            return shipped
    for p in sorted(root.iterdir()):
        if p.is_file() and p.suffix.lower() in _EXT and _GT_WORD.search(p.stem):
            stem = _GT_WORD.sub("", p.stem).strip("_- .") or p.stem
            found.append((safe_agent_name(stem), p))
        elif p.is_dir():
            inner = [
                q for q in sorted(p.iterdir()) if q.is_file() and q.suffix.lower() in _EXT and _GT_WORD.search(q.stem)
            ]
            if len(inner) > 1:
                raise FormatError(
                    f"{p}: {len(inner)} ground-truth files ({inner[0].name}, {inner[1].name}); "
                    "expected one per robot folder"
                )
            if inner:
                found.append((safe_agent_name(p.name), inner[0]))
    return found


def is_airmuseum_sequence(path: Path) -> bool:
    """True for a scenario folder with a ``data/`` folder and ground-truth files (also when they are
    malformed, e.g. two in one robot folder: the reader then says what is wrong)."""
    if not (path.is_dir() and (path / "data").is_dir()):
        return False
    try:
        return bool(find_ground_truth_files(path))
    except FormatError:
        return True


def read_airmuseum(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    """``studio convert airmuseum DIR``: every robot with a ground-truth file."""
    root = Path(inputs[0])
    if not root.is_dir():
        raise FormatError(f"{root}: not a folder (expected an AirMuseum sequence folder)")
    found = find_ground_truth_files(root)
    if not found:
        raise FormatError(f"{root}: no ground-truth file (*gt*.txt, *groundtruth*.txt) here or in a sub-folder")
    names = [n for n, _ in found]
    for n in names:
        if names.count(n) > 1:
            raise FormatError(f"{root}: two robots would be named {n!r}")
    return [read_tum_trajectory(p, name=n, warn=warn) for n, p in found]
