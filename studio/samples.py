"""``studio samples DIR``: a small simulated sample in every source's layout, to try the commands on.

The data is simulated (smooth loops, unicycle robots); the layouts are the real ones: TUM files,
an S3E sequence, AirMuseum scenarios, ROS 1 and ROS 2 bags, EuRoC sequences, a KITTI poses file, a
Kimera-Multi ground-truth folder, an MR.CLAM dataset folder, a drifting VIO estimate, a single g2o
graph and a small kollagen config. No dataset's files are copied. Names are the layouts' own
(``MRCLAM_Dataset1``, ``MH_01_easy``) or plain (``single_robot.g2o``, ``sample_config.json``); none
is the name of a synth preset, so ``studio synth PRESET`` inside the folder is the preset.

The tests build their fixtures with these writers too (``tests/converters``), and the docs' commands
run on them (``tests/test_docs_commands.py``). The folder is written through the output guard
(:func:`studio.io.atomic.staged_outputs`): all of it or nothing, replaced only with ``force``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from studio.core.types import PathLike

__all__ = [
    "SAMPLES",
    "write_samples",
    "UTM_EAST",
    "UTM_NORTH",
    "loop_trajectory",
    "tum_text",
    "write_tum_file",
    "drifting_estimate",
    "Msgs",
    "typestore",
    "write_bag",
    "utm31_to_latlon",
    "write_mrclam_dataset",
    "s3e_folder",
    "airmuseum_folder",
    "euroc_sequence",
]

UTM_EAST, UTM_NORTH = 500_000.0, 4_649_776.0  # a UTM-sized origin (zone 31 around 42 N)


# --------------------------------------------------------------------------------- trajectories


def loop_trajectory(
    n: int = 400,
    *,
    rate_hz: float = 10.0,
    radius: float = 10.0,
    laps: float = 2.0,
    centre: Sequence[float] = (0.0, 0.0, 0.0),
    phase: float = 0.0,
    t0_s: float = 1_600_000_000.0,
    climb: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` poses on a circle driven ``laps`` times, heading along the motion: ``(stamps_ns,
    positions_xyz, quat_xyzw)``."""
    k = np.arange(n)
    ang = phase + 2 * np.pi * laps * k / (n - 1)
    pos = np.column_stack(
        [centre[0] + radius * np.cos(ang), centre[1] + radius * np.sin(ang), centre[2] + climb * k / n]
    )
    yaw = ang + np.pi / 2
    quat = np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    stamps_ns = np.int64(round(t0_s * 1e9)) + (k * (1e9 / rate_hz)).astype(np.int64)
    return stamps_ns, pos, quat


def tum_text(
    stamps_ns: np.ndarray,
    pos: np.ndarray,
    quat: np.ndarray,
    *,
    sep: str = " ",
    header: str | None = "# timestamp tx ty tz qx qy qz qw",
) -> str:
    lines = [header] if header else []
    for s, p, q in zip(stamps_ns.tolist(), pos.tolist(), quat.tolist()):
        sec, ns = divmod(s, 1_000_000_000)
        vals = [f"{sec}.{ns:09d}"] + [repr(v) for v in p + q]
        lines.append(sep.join(vals))
    return "\n".join(lines) + "\n"


def write_tum_file(path: Path, stamps_ns: np.ndarray, pos: np.ndarray, quat: np.ndarray, **kw: Any) -> Path:
    path.write_text(tum_text(stamps_ns, pos, quat, **kw))
    return path


