"""ROS bags through ``rosbags``: ROS 1 ``.bag`` files, ROS 2 bag folders (sqlite3 or mcap storage)
and plain ROS 2 ``.mcap`` files.

An agent is given as ``NAME=SPEC`` where SPEC is

* ``/topic``: ``geometry_msgs/PoseStamped``, ``geometry_msgs/PoseWithCovarianceStamped``,
  ``nav_msgs/Odometry`` or ``sensor_msgs/NavSatFix`` (header stamps, metres);
* ``/fix+/heading``: ``sensor_msgs/NavSatFix`` with its orientation from a
  ``geometry_msgs/QuaternionStamped`` or ``sensor_msgs/Imu`` topic (the heading message nearest in
  time to each fix);
* ``/tf:PARENT:CHILD``: the ``tf2_msgs/TFMessage`` transforms from frame PARENT to frame CHILD
  (direct transforms only, leading ``/`` of frame ids ignored).

GNSS fixes are projected to UTM (WGS 84, the zone of the fixes) with pyproj; fixes with a no-fix
status or NaN coordinates are dropped with a warning; fixes spanning two UTM zones are an error.
Without a heading topic a fix's orientation is the yaw of the direction of travel.

Every failure (unknown topic, unsupported message type, corrupt or truncated bag) is a
:class:`~studio.core.errors.FormatError` naming the bag; an unknown topic lists the bag's topics and types.
"""

from __future__ import annotations

import os
import sqlite3
import struct
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from studio.converters.names import check_agent_name
from studio.core.errors import ConfigError, FormatError
from studio.core.trajectory import Trajectory, Warn, clean_trajectory
from studio.core.types import PathLike
from studio.core.units import NS_PER_S
from studio.runtime.progress import Progress

__all__ = [
    "typestore_for",
    "AgentSpec",
    "parse_agent_spec",
    "read_bag",
    "read_bag_sources",
    "POSE_TYPES",
    "HEADING_TYPES",
]

#: Message types that give a pose (or a position, for NavSatFix) per message.
POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
    "sensor_msgs/msg/NavSatFix",
)
#: Message types that give a heading for NavSatFix.
HEADING_TYPES = ("geometry_msgs/msg/QuaternionStamped", "sensor_msgs/msg/Imu")


@dataclass(frozen=True)
class AgentSpec:
    name: str
    topic: str
    heading_topic: str | None = None
    parent_frame: str | None = None
    child_frame: str | None = None


def parse_agent_spec(text: str) -> AgentSpec:
    """``NAME=/odom``, ``NAME=/fix+/heading`` or ``NAME=/tf:PARENT:CHILD``."""
    where = f"--agent {text}"
    name, sep, spec = text.partition("=")
    if not sep or not spec:
        raise ConfigError(f"{where}: expected NAME=SPEC (SPEC: /topic, /fix+/heading or /tf:PARENT:CHILD)")
    check_agent_name(name, where)
    if ":" in spec:
        parts = spec.split(":")
        if len(parts) != 3 or not all(parts):
            raise ConfigError(f"{where}: a TF spec is /tf:PARENT:CHILD")
        return AgentSpec(name, parts[0], parent_frame=parts[1].lstrip("/"), child_frame=parts[2].lstrip("/"))
    if "+" in spec:
        topic, _, heading = spec.partition("+")
        if not topic or not heading or "+" in heading:
            raise ConfigError(f"{where}: a GNSS spec is /fix+/heading")
        return AgentSpec(name, topic, heading_topic=heading)
    return AgentSpec(name, spec)


#: Definitions the built-in typestores lack (tf2_msgs is not in rosbags' stores).
_EXTRA_MSGS = {"tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n"}


