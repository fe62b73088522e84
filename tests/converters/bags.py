"""Small ROS 1 and ROS 2 bags written with rosbags' own writers, for the converter tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

STORAGES = ("ros1", "sqlite3", "mcap")


def typestore(storage: str):
    from studio.converters.rosbag import typestore_for

    return typestore_for(ros1=storage == "ros1")


class Msgs:
    """Message builders for one typestore (ROS 1 headers carry a ``seq``)."""

    def __init__(self, ts):
        self.ts = ts
        self.T = ts.types
        self.ros1 = "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, ns: int, frame: str = "map"):
        stamp = self.T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        kw = {"seq": 0} if self.ros1 else {}
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame, **kw)

    def pose(self, p, q):
        T = self.T
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]), orientation=self.quat(q)
        )

    def quat(self, q):
        return self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])

    def pose_cov(self, p, q):
        return self.T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(p, q), covariance=np.zeros(36))

    def PoseStamped(self, ns, p, q):
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(ns), pose=self.pose(p, q))

    def PoseWithCovarianceStamped(self, ns, p, q):
        return self.T["geometry_msgs/msg/PoseWithCovarianceStamped"](header=self.header(ns), pose=self.pose_cov(p, q))

    def Odometry(self, ns, p, q):
        T = self.T
        v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=v, angular=v), covariance=np.zeros(36)
        )
        return T["nav_msgs/msg/Odometry"](
            header=self.header(ns, "odom"), child_frame_id="base_link", pose=self.pose_cov(p, q), twist=twist
        )

    def TFMessage(self, ns, p, q, parent="odom", child="base_link"):
        T = self.T

        def tr(par, ch, pp, qq):
            return T["geometry_msgs/msg/TransformStamped"](
                header=self.header(ns, par),
                child_frame_id=ch,
                transform=T["geometry_msgs/msg/Transform"](
                    translation=T["geometry_msgs/msg/Vector3"](x=pp[0], y=pp[1], z=pp[2]), rotation=self.quat(qq)
                ),
            )

        other = tr("base_link", "camera", (0.1, 0.0, 0.3), (0.0, 0.0, 0.0, 1.0))
        return T["tf2_msgs/msg/TFMessage"](transforms=[other, tr(parent, child, p, q)])

    def NavSatFix(self, ns, lat, lon, alt, status=0):
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

    def QuaternionStamped(self, ns, q):
        return self.T["geometry_msgs/msg/QuaternionStamped"](header=self.header(ns), quaternion=self.quat(q))

    def Imu(self, ns, q):
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

    def String(self, ns):
        return self.T["std_msgs/msg/String"](data="hello")


def write_bag(path: Path, storage: str, topics: dict[str, list[tuple[int, object]]]) -> Path:
    """Write ``{topic: [(stamp_ns, message), ...]}`` as a ROS 1 ``.bag`` or a ROS 2 folder."""
    ts = typestore(storage)
    if storage == "ros1":
        from rosbags.rosbag1 import Writer

        path = path.with_suffix(".bag")
        with Writer(path) as w:
            for topic, msgs in topics.items():
                conn = w.add_connection(topic, msgs[0][1].__msgtype__, typestore=ts)
                for t, m in msgs:
                    w.write(conn, t, ts.serialize_ros1(m, m.__msgtype__))
        return path
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        for topic, msgs in topics.items():
            conn = w.add_connection(topic, msgs[0][1].__msgtype__, typestore=ts)
            for t, m in msgs:
                w.write(conn, t, ts.serialize_cdr(m, m.__msgtype__))
    return path


def utm31_to_latlon(east: np.ndarray, north: np.ndarray):
    from pyproj import Transformer

    lon, lat = Transformer.from_crs("EPSG:32631", "EPSG:4326", always_xy=True).transform(east, north)
    return np.asarray(lat), np.asarray(lon)
