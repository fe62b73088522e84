"""Write a small sample in every source's layout: ``python -m tests.samples DIR`` (from the repository
root). These are the stand-ins the README's and docs' commands run on (tests/test_docs_commands.py):
simulated data in the real layouts of TUM, S3E, AirMuseum, ROS bags, EuRoC, KITTI, Kimera-Multi and
MR.CLAM, made by the tests' own writers; no dataset's files are copied. Then, inside DIR, e.g.
``studio convert mrclam MRCLAM_Dataset1/ --planar --odometry real -o out/mrclam1``."""

from __future__ import annotations

import sys
from pathlib import Path


def write_samples(folder: Path) -> list[str]:
    """Write every sample into ``folder`` (created; it must be empty); returns what it holds."""
    from tests.test_docs_commands import INPUTS

    folder.mkdir(parents=True, exist_ok=True)
    if any(folder.iterdir()):
        raise SystemExit(f"{folder}: not empty")
    for make in dict.fromkeys(INPUTS.values()):
        make(folder)
    return sorted(p.name for p in folder.iterdir())


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python -m tests.samples DIR")
    for name in write_samples(Path(sys.argv[1])):
        print(name)