def drifting_estimate(
    stamps: np.ndarray, pos: np.ndarray, quat: np.ndarray, *, scale: float, yaw_rate: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """A VIO-like estimate of a trajectory: its motion scaled by ``scale``, its heading drifting by
    ``yaw_rate`` rad/s, plus 2 mm of noise per step, in its own frame (starting at the origin).
    Returns ``(positions_xyz, quat_xyzw)``."""
    from studio.core.geometry import quat_from_rotvec, quat_mul, quat_rotate

    rng = np.random.default_rng(seed)
    t = (np.asarray(stamps) - stamps[0]) / 1e9
    drift = quat_from_rotvec(np.column_stack([np.zeros((len(t), 2)), yaw_rate * t]))
    steps = np.diff(pos, axis=0) * scale + rng.normal(0, 0.002, (len(pos) - 1, 3))
    steps[:, 2] = 0.0
    p = np.vstack([np.zeros(3), np.cumsum(quat_rotate(drift[1:], steps), axis=0)])
    return p, quat_mul(drift, quat)


# ----------------------------------------------------------------------------------------- bags


def typestore(storage: str) -> Any:
    from studio.converters.rosbag import typestore_for

    return typestore_for(ros1=storage == "ros1")


class Msgs:
    """Message builders for one rosbags typestore (ROS 1 headers carry a ``seq``); the messages are
    rosbags' own dataclasses (``Any``: rosbags' types are generated)."""

    def __init__(self, ts: Any) -> None:
        self.ts = ts
        self.T = ts.types
        self.ros1 = "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, ns: int, frame: str = "map") -> Any:
        stamp = self.T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        kw = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame, **kw)

    def pose(self, p: Sequence[float], q: Sequence[float]) -> Any:
        T = self.T
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]), orientation=self.quat(q)
        )

    def quat(self, q: Sequence[float]) -> Any:
        return self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])

    def pose_cov(self, p: Sequence[float], q: Sequence[float]) -> Any:
        return self.T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(p, q), covariance=np.zeros(36))

    def PoseStamped(self, ns: int, p: Sequence[float], q: Sequence[float]) -> Any:
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(ns), pose=self.pose(p, q))

    def PoseWithCovarianceStamped(self, ns: int, p: Sequence[float], q: Sequence[float]) -> Any:
        return self.T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=self.header(ns), pose=self.pose_cov(p, q))

    def Odometry(self, ns: int, p: Sequence[float], q: Sequence[float]) -> Any:
        T = self.T
        v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=v, angular=v), covariance=np.zeros(36)
        )
        return T["nav_msgs/msg/Odometry"](
            header=self.header(ns, "odom"), child_frame_id="base_link", pose=self.pose_cov(p, q), twist=twist
        )

    def TFMessage(
        self, ns: int, p: Sequence[float], q: Sequence[float], parent: str = "odom", child: str = "base_link"
    ) -> Any:
        T = self.T

        def tr(par: str, ch: str, pp: Sequence[float], qq: Sequence[float]) -> Any:
            return T["geometry_msgs/msg/TransformStamped"](
                header=self.header(ns, par),
                child_frame_id=ch,
                transform=T["geometry_msgs/msg/Transform"](
                    translation=T["geometry_msgs/msg/Vector3"](x=pp[0], y=pp[1], z=pp[2]), rotation=self.quat(qq)
                ),
            )

        other = tr("base_link", "camera", (0.1, 0.0, 0.3), (0.0, 0.0, 0.0, 1.0))
        return T["tf2_msgs/msg/TFMessage"](transforms=[other, tr(parent, child, p, q)])

    def NavSatFix(self, ns: int, lat: float, lon: float, alt: float, status: int = 0) -> Any:
        T = self.T
        st = T["sensor_msgs/msg/NavSatStatus"](status=status, service=1)
        return T["sensor_msgs/msg/NavSatFix"](
            header=self.header(ns, "gps"),
            status=st,
            latitude=lat,
            longitude=lon,
            altitude=alt,
            position_covariance=np.zeros(9),
            position_covariance_type=0,
        )

    def QuaternionStamped(self, ns: int, q: Sequence[float]) -> Any:
        return self.T["geometry_msgs/msg/QuaternionStamped"](header=self.header(ns), quaternion=self.quat(q))

    def Imu(self, ns: int, q: Sequence[float]) -> Any:
        T = self.T
        v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        return T["sensor_msgs/msg/Imu"](
            header=self.header(ns, "imu"),
            orientation=self.quat(q),
            orientation_covariance=np.zeros(9),
            angular_velocity=v,
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=v,
            linear_acceleration_covariance=np.zeros(9),
        )

    def String(self, ns: int) -> Any:
        return self.T["std_msgs/msg/String"](data="hello")


