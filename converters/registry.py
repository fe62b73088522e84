"""The source formats ``studio convert`` knows: an explicit dict from name to :class:`Source`.

Every reader follows the :class:`SourceReader` seam: ``reader(inputs, *, agents=(), warn=None,
progress=None) -> list[Trajectory]``, where ``inputs`` are the paths given on the command line and
``agents`` the ``NAME=SPEC`` strings of ``--agent``. A source's facts (does it take ``--agent``, how
many inputs, what its agents are named after, its help line, how its paths are recognised, its
agents' default body frames, the options a graph source reads) are declared once in its entry, and :func:`check_inputs` checks them
before any reader runs; ``studio convert``'s help and source list are built from the entries.
Each entry names its reader, detection and other code by module and attribute
(:class:`~studio.core.lazy.Lazy`): a module is imported when its source is used, so a command pays
only for the sources it reads. A new source is one module with its reader and one entry here.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from studio.core.errors import ConfigError
from studio.core.lazy import Lazy, LazyMapping
from studio.core.types import PathLike

if TYPE_CHECKING:
    from studio.converters.graph_split import GraphImportOptions, ImportedGraph
    from studio.core.trajectory import Trajectory, Warn
    from studio.runtime.progress import Progress

__all__ = [
    "SourceReader",
    "GraphReader",
    "Source",
    "SOURCES",
    "READERS",
    "get_reader",
    "get_source",
    "source_names",
    "check_inputs",
    "detect_sources",
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


class Detect(Protocol):
    """True when one input path is unmistakably this source's (it must not raise on other data)."""

    def __call__(self, path: Path) -> bool: ...


class GraphReader(Protocol):
    """Read a graph source's inputs (a JRL file, a folder of Symbol-keyed g2o files, DPGO CSVs, a
    single g2o) into its pose graph and labelled outliers, measurements as they are."""

    def __call__(
        self, inputs: Sequence[PathLike], *, warn: Warn | None = None, options: GraphImportOptions | None = None
    ) -> ImportedGraph: ...


@dataclass(frozen=True)
class Source:
    """One source format as the registry declares it: the whole declaration of a source."""

    read: SourceReader
    inputs: str
    """What the inputs are, for messages and ``studio convert --help`` (``one sequence folder``)."""
    agents_from: str
    """What the agents are named after, for messages."""
    help: str = ""
    """One line for ``studio convert --help``: what the source is."""
    one_input: bool = False
    """Exactly one input (a sequence folder), else one or more."""
    takes_agents: bool = False
    """Takes ``--agent NAME=SPEC`` (bags)."""
    detect: Detect | None = None
    """Recognises an input path of this source, for :func:`guess_source` (None: never guessed)."""
    body_frames: Mapping[str, str] = field(default_factory=dict)
    """Default body frames (``FLU`` codes) of the agents, by lower-case agent name; ``--body-frame`` wins."""
    read_graph: GraphReader | None = None
    """Graph sources: the reader of the graph itself, which ``studio convert`` writes as it is (then
    ``read`` gives the graph's ground truth as trajectories, for :func:`studio.convert.convert`)."""
    odometry: Any = None
    """The source's own odometry (``--odometry real``): ``(inputs, ground_truth, *, warn) ->
    {agent: dead-reckoned Trajectory}`` (:func:`studio.converters.mrclam.read_mrclam_odometry`)."""
    sightings: Any = None
    """The source's agent-to-agent range-bearing sightings: ``(inputs, *, warn) -> Sightings``."""
    graph_options: tuple[str, ...] = ()
    """Graph sources: the :class:`~studio.converters.options.GraphImportOptions` fields its graph
    reader reads (g2o: the split into robots, where the ground truth comes from); ``studio convert``
    refuses the others (:func:`studio.convert_config.check_source_options`)."""


