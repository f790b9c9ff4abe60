"""Plain records of what robot_logs reads from a log, independent of ROS message classes.

Times: every `stamp_ns` is the message's header stamp (the sensor's acquisition time, the
clock tf uses), in integer nanoseconds; `record_ns` is when the logger wrote the message and
serves only to order messages and to pair unstamped ones (see `robot_logs.reader`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.frames import Pose2D


def seconds(stamp_ns: int) -> float:
    """Nanoseconds as float seconds."""
    return stamp_ns * 1e-9


def stamp_text(stamp_ns: int) -> str:
    """Nanoseconds as exact decimal seconds, e.g. '1403201183.698857000' (no float rounding)."""
    sign = "-" if stamp_ns < 0 else ""
    whole, part = divmod(abs(stamp_ns), 1_000_000_000)
    return f"{sign}{whole}.{part:09d}"


@dataclass(frozen=True)
class Scan:
    """One planar lidar sweep (sensor_msgs/LaserScan), beams at angle_min + i * angle_increment.

    `ranges` follows REP 117: +inf means no return, NaN a failed measurement, and values
    outside [range_min, range_max] are to be ignored.
    """

    stamp_ns: int
    frame_id: str
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray

    @property
    def stamp(self) -> float:
        """Header stamp in seconds."""
        return seconds(self.stamp_ns)

    def angles(self) -> np.ndarray:
        """(n,) bearing of every beam (rad)."""
        return self.angle_min + self.angle_increment * np.arange(len(self.ranges))

    def valid(self) -> np.ndarray:
        """(n,) True for beams with a real return inside the sensor's limits."""
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isfinite(r) & (r >= self.range_min) & (r < self.range_max)


def beam_count(angle_min: float, angle_max: float, angle_increment: float) -> int:
    """Beams a LaserScan header promises: (angle_max - angle_min) / angle_increment + 1."""
    return int(math.floor((angle_max - angle_min) / angle_increment + 0.5)) + 1


@dataclass(frozen=True)
class Odometry:
    """The robot's base pose in the odometry frame (nav_msgs/Odometry), with its velocity."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    pose: Pose2D
    linear: float
    angular: float


@dataclass(frozen=True)
class Transform:
    """One tf edge: the pose of `child` in `parent` at a time; static ones hold at all times."""

    stamp_ns: int
    parent: str
    child: str
    pose: Pose2D
    static: bool


@dataclass(frozen=True)
class PointSet:
    """Labelled or ground-truth positions (e.g. legs or people) in one frame at one time."""

    stamp_ns: int
    record_ns: int
    frame_id: str
    points: np.ndarray
