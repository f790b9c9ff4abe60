"""ROS messages (rosbags objects of any ROS version, or rospy's live ones) turned into robot_logs records.

Time rule: a message is timed by its header stamp; one whose stamp is zero (never set by its
publisher) takes its record time instead, the only place record time stands in for a stamp.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from robot_logs.errors import LogError
from robot_logs.frames import Pose2D, frame_name, yaw_from_quaternion
from robot_logs.records import Odometry, PointSet, Scan, Transform, beam_count


def stamp_ns(header: Any, record_ns: int) -> int:
    """Header stamp in ns, or the record time when the stamp was left at zero.

    rosbags names a stamp's fields sec/nanosec, rospy (genpy's Time) secs/nsecs."""
    stamp = header.stamp
    sec, nanosec = (stamp.sec, stamp.nanosec) if hasattr(stamp, "nanosec") else (stamp.secs, stamp.nsecs)
    value = int(sec) * 1_000_000_000 + int(nanosec)
    return value if value else record_ns


def _pose(position: Any, orientation: Any) -> Pose2D:
    return Pose2D(
        float(position.x),
        float(position.y),
        yaw_from_quaternion(orientation.x, orientation.y, orientation.z, orientation.w),
    )


def to_scan(msg: Any, record_ns: int, where: str) -> Scan:
    """A `Scan` from a sensor_msgs/LaserScan, after checking its sizes agree.

    Raises:
        LogError: angles and beam count disagree, intensities have another length, or the
            angular step is not a positive number (`where` names the scan in the message).
    """
    increment = float(msg.angle_increment)
    if not math.isfinite(increment) or increment <= 0.0:
        raise LogError(f"{where}: angle_increment is {increment}, expected a positive number of radians")
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    expected = beam_count(float(msg.angle_min), float(msg.angle_max), increment)
    if abs(len(ranges) - expected) > 1:
        raise LogError(
            f"{where}: {len(ranges)} ranges, but angle_min..angle_max at angle_increment "
            f"gives {expected} beams (inconsistent LaserScan sizes)"
        )
    intensities = len(msg.intensities)
    if intensities not in (0, len(ranges)):
        raise LogError(f"{where}: {intensities} intensities for {len(ranges)} ranges (inconsistent LaserScan sizes)")
    return Scan(
        stamp_ns=stamp_ns(msg.header, record_ns),
        frame_id=frame_name(msg.header.frame_id),
        angle_min=float(msg.angle_min),
        angle_increment=increment,
        range_min=float(msg.range_min),
        range_max=float(msg.range_max),
        ranges=ranges,
    )


def to_odometry(msg: Any, record_ns: int) -> Odometry:
    """An `Odometry` (planar pose and forward/turn rates) from a nav_msgs/Odometry."""
    twist = msg.twist.twist
    return Odometry(
        stamp_ns=stamp_ns(msg.header, record_ns),
        frame_id=frame_name(msg.header.frame_id),
        child_frame_id=frame_name(msg.child_frame_id),
        pose=_pose(msg.pose.pose.position, msg.pose.pose.orientation),
        linear=float(twist.linear.x),
        angular=float(twist.angular.z),
    )


def to_transforms(msg: Any, record_ns: int, static: bool) -> list[Transform]:
    """The edges of a tf2_msgs/TFMessage (or ROS1 tf/tfMessage)."""
    return [
        Transform(
            stamp_ns=stamp_ns(t.header, record_ns),
            parent=frame_name(t.header.frame_id),
            child=frame_name(t.child_frame_id),
            pose=_pose(t.transform.translation, t.transform.rotation),
            static=static,
        )
        for t in msg.transforms
    ]


def to_points(msg: Any, record_ns: int) -> PointSet:
    """Positions of a geometry_msgs/PoseArray (labelled legs or ground-truth people)."""
    points = np.array([[p.position.x, p.position.y] for p in msg.poses], dtype=float).reshape(-1, 2)
    return PointSet(stamp_ns(msg.header, record_ns), record_ns, frame_name(msg.header.frame_id), points)