def _read_bag(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    from studio.converters.rosbag import read_bag_sources

    return read_bag_sources(inputs, agents=agents, warn=warn, progress=progress)


def _first_row_width(path: Path) -> int | None:
    """The number of fields of a ``.txt`` file's first data line (not a ``#`` comment), or None."""
    if path.suffix != ".txt" or not path.is_file():
        return None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            fields = line.replace(",", " ").split()
            if fields and not line.lstrip().startswith("#"):
                return len(fields)
    return None


def _is_tum(path: Path) -> bool:
    return path.suffix == ".tum" or _first_row_width(path) == 8


def _is_kitti(path: Path) -> bool:
    return _first_row_width(path) == 12


def _is_bag(path: Path) -> bool:
    return path.suffix in (".bag", ".mcap") or (path.is_dir() and (path / "metadata.yaml").is_file())


def _is_euroc(path: Path) -> bool:
    from studio.converters.euroc import euroc_ground_truth

    return (path.is_dir() or path.name == "data.csv") and euroc_ground_truth(path) is not None


def _is_kimera_multi(path: Path) -> bool:
    from studio.converters.kimera_multi import SUFFIX as KIMERA_SUFFIX
    from studio.converters.kimera_multi import kimera_files

    return bool(kimera_files(path)) if path.is_dir() else path.name.endswith(KIMERA_SUFFIX)


def _is_mrclam(path: Path) -> bool:
    return path.is_dir() and (path / "Robot1_Groundtruth.dat").is_file()


def _is_jrl(path: Path) -> bool:
    return path.suffix == ".jrl" and path.is_file()


def _is_g2o(path: Path) -> bool:
    return path.suffix == ".g2o" and path.is_file()


def _is_symbols(path: Path) -> bool:
    return path.is_dir() and any((path / name).is_file() for name in ("fullGraph.g2o", "0.g2o", "robot_a.g2o"))


def _is_dpgo(path: Path) -> bool:
    if path.is_file():
        return path.name == "measurements.csv"
    return path.is_dir() and any((q / "measurements.csv").is_file() for q in path.iterdir() if q.is_dir())


SOURCES: dict[str, Source] = {
    "tum": Source(
        Lazy("studio.converters.tum", "read_tum_sources"),
        "trajectory files",
        "their files",
        "TUM trajectories, one agent per file",
        detect=_is_tum,
    ),
    "s3e": Source(
        Lazy("studio.converters.s3e", "read_s3e"),
        "one sequence folder",
        "alpha, bob and carol",
        "an S3E sequence (<agent>_gt.txt, or its bag's GNSS fixes)",
        one_input=True,
        detect=Lazy("studio.converters.s3e", "is_s3e_sequence"),
    ),
    "airmuseum": Source(
        Lazy("studio.converters.airmuseum", "read_airmuseum"),
        "one sequence folder",
        "the robot folders",
        "an AirMuseum scenario (one ground truth per robot; its body frames by default)",
        one_input=True,
        detect=Lazy("studio.converters.airmuseum", "is_airmuseum_sequence"),
        body_frames=LazyMapping("studio.converters.airmuseum", "BODY_FRAMES"),
    ),
    "bag": Source(
        _read_bag,
        "bags (.bag, ROS 2 folder, .mcap)",
        "the --agent names",
        "ROS 1/2 bags, one --agent per robot",
        takes_agents=True,
        detect=_is_bag,
    ),
    "euroc": Source(
        Lazy("studio.converters.euroc", "read_euroc"),
        "sequence folders (e.g. MH_01_easy)",
        "their sequences",
        "EuRoC MAV ground truth",
        detect=_is_euroc,
    ),
    "kitti": Source(
        Lazy("studio.converters.kitti", "read_kitti"),
        "poses files (e.g. poses/00.txt)",
        "their files",
        "KITTI odometry poses",
        detect=_is_kitti,
    ),
    "kimera-multi": Source(
        Lazy("studio.converters.kimera_multi", "read_kimera_multi"),
        "a ground-truth folder",
        "the robots' files",
        "Kimera-Multi ground truth (<robot>_gt_odom.csv)",
        detect=_is_kimera_multi,
    ),
    "jrl": Source(
        Lazy("studio.converters.jrl", "read_jrl_trajectories"),
        "one JRL file",
        "its robots (the names it keeps)",
        "a JRL file (MESA, COSMO-Bench), the graph as it is",
        one_input=True,
        read_graph=Lazy("studio.converters.jrl", "read_jrl_graph"),
        detect=_is_jrl,
    ),
    "symbols": Source(
        Lazy("studio.converters.symbols", "read_symbols_trajectories"),
        "one folder of Symbol-keyed g2o files (0.g2o, 1.g2o, ..., robot_a.g2o, ... or fullGraph.g2o)",
        "their Symbol characters",
        "per-robot g2o files with GTSAM Symbol or LabeledSymbol keys (DGS, Kimera, Swarm-SLAM)",
        one_input=True,
        read_graph=Lazy("studio.converters.symbols", "read_symbols_graph"),
        detect=_is_symbols,
    ),
    "dpgo": Source(
        Lazy("studio.converters.dpgo", "read_dpgo_trajectories"),
        "a folder of measurements.csv files, or the files",
        "robot0..",
        "DPGO's per-robot measurements.csv",
        read_graph=Lazy("studio.converters.dpgo", "read_dpgo_graph"),
        detect=_is_dpgo,
    ),
    "g2o": Source(
        Lazy("studio.converters.g2o", "read_g2o_trajectories"),
        "one .g2o file",
        "the file (robot0.. with --split)",
        "any single g2o graph, split into robots with --split/--partition",
        one_input=True,
        read_graph=Lazy("studio.converters.g2o", "read_g2o_graph"),
        detect=_is_g2o,
        graph_options=("split", "partition", "overlap_s", "ground_truth"),
    ),
    "mrclam": Source(
        Lazy("studio.converters.mrclam", "read_mrclam"),
        "one dataset folder (e.g. MRCLAM_Dataset1)",
        "Robot1..Robot5",
        "UTIAS MR.CLAM (RobotK_Groundtruth.dat; its odometry and robot sightings)",
        one_input=True,
        odometry=Lazy("studio.converters.mrclam", "read_mrclam_odometry"),
        sightings=Lazy("studio.converters.mrclam", "read_mrclam_sightings"),
        detect=_is_mrclam,
    ),
}
#: Each source's reader.
READERS: dict[str, SourceReader] = {name: src.read for name, src in SOURCES.items()}


def source_names() -> list[str]:
    return list(SOURCES)


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


def detect_sources(path: Path) -> list[str]:
    """The sources whose ``detect`` claims ``path`` (none, one, or several when it is ambiguous)."""
    return [name for name, src in SOURCES.items() if src.detect is not None and src.detect(path)]


def guess_source(inputs: Sequence[PathLike]) -> str:
    """The source format of ``inputs`` where the paths tell it unambiguously: every path claimed by
    the ``detect`` of one and the same source (a ``.bag``/``.mcap`` or a folder with ``metadata.yaml``:
    bag; an EuRoC sequence folder; a Kimera-Multi ground-truth folder; an S3E or AirMuseum sequence;
    ``.tum`` files; a KITTI poses file of 12 numbers per line). Otherwise a ConfigError asks for the
    source by name."""
    if not inputs:
        raise ConfigError("give a source (" + ", ".join(READERS) + ") and its inputs, or --config")
    kinds = {str(p): detect_sources(Path(p)) for p in inputs}
    unknown = [p for p, k in kinds.items() if not k]
    found = {name for k in kinds.values() for name in k}
    if unknown or len(found) != 1:
        why = (
            f"cannot tell the source of {unknown[0]}" if unknown else f"the inputs look like {', '.join(sorted(found))}"
        )
        raise ConfigError(f"{why}: name it (studio convert SOURCE INPUT..., SOURCE one of {', '.join(READERS)})")
    return found.pop()
