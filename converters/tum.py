"""TUM-style trajectory text files: ``timestamp tx ty tz qx qy qz qw`` per line.

Space- or comma-separated, ``#`` comments or one header line; parsing is :func:`studio.io.tum.read_tum_rows`
(errors name ``file:line``). Quaternions are normalised; unsorted or duplicate timestamps are sorted
and de-duplicated with a warning that counts them. One file is one agent, named after the file; files
whose names collide (every TUM RGB-D sequence ships ``groundtruth.txt``) are named after their folders
(``rgbd_dataset_freiburg1_xyz``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from studio.converters.names import safe_agent_name
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike
from studio.io.tum import read_tum_rows
from studio.runtime.parallel import parallel_map
from studio.runtime.progress import Progress

__all__ = ["read_tum_trajectory", "read_tum_sources"]

#: Inputs larger than this in total are parsed in parallel (one process per core).
_PARALLEL_MIN_BYTES = 8 * 1024 * 1024


def read_tum_trajectory(path: PathLike, *, name: str | None = None, warn: Warn | None = None) -> Trajectory:
    """One trajectory; ``name`` defaults to a safe version of the file's stem."""
    path = Path(path)
    stamps_ns, poses = read_tum_rows(path)
    agent = name if name is not None else safe_agent_name(path.stem)
    return clean_trajectory(agent, stamps_ns, poses[:, :3], poses[:, 3:], str(path), warn)


def agent_names(inputs: Sequence[PathLike]) -> list[str]:
    """One agent name per file: its stem, or its folder's name where stems collide."""
    stems = [safe_agent_name(Path(p).stem) for p in inputs]
    return [safe_agent_name(Path(p).resolve().parent.name) if stems.count(s) > 1 else s for p, s in zip(inputs, stems)]


def read_tum_sources(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    """``studio convert tum FILE...``: one agent per file, in the order given."""
    sizes = [Path(p).stat().st_size if Path(p).is_file() else 0 for p in inputs]
    names = agent_names(inputs)
    total = sum(sizes)

    def tick(done: int, _n: int) -> None:
        if progress is not None:
            progress("reading", sum(sizes[:done]), total, "bytes")

    if len(inputs) < 2 or sum(sizes) < _PARALLEL_MIN_BYTES:
        trajs = []
        tick(0, len(inputs))
        for k, p in enumerate(inputs):
            trajs.append(read_tum_trajectory(p, name=names[k], warn=warn))
            tick(k + 1, len(inputs))
        return trajs

    # large files are parsed by several processes; their warnings are replayed here, in order
    def read_one(k: int) -> tuple[Trajectory, list[str]]:
        messages: list[str] = []
        return read_tum_trajectory(inputs[k], name=names[k], warn=messages.append), messages

    out = []
    for traj, messages in parallel_map(read_one, len(inputs), on_done=tick):
        for msg in messages:
            if warn is not None:
                warn(msg)
        out.append(traj)
    return out