def write_bag(path: Path, storage: str, topics: dict[str, list[tuple[int, Any]]]) -> Path:
    """Write ``{topic: [(stamp_ns, message), ...]}`` as a ROS 1 ``.bag`` or a ROS 2 folder
    (``storage``: ``ros1``, ``sqlite3`` or ``mcap``), with rosbags' own writers."""
    ts = typestore(storage)
    if storage == "ros1":
        from rosbags.rosbag1 import Writer as Writer1

        path = path.with_suffix(".bag")
        with Writer1(path) as w:
            for topic, msgs in topics.items():
                conn = w.add_connection(topic, msgs[0][1].__msgtype__, typestore=ts)
                for t, m in msgs:
                    w.write(conn, t, ts.serialize_ros1(m, m.__msgtype__))
        return path
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w2:
        for topic, msgs in topics.items():
            conn = w2.add_connection(topic, msgs[0][1].__msgtype__, typestore=ts)
            for t, m in msgs:
                w2.write(conn, t, ts.serialize_cdr(m, m.__msgtype__))
    return path


def utm31_to_latlon(east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from pyproj import Transformer

    lon, lat = Transformer.from_crs("EPSG:32631", "EPSG:4326", always_xy=True).transform(east, north)
    return np.asarray(lat), np.asarray(lon)


# ------------------------------------------------------------------------------------- MR.CLAM

_MRCLAM_T0_S = 1248272262.841  # a stamp in MR.CLAM's range (July 2009)
ROBOT_BARCODES = (5, 14, 41, 32, 23)
LANDMARK_BARCODES = (72, 27, 54, 70, 36, 18, 25, 9, 81, 16, 90, 61, 45, 7, 63)
RANGE_SIGMA_M = 0.05
BEARING_SIGMA_RAD = 0.02
_MRCLAM_HEAD = (
    "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n"
    "# produced by Keith Leung (keith.leung@robotics.utias.utoronto.ca) 2009\n"
    "# (simulated stand-in written by studio.samples)\n"
)


def _write_dat(path: Path, columns: str, rows: np.ndarray, fmts: list[str], padded: bool = False) -> None:
    """``padded``: as the real files are laid out (the copies in public repositories): each column
    right-aligned and followed by a space, columns joined by a tab, a space before every tab and at
    the end of the line (``1248444175.103 \\t 1.41277290 \\t -3.89107760 \\t 2.26960000 ``)."""
    fmt = " \t ".join(fmts) + " " if padded else "\t".join(fmts)
    lines = [fmt % tuple(r) for r in rows.tolist()]
    path.write_text(_MRCLAM_HEAD + "# " + columns + "\n" + "\n".join(lines) + "\n", encoding="utf-8")


def simulate_mrclam(seconds: float, seed: int, lag_s: float = 0.0) -> list[Any]:
    """Per robot: ``(truth, commands, dense)``: the ground truth ``(t, x, y, theta)`` at 100 Hz with 1 mm
    of noise, the velocity commands ``(t, v, w)`` at about 67 Hz (piecewise constant, some turns on the
    spot), the true motion ``(t, x, y, theta)`` at 1 kHz (the command with a scale error and noise).
    ``lag_s``: the robots move ``lag_s`` after each command (the real robots follow theirs by
    0.15-0.2 s)."""
    rng = np.random.default_rng(seed)
    robots = []
    n = int(seconds * 1000)
    for k in range(5):
        cmd_t = np.cumsum(rng.uniform(0.010, 0.020, int(seconds / 0.010)))
        cmd_t = cmd_t[cmd_t < seconds]
        seg = (cmd_t // 2.0).astype(int)  # a new command every 2 s
        nseg = seg.max() + 1
        v_seg = rng.uniform(0.05, 0.3, nseg)
        w_seg = rng.uniform(-0.4, 0.4, nseg)
        spot = rng.random(nseg) < 0.15  # turns on the spot
        v_seg[spot] = 0.0
        w_seg[spot] = rng.choice([-0.8, 0.8], int(spot.sum()))
        v_cmd, w_cmd = v_seg[seg], w_seg[seg]
        t_ms = np.arange(n) / 1000.0
        idx = np.clip(np.searchsorted(cmd_t, t_ms - lag_s, side="right") - 1, 0, len(cmd_t) - 1)
        before = t_ms - lag_s < cmd_t[0]
        v = np.where(before, 0.0, v_cmd[idx]) * (1.03 + 0.02 * k) + rng.normal(0, 0.02, n)
        w = np.where(before, 0.0, w_cmd[idx]) * 0.97 + rng.normal(0, 0.05, n)
        v[before] = w[before] = 0.0
        th = rng.uniform(-np.pi, np.pi) + np.concatenate([[0.0], np.cumsum(w[:-1] / 1000.0)])
        x = 1.2 * k - 2.4 + np.concatenate([[0.0], np.cumsum(v[:-1] * np.cos(th[:-1]) / 1000.0)])
        y = 0.5 * (k % 2) + np.concatenate([[0.0], np.cumsum(v[:-1] * np.sin(th[:-1]) / 1000.0)])
        gt = np.arange(0, n, 10)
        truth = (t_ms[gt], x[gt] + rng.normal(0, 0.001, len(gt)), y[gt] + rng.normal(0, 0.001, len(gt)), th[gt])
        robots.append((truth, (cmd_t, v_cmd, w_cmd), (t_ms, x, y, th)))
    return robots


def _sightings(robots: list[Any], k: int, landmarks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Robot ``k``'s camera frames every 0.2 s: the other robots and the landmarks within 5 m and
    +-30 degrees, range and bearing with noise, and one misread barcode; rows by time."""
    t_ms, x, y, th = robots[k][2]
    rows = []
    for i in range(0, len(t_ms), 200):
        for code, (tx, ty) in [
            *((ROBOT_BARCODES[j], (robots[j][2][1][i], robots[j][2][2][i])) for j in range(5) if j != k),
            *zip(LANDMARK_BARCODES, landmarks.tolist()),
        ]:
            dx, dy = tx - x[i], ty - y[i]
            r = float(np.hypot(dx, dy))
            b = float((np.arctan2(dy, dx) - th[i] + np.pi) % (2 * np.pi) - np.pi)
            if r < 5.0 and abs(b) < np.radians(30):
                rows.append(
                    [
                        _MRCLAM_T0_S + t_ms[i],
                        code,
                        abs(r + rng.normal(0, RANGE_SIGMA_M)),
                        b + rng.normal(0, BEARING_SIGMA_RAD),
                    ]
                )
    rows.append([_MRCLAM_T0_S + 1.0, 99, 1.0, 0.0])  # a barcode nobody carries (misread)
    rows.sort(key=lambda r: r[0])
    return np.array(rows)


def write_mrclam_dataset(
    root: Path, *, seconds: float = 60.0, seed: int = 0, lag_s: float = 0.0, padded: bool = False
) -> Path:
    """An ``MRCLAM_DatasetN``-layout folder at ``root`` (``RobotK_Groundtruth.dat``,
    ``RobotK_Odometry.dat``, ``RobotK_Measurement.dat``, ``Barcodes.dat``, ``Landmark_Groundtruth.dat``:
    four ``#`` lines then tab-separated columns, Unix seconds with three decimals; MR.CLAM's barcodes,
    robots 1-5 carry 5, 14, 41, 32, 23); returns it. ``lag_s``: see :func:`simulate_mrclam`;
    ``padded``: the real files' column layout (see :func:`_write_dat`)."""
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed + 100)
    robots = simulate_mrclam(seconds, seed, lag_s)
    landmarks = np.column_stack([rng.uniform(-5, 5, 15), rng.uniform(-4, 4, 15)])
    codes = np.array([[k + 1, b] for k, b in enumerate(ROBOT_BARCODES + LANDMARK_BARCODES)])
    _write_dat(root / "Barcodes.dat", "Subject #\tBarcode #", codes, ["%d", "%d"], padded)
    _write_dat(
        root / "Landmark_Groundtruth.dat",
        "Subject #\tx [m]\ty [m]\tx std-dev [m]\ty std-dev [m]",
        np.column_stack([np.arange(6, 21), landmarks, np.full(15, 0.001), np.full(15, 0.001)]),
        ["%d", "%.4f", "%.4f", "%.6f", "%.6f"],
        padded,
    )
    for k, (truth, cmd, _dense) in enumerate(robots):
        gt_t, gx, gy, gth = truth
        th_wrapped = (gth + np.pi) % (2 * np.pi) - np.pi
        _write_dat(
            root / f"Robot{k + 1}_Groundtruth.dat",
            "Time [s]\tx [m]\ty [m]\torientation [rad]",
            np.column_stack([_MRCLAM_T0_S + gt_t, gx, gy, th_wrapped]),
            ["%.3f", "%.4f", "%.4f", "%.4f"],
            padded,
        )
        _write_dat(
            root / f"Robot{k + 1}_Odometry.dat",
            "Time [s]\tforward velocity [m/s]\tangular velocity [rad/s]",
            np.column_stack([_MRCLAM_T0_S + cmd[0], cmd[1], cmd[2]]),
            ["%.3f", "%.3f", "%.3f"],
            padded,
        )
        _write_dat(
            root / f"Robot{k + 1}_Measurement.dat",
            "Time [s]\tSubject #\trange [m]\tbearing [rad]",
            _sightings(robots, k, landmarks, rng),
            ["%.3f", "%d", "%.4f", "%.4f"],
            padded,
        )
    return root


# ---------------------------------------------------------------------------------- the layouts


def s3e_folder(root: Path, names: Sequence[str] = ("Alpha_gt.txt", "BOB_GT.TXT", "carol_gt.txt")) -> Path:
    """An S3E sequence: ``<agent>_gt.txt`` in UTM coordinates (any case), each with a 3 s gap where
    RTK lost its fix."""
    root.mkdir(parents=True)
    for k, fname in enumerate(names):
        s, p, q = loop_trajectory(
            500, centre=(UTM_EAST + 3 * k, UTM_NORTH + 1, 30.0), phase=0.7 * k, t0_s=1_681_000_000.0 + 0.5 * k
        )
        keep = np.ones(500, bool)
        keep[100 + 50 * k : 130 + 50 * k] = False  # RTK lost its fix: 3 s without ground truth
        write_tum_file(root / fname, s[keep], p[keep], q[keep], header=None)
    return root


def airmuseum_folder(root: Path) -> Path:
    """An AirMuseum scenario: three ground robots' folders and a drone's file, and a note."""
    root.mkdir()
    for k, robot in enumerate(["robot_1", "robot_2", "robot_3"]):
        (root / robot).mkdir()
        s, p, q = loop_trajectory(400, centre=(2.0 * k, 0.0, 0.0), phase=k, t0_s=1_560_000_000.0)
        write_tum_file(root / robot / "groundtruth.txt", s, p, q)
    s, p, q = loop_trajectory(400, centre=(1.0, 1.0, 0.0), climb=4.0, t0_s=1_560_000_000.0)
    write_tum_file(root / "drone_gt.txt", s, p, q)
    (root / "notes.txt").write_text("not a trajectory\n")
    return root


def euroc_sequence(root: Path, name: str, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``root/name/mav0/state_groundtruth_estimate0/data.csv`` at 200 Hz (quaternions w first, 17
    columns); returns the trajectory written."""
    from scipy.spatial.transform import Rotation

    folder = root / name / "mav0" / "state_groundtruth_estimate0"
    folder.mkdir(parents=True)
    s, p, q = loop_trajectory(400, rate_hz=200.0, radius=3.0, phase=k, climb=1.0)
    q = (Rotation.from_quat(q) * Rotation.from_euler("x", 0.3)).as_quat()  # roll: w x y z order matters
    rows = [
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
        "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], "
        "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]"
    ]
    for t, pp, qq in zip(s.tolist(), p.tolist(), q.tolist()):
        rows.append(
            ",".join([str(t), *map(repr, pp), repr(qq[3]), repr(qq[0]), repr(qq[1]), repr(qq[2])] + ["0.1"] * 9)
        )
    (folder / "data.csv").write_text("\n".join(rows) + "\n")
    return s, p, q


def _tum(work: Path) -> None:
    centres = ((0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (0.0, 4.0, 0.5))
    for k, (name, centre) in enumerate(zip(("alpha", "bob", "carol"), centres)):
        s, p, q = loop_trajectory(300, rate_hz=5.0, radius=8.0 + k, centre=centre, phase=k)
        write_tum_file(work / f"{name}.txt", s, p, q)


def _vio(work: Path) -> None:
    """``bob_vio.txt``: a drifting estimate of bob's trajectory (5 % scale, 0.002 rad/s of yaw)."""
    s, p, q = loop_trajectory(300, rate_hz=5.0, radius=9.0, centre=(3.0, 0.0, 0.0), phase=1)
    p2, q2 = drifting_estimate(s, p, q, scale=1.05, yaw_rate=0.002, seed=1)
    write_tum_file(work / "bob_vio.txt", s, p2, q2)


def _bags(work: Path) -> None:
    m = Msgs(typestore("ros1"))
    s, p, q = loop_trajectory(400)
    s2, p2, q2 = loop_trajectory(400, centre=(3.0, 0.0, 0.0), phase=1.0)
    odom = [(int(t), m.Odometry(int(t), pp, qq)) for t, pp, qq in zip(s, p, q)]
    tf = [(int(t), m.TFMessage(int(t), pp, qq, parent="odom", child="bob/base_link")) for t, pp, qq in zip(s2, p2, q2)]
    write_bag(work / "run", "ros1", {"/alpha/odom": odom, "/tf": tf})
    m2 = Msgs(typestore("sqlite3"))
    s, p, q = loop_trajectory(400, centre=(UTM_EAST, UTM_NORTH, 80.0), t0_s=1_700_000_000.0)
    lat, lon = utm31_to_latlon(p[:, 0], p[:, 1])
    fixes = [(int(t), m2.NavSatFix(int(t), la, lo, pp[2])) for t, la, lo, pp in zip(s, lat, lon, p)]
    headings = [(int(t), m2.QuaternionStamped(int(t), qq)) for t, qq in zip(s, q)]
    write_bag(work / "s3e_bag", "sqlite3", {"/alpha/fix": fixes, "/alpha/heading": headings})


def _kitti(work: Path) -> None:
    (work / "poses").mkdir()
    n = 600
    yaw = np.linspace(0, 2.0, n)
    rows = []
    for i in range(n):
        c, s = np.cos(yaw[i]), np.sin(yaw[i])
        pose = (c, 0, s, 5 * np.sin(yaw[i]), 0, 1, 0, 0, -s, 0, c, 5 * (1 - np.cos(yaw[i])) + 0.5 * i)
        rows.append(" ".join(f"{v:.9e}" for v in pose))
    (work / "poses" / "00.txt").write_text("\n".join(rows) + "\n")


def _kimera(work: Path) -> None:
    folder = work / "ground_truth" / "1014"
    folder.mkdir(parents=True)
    for k, robot in enumerate(("acl_jackal", "acl_jackal2")):
        s, p, q = loop_trajectory(400, radius=5.0, phase=k)
        lines = ["#timestamp_kf,x,y,z,qw,qx,qy,qz"] + [
            ",".join([str(t), *map(repr, pp), repr(qq[3]), repr(qq[0]), repr(qq[1]), repr(qq[2])])
            for t, pp, qq in zip(s.tolist(), p.tolist(), q.tolist())
        ]
        (folder / f"{robot}_gt_odom.csv").write_text("\n".join(lines) + "\n")


def _euroc(work: Path) -> None:
    for k, name in enumerate(("MH_01_easy", "MH_02_easy", "MH_03_medium")):
        euroc_sequence(work, name, k)


def _s3e(work: Path) -> None:
    s3e_folder(work / "S3E_Square_1")


def _mrclam(work: Path) -> None:
    write_mrclam_dataset(work / "MRCLAM_Dataset1", padded=True, lag_s=0.17)  # the real files' layout and lag


def _airmuseum(work: Path) -> None:
    for name in ("AirMuseum_seq", "AirMuseum_seq_1"):
        airmuseum_folder(work / name)


#: kollagen's config format, three agents of 100 steps: ``studio synth sample_config.json``.
SAMPLE_CONFIG: dict[str, Any] = {
    "number_of_steps": 100,
    "align": True,
    "number_of_agents": 3,
    "exact_information_matrix": False,
    "agent_parameters": {
        "stepsize": 1.0,
        "step_fragment": 4,
        "allow_retrocession": True,
        "agent_specific": [
            {
                "std_dev_position": 0.03,
                "std_dev_angle": 0.03,
                "estimated_information_position": 1111.111111111111,
                "estimated_information_angle": 1111.111111111111,
                "random_number_generator_seed": seed,
                "std_dev_intra_loop_closure_position": 0.02,
                "std_dev_intra_loop_closure_angle": 0.02,
                "estimated_information_intra_position": 2500.0,
                "estimated_information_intra_angle": 2500.0,
                "intra_loop_closure_radius": 5.0,
                "same_position_intra_loop_closure_probability": 0.5,
                "intra_loop_closure_probability_scaling": 0.05,
            }
            for seed in (1407, 1303, 3097)
        ],
    },
    "inter_agent_loop_closure_parameters": {
        "std_dev_loop_closure_position": 0.025,
        "std_dev_loop_closure_angle": 0.025,
        "estimated_information_position": 1599.9999999999998,
        "estimated_information_angle": 1599.9999999999998,
        "loop_closure_radius": 5.0,
        "loop_closure_probability_scaling": 0.05,
        "same_position_loop_closure_probability": 0.8,
        "random_number_generator_seed": 2710,
    },
}


def _config(work: Path) -> None:
    import json

    (work / "sample_config.json").write_text(json.dumps(SAMPLE_CONFIG, indent=4) + "\n", encoding="utf-8")


def _single_g2o(work: Path) -> None:
    """``single_robot.g2o`` (and its ``_GT.tum``): the single g2o of the sample config's walk."""
    import json
    import shutil

    from studio.io.synth_config import parse_synth_config
    from studio.synth import synthesize

    cfg = parse_synth_config(json.loads(json.dumps(SAMPLE_CONFIG)), name="single_robot")
    res = synthesize(cfg, work / ".single", rrd=False, jobs=1)
    assert res.single_dir is not None  # a planar walk always has its single-g2o view
    shutil.copyfile(res.single_dir / "single_robot.g2o", work / "single_robot.g2o")
    shutil.copyfile(res.single_dir / "single_robot_GT.tum", work / "single_robot_GT.tum")
    shutil.rmtree(work / ".single")


#: Each sample: what it writes (the names in the folder) and its writer ``(folder) -> None``.
SAMPLES: dict[str, tuple[tuple[str, ...], Callable[[Path], None]]] = {
    "tum": (("alpha.txt", "bob.txt", "carol.txt"), _tum),
    "vio": (("bob_vio.txt",), _vio),
    "s3e": (("S3E_Square_1",), _s3e),
    "airmuseum": (("AirMuseum_seq", "AirMuseum_seq_1"), _airmuseum),
    "bag": (("run.bag", "s3e_bag"), _bags),
    "euroc": (("MH_01_easy", "MH_02_easy", "MH_03_medium"), _euroc),
    "kitti": (("poses",), _kitti),
    "kimera-multi": (("ground_truth",), _kimera),
    "mrclam": (("MRCLAM_Dataset1",), _mrclam),
    "synth": (("sample_config.json",), _config),
    "g2o": (("single_robot.g2o", "single_robot_GT.tum"), _single_g2o),
}


def write_samples(folder: PathLike, *, force: bool = False) -> list[str]:
    """Write every sample into the new folder ``folder`` (replaced only with ``force``), all of it
    or nothing; returns the names it holds."""
    from studio.io.atomic import staged_outputs

    target = Path(folder).absolute()
    with staged_outputs(target.parent, [target.name], force=force) as staging:
        work = staging / target.name
        work.mkdir()
        for _names, write in SAMPLES.values():
            write(work)
        names = sorted(p.name for p in work.iterdir() if not p.name.startswith("."))
    return names
