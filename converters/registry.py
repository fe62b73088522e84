"""The source formats ``studio convert`` knows: an explicit dict from name to :class:`Source`.

Every reader follows the :class:`SourceReader` seam: ``reader(inputs, *, agents=(), warn=None,
progress=None) -> list[Trajectory]``, where ``inputs`` are the paths given on the command line and
``agents`` the ``NAME=SPEC`` strings of ``--agent``. A source's facts (does it take ``--agent``, how
many inputs, what its agents are named after) are declared once beside its reader, and
:func:`check_inputs` checks them before any reader runs. Readers that need heavy libraries import
them when called. A new source is one module with its reader and one entry here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from studio.converters.airmuseum import read_airmuseum
from studio.converters.euroc import euroc_ground_truth, read_euroc
from studio.converters.kimera_multi import kimera_files, read_kimera_multi
from studio.converters.kitti import read_kitti
from studio.converters.mrclam import read_mrclam, read_mrclam_odometry, read_mrclam_sightings
from studio.converters.s3e import read_s3e
from studio.converters.tum import read_tum_sources
from studio.core.errors import ConfigError
from studio.core.progress import Progress
from studio.core.trajectory import Trajectory, Warn
from studio.core.types import PathLike

__all__ = [
    "SourceReader",
    "Source",
    "SOURCES",
    "READERS",
    "get_reader",
    "get_source",
    "source_names",
    "check_inputs",
    "guess_source",
]


class SourceReader(Protocol):
    """Read one source's inputs into one :class:`Trajectory` per agent."""

    def __call__(
        self,
        inputs: Sequence[PathLike],
        *,
        agents: Sequence[str] = (),
        warn: Warn | None = None,
        progress: Progress | None = None,
    ) -> list[Trajectory]: ...


@dataclass(frozen=True)
class Source:
    read: SourceReader
    inputs: str
    """What the inputs are, for messages (``one sequence folder``)."""
    agents_from: str
    """What the agents are named after, for messages."""
    one_input: bool = False
    """Exactly one input (a sequence folder), else one or more."""
    takes_agents: bool = False
    """Takes ``--agent NAME=SPEC`` (bags)."""
    odometry: Any = None
    """The source's own odometry (``--odometry real``): ``(inputs, ground_truth, *, warn) ->
    {agent: dead-reckoned Trajectory}`` (:func:`studio.converters.mrclam.read_mrclam_odometry`)."""
    sightings: Any = None
    """The source's agent-to-agent range-bearing sightings: ``(inputs, *, warn) -> Sightings``."""


def _read_bag(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    from studio.converters.rosbag import read_bag_sources

    return read_bag_sources(inputs, agents=agents, warn=warn, progress=progress)


SOURCES: dict[str, Source] = {
    "tum": Source(read_tum_sources, "trajectory files", "their files"),
    "s3e": Source(read_s3e, "one sequence folder", "alpha, bob and carol", one_input=True),
    "airmuseum": Source(read_airmuseum, "one sequence folder", "the robot folders", one_input=True),
    "bag": Source(_read_bag, "bags", "the --agent names", takes_agents=True),
    "euroc": Source(read_euroc, "sequence folders (e.g. MH_01_easy)", "their sequences"),
    "kitti": Source(read_kitti, "poses files (e.g. poses/00.txt)", "their files"),
    "kimera-multi": Source(read_kimera_multi, "a ground-truth folder", "the robots' files"),
    "mrclam": Source(
        read_mrclam,
        "one dataset folder (e.g. MRCLAM_Dataset1)",
        "Robot1..Robot5",
        one_input=True,
        odometry=read_mrclam_odometry,
        sightings=read_mrclam_sightings,
    ),
}
#: Each source's reader.
READERS: dict[str, SourceReader] = {name: src.read for name, src in SOURCES.items()}


def source_names() -> list[str]:
    return list(READERS)


def get_source(name: str) -> Source:
    try:
        return SOURCES[name]
    except KeyError:
        raise ConfigError(f"unknown source format {name!r} (known: {', '.join(SOURCES)})") from None


def get_reader(name: str) -> SourceReader:
    return get_source(name).read


def check_inputs(name: str, inputs: Sequence[PathLike], agents: Sequence[str]) -> None:
    """The source's facts, checked once before its reader runs."""
    src = get_source(name)
    if agents and not src.takes_agents:
        raise ConfigError(f"--agent is only for `studio convert bag`; {name} agents are named after {src.agents_from}")
    if src.one_input and len(inputs) != 1:
        raise ConfigError(f"studio convert {name} takes {src.inputs}, got {len(inputs)} inputs")
    if not inputs:
        raise ConfigError(f"studio convert {name} needs {src.inputs}")


def _kind_of(path: Path) -> str | None:
    """The source one input path unambiguously belongs to, or None."""
    from studio.converters.airmuseum import find_ground_truth_files
    from studio.converters.s3e import _GT as S3E_GT

    if path.suffix in (".bag", ".mcap") or (path.is_dir() and (path / "metadata.yaml").is_file()):
        return "bag"
    if path.is_dir():
        if euroc_ground_truth(path) is not None:
            return "euroc"
        if kimera_files(path):
            return "kimera-multi"
        if (path / "Robot1_Groundtruth.dat").is_file():
            return "mrclam"
        entries = [*path.iterdir(), *(q for d in path.iterdir() if d.is_dir() for q in d.iterdir())]
        if any(S3E_GT.match(q.name) for q in entries):
            return "s3e"
        if (path / "data").is_dir() and find_ground_truth_files(path):
            return "airmuseum"
        return None
    if path.name == "data.csv" and euroc_ground_truth(path) is not None:
        return "euroc"
    if path.name.endswith("_gt_odom.csv"):
        return "kimera-multi"
    if path.suffix == ".tum":
        return "tum"
    if path.suffix == ".txt" and path.is_file():
        with open(path, encoding="utf-8", errors="replace") as f:
            for line in f:
                fields = line.replace(",", " ").split()
                if fields and not line.lstrip().startswith("#"):
                    return "kitti" if len(fields) == 12 else "tum" if len(fields) == 8 else None
    return None


def guess_source(inputs: Sequence[PathLike]) -> str:
    """The source format of ``inputs`` where the paths tell it unambiguously (a ``.bag``/``.mcap``
    or a folder with ``metadata.yaml``: bag; an EuRoC sequence folder; a Kimera-Multi ground-truth
    folder; an S3E or AirMuseum sequence; ``.tum`` files; a KITTI poses file of 12 numbers per line).
    Otherwise a ConfigError asks for the source by name."""
    from pathlib import Path

    if not inputs:
        raise ConfigError("give a source (" + ", ".join(READERS) + ") and its inputs, or --config")
    kinds = {str(p): _kind_of(Path(p)) for p in inputs}
    unknown = [p for p, k in kinds.items() if k is None]
    found = {k for k in kinds.values() if k is not None}
    if unknown or len(found) != 1:
        why = (
            f"cannot tell the source of {unknown[0]}" if unknown else f"the inputs look like {', '.join(sorted(found))}"
        )
        raise ConfigError(f"{why}: name it (studio convert SOURCE INPUT..., SOURCE one of {', '.join(READERS)})")
    return found.pop()
