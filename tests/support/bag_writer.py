"""Writing scans, odometry, tf and labelled points as ROS1 or ROS2 bags (via rosbags).

The tests build logs with known content (moving robots, bad scans) with it, in every format
robot_logs reads.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import TracebackType
from typing import Any, Literal

import numpy as np
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from robot_logs.frames import Pose2D
from robot_logs.records import Odometry, PointSet, Scan, Transform

BagFormat = Literal["ros1", "ros2-sqlite3", "ros2-mcap"]

SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POSE_ARRAY = "geometry_msgs/msg/PoseArray"


class BagWriter:
    """Writes robot_logs records into a new bag; the record time of each message is its stamp
    unless given.

    Args:
        path: a `.bag` file (ros1) or a folder to create (ros2-*).
        bag_format: "ros1", "ros2-sqlite3" or "ros2-mcap".
        store: the ROS 2 type store whose definitions the messages follow (ros2-* only).
        version: the rosbag2 metadata version (8 or 9, what rosbags writes).
        compression: zstd compression of whole storage files or of each message (ros2-* only).
    """

    def __init__(
        self,
        path: str | Path,
        bag_format: BagFormat = "ros1",
        store: Stores = Stores.ROS2_HUMBLE,
        version: int = 9,
        compression: CompressionMode = CompressionMode.NONE,
    ) -> None:
        self.ros1 = bag_format == "ros1"
        if self.ros1:
            self.store = get_typestore(Stores.ROS1_NOETIC)
            self.store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))
            self._writer: Any = Ros1Writer(Path(path))
        else:
            self.store = get_typestore(store)
            plugin = StoragePlugin.MCAP if bag_format == "ros2-mcap" else StoragePlugin.SQLITE3
            self._writer = Ros2Writer(Path(path), version=version, storage_plugin=plugin)
            if compression != CompressionMode.NONE:
                self._writer.set_compression(compression, CompressionFormat.ZSTD)
        self._connections: dict[str, Any] = {}

    def __enter__(self) -> BagWriter:
        self._writer.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self._writer.close()

    def _type(self, name: str) -> Any:
        return self.store.types[name]

    def _header(self, stamp_ns: int, frame: str) -> Any:
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        stamp = self._type("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)
        if self.ros1:
            return self._type("std_msgs/msg/Header")(seq=0, stamp=stamp, frame_id=frame)
        return self._type("std_msgs/msg/Header")(stamp=stamp, frame_id=frame)

    def _pose(self, pose: Pose2D) -> Any:
        point = self._type("geometry_msgs/msg/Point")(x=pose.x, y=pose.y, z=0.0)
        return self._type("geometry_msgs/msg/Pose")(position=point, orientation=self._quaternion(pose.yaw))

    def _quaternion(self, yaw: float) -> Any:
        return self._type("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def _vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        return self._type("geometry_msgs/msg/Vector3")(x=x, y=y, z=z)

    def write(self, topic: str, msgtype: str, message: Any, record_ns: int) -> None:
        """Serialise and write any message of a registered type."""
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(topic, msgtype, typestore=self.store)
        serialize = self.store.serialize_ros1 if self.ros1 else self.store.serialize_cdr
        self._writer.write(self._connections[topic], record_ns, serialize(message, msgtype))

    def raw(self, topic: str, msgtype: str, data: bytes, record_ns: int, definition: str = "") -> None:
        """Already serialised bytes of a type the store lacks, with the definition text the bag
        stores for it ('' for none, as recorders write for types they cannot describe)."""
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(topic, msgtype, msgdef=definition, rihs01="RIHS01_" + "0" * 64)
        self._writer.write(self._connections[topic], record_ns, data)

    def scan(self, scan: Scan, topic: str = "/scan", record_ns: int | None = None, angle_max: float | None = None) -> None:
        """A sensor_msgs/LaserScan (angle_max defaults to the one the beams imply)."""
        count = len(scan.ranges)
        message = self._type(SCAN)(
            header=self._header(scan.stamp_ns, scan.frame_id),
            angle_min=scan.angle_min,
            angle_max=scan.angle_min + scan.angle_increment * (count - 1) if angle_max is None else angle_max,
            angle_increment=scan.angle_increment,
            time_increment=0.0,
            scan_time=0.0,
            range_min=scan.range_min,
            range_max=scan.range_max,
            ranges=np.asarray(scan.ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32),
        )
        self.write(topic, SCAN, message, scan.stamp_ns if record_ns is None else record_ns)

    def odometry(self, odometry: Odometry, topic: str = "/odom", record_ns: int | None = None) -> None:
        """A nav_msgs/Odometry with zero covariances."""
        pose = self._type("geometry_msgs/msg/PoseWithCovariance")(pose=self._pose(odometry.pose), covariance=np.zeros(36))
        twist = self._type("geometry_msgs/msg/Twist")(linear=self._vector(odometry.linear), angular=self._vector(z=odometry.angular))
        message = self._type(ODOMETRY)(
            header=self._header(odometry.stamp_ns, odometry.frame_id),
            child_frame_id=odometry.child_frame_id,
            pose=pose,
            twist=self._type("geometry_msgs/msg/TwistWithCovariance")(twist=twist, covariance=np.zeros(36)),
        )
        self.write(topic, ODOMETRY, message, odometry.stamp_ns if record_ns is None else record_ns)

    def transforms(self, edges: list[Transform], topic: str = "/tf", record_ns: int | None = None) -> None:
        """A tf2_msgs/TFMessage (use topic "/tf_static" for static edges)."""
        stamped = [
            self._type("geometry_msgs/msg/TransformStamped")(
                header=self._header(edge.stamp_ns, edge.parent),
                child_frame_id=edge.child,
                transform=self._type("geometry_msgs/msg/Transform")(
                    translation=self._vector(edge.pose.x, edge.pose.y), rotation=self._quaternion(edge.pose.yaw)
                ),
            )
            for edge in edges
        ]
        self.write(topic, TF, self._type(TF)(transforms=stamped), edges[0].stamp_ns if record_ns is None else record_ns)

    def points(self, points: PointSet, topic: str) -> None:
        """A geometry_msgs/PoseArray of positions (stamp 0 in PointSet leaves it unstamped)."""
        poses = [self._pose(Pose2D(float(x), float(y))) for x, y in points.points]
        message = self._type(POSE_ARRAY)(header=self._header(points.stamp_ns, points.frame_id), poses=poses)
        self.write(topic, POSE_ARRAY, message, points.record_ns)