def typestore_for(*, ros1: bool) -> Any:
    """rosbags' ROS 1 Noetic or latest ROS 2 typestore, with tf2_msgs/TFMessage added."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.LATEST)
    types = {}
    for name, text in _EXTRA_MSGS.items():
        if name not in store.types:
            types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * NS_PER_S + int(header.stamp.nanosec)


class _Collector:
    """Columns gathered for one agent while the bag is read (Python lists, then numpy)."""

    def __init__(self, spec: AgentSpec):
        self.spec = spec
        self.stamps: list[int] = []
        self.values: list[tuple[float, ...]] = []
        self.status_dropped = 0
        self.heading_stamps: list[int] = []
        self.headings: list[tuple[float, float, float, float]] = []
        self.frames_seen: set[tuple[str, str]] = set()
        self.kind = ""


def _pose_values(p: Any) -> tuple[float, ...]:
    return (
        p.position.x,
        p.position.y,
        p.position.z,
        p.orientation.x,
        p.orientation.y,
        p.orientation.z,
        p.orientation.w,
    )


def _take(col: _Collector, msgtype: str, msg: Any) -> None:
    if msgtype == "geometry_msgs/msg/PoseStamped":
        col.stamps.append(_stamp(msg.header))
        col.values.append(_pose_values(msg.pose))
    elif msgtype in ("geometry_msgs/msg/PoseWithCovarianceStamped", "nav_msgs/msg/Odometry"):
        col.stamps.append(_stamp(msg.header))
        col.values.append(_pose_values(msg.pose.pose))
    elif msgtype == "tf2_msgs/msg/TFMessage":
        for tr in msg.transforms:
            pair = (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
            if pair == (col.spec.parent_frame, col.spec.child_frame):
                t, r = tr.transform.translation, tr.transform.rotation
                col.stamps.append(_stamp(tr.header))
                col.values.append((t.x, t.y, t.z, r.x, r.y, r.z, r.w))
            elif len(col.frames_seen) < 20:
                col.frames_seen.add(pair)
    elif msgtype == "sensor_msgs/msg/NavSatFix":
        if msg.status.status < 0:  # STATUS_NO_FIX
            col.status_dropped += 1
            return
        col.stamps.append(_stamp(msg.header))
        col.values.append((msg.latitude, msg.longitude, msg.altitude))


def _take_heading(col: _Collector, msgtype: str, msg: Any) -> None:
    q = msg.quaternion if msgtype == "geometry_msgs/msg/QuaternionStamped" else msg.orientation
    col.heading_stamps.append(_stamp(msg.header))
    col.headings.append((q.x, q.y, q.z, q.w))


def _utm(lat: np.ndarray, lon: np.ndarray, where: str) -> np.ndarray:
    from pyproj import Transformer

    zones = np.floor((lon + 180.0) / 6.0).astype(np.int64) % 60 + 1
    south = lat < 0
    keys = np.unique(zones * 2 + south)
    if len(keys) > 1:
        names = [f"{k // 2}{'S' if k % 2 else 'N'}" for k in keys.tolist()]
        raise FormatError(
            f"{where}: NavSatFix positions span UTM zones {' and '.join(names)}; split the recording per zone"
        )
    zone, is_south = int(zones[0]), bool(south[0])
    epsg = (32700 if is_south else 32600) + zone
    tr = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    east, north = tr.transform(lon, lat)
    return np.column_stack([east, north])


def _course_over_ground(pos: np.ndarray) -> np.ndarray:
    """Yaw quaternions along the direction of travel: the chord from the previous to the next fix
    (central difference), held while standing still (chord under 1 mm)."""
    n = len(pos)
    ahead = pos[np.minimum(np.arange(n) + 1, n - 1), :2]
    behind = pos[np.maximum(np.arange(n) - 1, 0), :2]
    chord = ahead - behind
    moving = np.hypot(chord[:, 0], chord[:, 1]) > 1e-3
    yaw_chord = np.arctan2(chord[:, 1], chord[:, 0])
    idx = np.maximum.accumulate(np.where(moving, np.arange(n), -1))
    first = int(np.argmax(moving)) if moving.any() else -1
    yaw = yaw_chord[np.where(idx < 0, first, idx)] if first >= 0 else np.zeros(n)
    return np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])


def _nearest(stamps: np.ndarray, query: np.ndarray) -> np.ndarray:
    k = np.clip(np.searchsorted(stamps, query), 1, len(stamps) - 1)
    left = stamps[k - 1]
    right = stamps[k]
    return np.where(query - left <= right - query, k - 1, k)


def _finish(col: _Collector, bag: str, warn: Warn | None) -> Trajectory:
    spec = col.spec
    where = f"{bag} {spec.topic}"
    if not col.stamps:
        if spec.parent_frame is not None:
            seen = ", ".join(f"{a}->{b}" for a, b in sorted(col.frames_seen)) or "none"
            raise FormatError(
                f"{where}: no transform {spec.parent_frame}->{spec.child_frame} (transforms seen: {seen})"
            )
        extra = f" ({col.status_dropped} with no fix dropped)" if col.status_dropped else ""
        raise FormatError(f"{where}: no usable messages{extra}; a trajectory needs at least 2")
    stamps = np.array(col.stamps, dtype=np.int64)
    vals = np.array(col.values, dtype=np.float64)
    if col.kind == "sensor_msgs/msg/NavSatFix":
        finite = np.isfinite(vals).all(axis=1)
        dropped = col.status_dropped + int(np.count_nonzero(~finite))
        stamps, vals = stamps[finite], vals[finite]
        if dropped and warn is not None:
            warn(f"{where}: {dropped} fix{'es' if dropped != 1 else ''} without a position dropped")
        if len(stamps) < 2:
            raise FormatError(f"{where}: {len(stamps)} usable fixes; a trajectory needs at least 2")
        order = np.argsort(stamps, kind="stable")
        stamps, vals = stamps[order], vals[order]
        en = _utm(vals[:, 0], vals[:, 1], where)
        pos = np.column_stack([en, vals[:, 2]])
        if spec.heading_topic is not None:
            if not col.headings:
                raise FormatError(f"{bag} {spec.heading_topic}: no heading messages")
            hs = np.array(col.heading_stamps, dtype=np.int64)
            hq = np.array(col.headings, dtype=np.float64)
            o = np.argsort(hs, kind="stable")
            hs, hq = hs[o], hq[o]
            quat = hq[_nearest(hs, stamps)] if len(hs) > 1 else np.repeat(hq, len(stamps), axis=0)
        else:
            quat = _course_over_ground(pos)
        return clean_trajectory(spec.name, stamps, pos, quat, where, warn)
    return clean_trajectory(spec.name, stamps, vals[:, :3], vals[:, 3:], where, warn)


class _PlainMcap:
    """A plain ``.mcap`` file (no ``metadata.yaml``), read with rosbags' MCAP storage reader and the
    same interface as ``AnyReader``: ``topics``, ``connections``, ``messages()``, ``deserialize()``.
    Message definitions stored in the file are registered like ``AnyReader`` does."""

    def __init__(self, path: Path, store: Any) -> None:
        from rosbags.rosbag2.storage_mcap import McapReader

        self._reader = McapReader(path)
        self._store = store
        self.connections: list[Any] = []

    def __enter__(self) -> _PlainMcap:
        from rosbags.interfaces import MessageDefinitionFormat
        from rosbags.rosbag2 import ReaderError
        from rosbags.typesys import get_types_from_idl, get_types_from_msg

        try:
            self._reader.open()
        except (TypeError, ValueError, IndexError, AssertionError) as err:  # rosbags' MCAP reader on a cut file
            raise ReaderError(f"malformed MCAP ({type(err).__name__}: {err})") from None
        self.connections = list(self._reader.connections)
        types = {}
        for conn in self.connections:
            if conn.msgtype in self._store.types:
                continue
            if conn.msgdef.format == MessageDefinitionFormat.MSG:
                types.update(get_types_from_msg(conn.msgdef.data, conn.msgtype))
            elif conn.msgdef.format == MessageDefinitionFormat.IDL:
                types.update(get_types_from_idl(conn.msgdef.data))
        self._store.register(types)
        return self

    def __exit__(self, *exc: object) -> None:
        self._reader.close()

    @property
    def topics(self) -> dict[str, Any]:
        from types import SimpleNamespace

        return {c.topic: SimpleNamespace(msgtype=c.msgtype) for c in self.connections}

    def messages(self, connections: Any) -> Iterator[tuple[Any, int, bytes]]:
        from rosbags.rosbag2 import ReaderError

        try:
            yield from self._reader.messages(connections)
        except (TypeError, ValueError, IndexError, AssertionError) as err:
            raise ReaderError(f"malformed MCAP ({type(err).__name__}: {err})") from None

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        return self._store.deserialize_cdr(raw, msgtype)


def _open_errors() -> tuple[type[BaseException], ...]:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as ReaderError1
    from rosbags.rosbag2 import ReaderError as ReaderError2
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    return (
        AnyReaderError,
        ReaderError1,
        ReaderError2,
        SerdeError,
        TypesysError,
        sqlite3.Error,
        struct.error,
        EOFError,
        OSError,
        UnicodeDecodeError,
    )  # e.g. one inverted byte in metadata.yaml


def read_bag(
    bag: PathLike | Sequence[PathLike],
    specs: Sequence[AgentSpec] | Mapping[str, str],
    *,
    warn: Warn | None = None,
    skip_missing: bool = False,
    progress: Progress | None = None,
    ignore_case: bool = False,
) -> list[Trajectory]:
    """One trajectory per agent spec, read in one pass over the bag.

    ``specs`` is a list of :class:`AgentSpec` or a ``{name: SPEC}`` mapping. With ``skip_missing`` an
    agent whose topics are not in the bag is left out instead of raising. With ``ignore_case`` a
    topic matches the bag's topic of the same name in any case (S3E's ``/Alpha/fix``).
    """
    from rosbags.highlevel import AnyReader

    paths = [Path(p) for p in ([bag] if isinstance(bag, (str, os.PathLike)) else bag)]
    name = ", ".join(str(p) for p in paths)
    if isinstance(specs, Mapping):
        specs = [parse_agent_spec(f"{k}={v}") for k, v in specs.items()]
    is_ros1, plain_mcap = _check_bag_paths(paths, name)
    store = typestore_for(ros1=is_ros1)
    errors = _open_errors()
    try:
        with _PlainMcap(paths[0], store) if plain_mcap else AnyReader(paths, default_typestore=store) as reader:
            topics = {t: info.msgtype for t, info in reader.topics.items()}
            cols, by_topic = _collectors(specs, topics, name, skip_missing=skip_missing, ignore_case=ignore_case)
            if not cols:  # every agent skipped (skip_missing): an empty filter would read everything
                return []
            _read_messages(reader, by_topic, progress)
    except FormatError:
        raise
    except errors as err:
        detail = str(err).strip().splitlines()[0][:200] if str(err).strip() else type(err).__name__
        raise FormatError(f"{name}: cannot read the bag, corrupt or truncated? ({detail})") from None
    return [_finish(col, name, warn) for col in cols]


def _check_bag_paths(paths: list[Path], name: str) -> tuple[bool, bool]:
    """Refuse what is not a bag before opening anything; returns (all ROS 1, one plain .mcap file)."""
    for p in paths:
        if not p.exists():
            raise FormatError(f"{p}: no such bag")
        if p.is_dir() and not (p / "metadata.yaml").is_file():
            raise FormatError(f"{p}: a folder without metadata.yaml is not a ROS 2 bag")
        if p.is_file() and p.suffix not in (".bag", ".mcap"):
            raise FormatError(f"{p}: not a ROS 1 .bag file, a ROS 2 bag folder or an .mcap file")
    is_ros1 = all(p.suffix == ".bag" for p in paths)
    plain_mcap = len(paths) == 1 and paths[0].is_file() and paths[0].suffix == ".mcap"
    if not plain_mcap and any(p.suffix == ".mcap" for p in paths):
        raise FormatError(f"{name}: give one .mcap file at a time")
    return is_ros1, plain_mcap


def _collectors(
    specs: Sequence[AgentSpec],
    topics: dict[str, str | None],
    name: str,
    *,
    skip_missing: bool,
    ignore_case: bool,
) -> tuple[list[_Collector], dict[str, list[tuple[_Collector, bool]]]]:
    """One collector per agent spec whose topics the bag has, and the collectors each topic feeds
    (``True``: as the agent's heading topic)."""
    listing = ", ".join(f"{t} [{(m or '?').replace('/msg/', '/')}]" for t, m in sorted(topics.items()))
    if ignore_case:
        lower = {t.lower(): t for t in topics}

        def actual(t: str) -> str:
            return lower.get(t.lower(), t)

        specs = [
            replace(
                sp,
                topic=actual(sp.topic),
                heading_topic=None if sp.heading_topic is None else actual(sp.heading_topic),
            )
            for sp in specs
        ]
    cols: list[_Collector] = []
    by_topic: dict[str, list[tuple[_Collector, bool]]] = {}
    for spec in specs:
        missing = [t for t in (spec.topic, spec.heading_topic) if t is not None and t not in topics]
        if missing:
            if skip_missing:
                continue
            raise FormatError(f"{name}: no topic {missing[0]!r} for agent {spec.name} (topics: {listing})")
        col = _Collector(spec)
        col.kind = topics[spec.topic] or ""
        _check_topic_types(spec, col.kind, topics, name)
        if spec.heading_topic is not None:
            by_topic.setdefault(spec.heading_topic, []).append((col, True))
        by_topic.setdefault(spec.topic, []).append((col, False))
        cols.append(col)
    return cols, by_topic


def _check_topic_types(spec: AgentSpec, kind: str, topics: dict[str, str | None], name: str) -> None:
    """The agent's pose topic (and heading topic) have types the reader takes, in a combination it takes."""
    if kind not in POSE_TYPES:
        raise FormatError(
            f"{name}: topic {spec.topic} has type {kind}, which is not supported "
            f"(supported: {', '.join(t.replace('/msg/', '/') for t in POSE_TYPES)})"
        )
    if (kind == "tf2_msgs/msg/TFMessage") != (spec.parent_frame is not None):
        raise FormatError(
            f"{name}: topic {spec.topic} is {kind}; TF topics take /tf:PARENT:CHILD and only TF topics do"
        )
    if spec.heading_topic is not None:
        if kind != "sensor_msgs/msg/NavSatFix":
            raise FormatError(f"{name}: a heading topic goes with a NavSatFix topic, {spec.topic} is {kind}")
        htype = topics[spec.heading_topic]
        if htype not in HEADING_TYPES:
            raise FormatError(
                f"{name}: heading topic {spec.heading_topic} has type {htype}, which "
                f"is not supported (supported: "
                f"{', '.join(t.replace('/msg/', '/') for t in HEADING_TYPES)})"
            )


def _read_messages(reader: Any, by_topic: dict[str, list[tuple[_Collector, bool]]], progress: Any) -> None:
    """One pass over the messages of the wanted topics, each fed to its collectors."""
    conns = [c for c in reader.connections if c.topic in by_topic]
    total = sum(c.msgcount for c in conns)
    done = 0
    for conn, _t, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        for col, is_heading in by_topic[conn.topic]:
            if is_heading:
                _take_heading(col, conn.msgtype, msg)
            else:
                _take(col, conn.msgtype, msg)
        done += 1
        if progress is not None and (done % 20000 == 0 or done == total):
            progress("reading bag", done, total, "messages")


def read_bag_sources(
    inputs: Sequence[PathLike],
    *,
    agents: Sequence[str] = (),
    warn: Warn | None = None,
    progress: Progress | None = None,
) -> list[Trajectory]:
    """``studio convert bag BAG --agent NAME=SPEC ...``: agents in the order given."""
    if not inputs:
        raise ConfigError("studio convert bag needs a bag (a ROS 1 .bag file, a ROS 2 bag folder or an .mcap file)")
    if not agents:
        raise ConfigError(
            "studio convert bag needs at least one --agent NAME=SPEC (SPEC: /topic, /fix+/heading or /tf:PARENT:CHILD)"
        )
    specs = [parse_agent_spec(a) for a in agents]
    names = [s.name for s in specs]
    for n in names:
        if names.count(n) > 1:
            raise ConfigError(f"--agent: the name {n!r} is given twice")
    if len(inputs) > 1 and not all(Path(p).suffix == ".bag" for p in inputs):
        raise ConfigError("several inputs must all be ROS 1 .bag files (a ROS 2 bag is one folder)")
    return read_bag(list(inputs), specs, warn=warn, progress=progress)
