"""Planar rigid transforms and a small time-indexed frame tree (2-D view of ROS tf).

A `Pose2D` maps points of a child frame into its parent frame: p_parent = R(yaw) p_child + t.
Frame names are compared without leading slashes, since ROS1 logs often write "/odom".
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from robot_logs.errors import LogError


def frame_name(frame_id: str) -> str:
    """A frame id without leading slashes ("/base_link" and "base_link" are one frame)."""
    return frame_id.lstrip("/")


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Heading about z of a 3-D rotation, the only angle a planar robot needs."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def wrap_angle(angle: float) -> float:
    """An angle folded into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Pose2D:
    """Position (m) and heading (rad) of a child frame in its parent frame."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def compose(self, other: Pose2D) -> Pose2D:
        """self * other: `other` expressed in self's child frame, brought into self's parent."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2D(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.yaw + other.yaw),
        )

    def inverse(self) -> Pose2D:
        """The transform from parent back to child."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2D(-c * self.x - s * self.y, s * self.x - c * self.y, wrap_angle(-self.yaw))

    def apply(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) child-frame points mapped into the parent frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rotation = np.array([[c, -s], [s, c]])
        return np.asarray(points, dtype=float).reshape(-1, 2) @ rotation.T + (self.x, self.y)


def interpolate(a: Pose2D, b: Pose2D, fraction: float) -> Pose2D:
    """The pose a fraction of the way from a to b (heading along the shorter arc)."""
    return Pose2D(
        a.x + fraction * (b.x - a.x),
        a.y + fraction * (b.y - a.y),
        wrap_angle(a.yaw + fraction * wrap_angle(b.yaw - a.yaw)),
    )


@dataclass
class PoseTrack:
    """Time-stamped poses of one child frame in one parent frame, interpolated on lookup."""

    parent: str
    child: str
    stamps_ns: list[int] = field(default_factory=list)
    poses: list[Pose2D] = field(default_factory=list)
    static: bool = False

    def add(self, stamp_ns: int, pose: Pose2D) -> None:
        """Insert a sample, keeping stamps sorted (logs are nearly sorted, so this is cheap)."""
        index = bisect.bisect_right(self.stamps_ns, stamp_ns)
        self.stamps_ns.insert(index, stamp_ns)
        self.poses.insert(index, pose)

    def at(self, stamp_ns: int, max_gap_ns: int) -> Pose2D | None:
        """The pose at a time, or None when no sample lies within max_gap_ns of it."""
        if not self.poses:
            return None
        if self.static:
            return self.poses[-1]
        index = bisect.bisect_left(self.stamps_ns, stamp_ns)
        if index < len(self.stamps_ns) and self.stamps_ns[index] == stamp_ns:
            return self.poses[index]
        if index == 0:
            near = self.stamps_ns[0]
            return self.poses[0] if near - stamp_ns <= max_gap_ns else None
        if index == len(self.stamps_ns):
            near = self.stamps_ns[-1]
            return self.poses[-1] if stamp_ns - near <= max_gap_ns else None
        t0, t1 = self.stamps_ns[index - 1], self.stamps_ns[index]
        if t1 - t0 > 2 * max_gap_ns:
            return None
        return interpolate(self.poses[index - 1], self.poses[index], (stamp_ns - t0) / (t1 - t0))


class FrameTree:
    """Transforms between named frames over time, looked up along the tree like tf does.

    Each child frame has one parent; `lookup(target, source, t)` returns the pose of `source`
    in `target` at time t, walking both frames up to their common ancestor.
    """

    def __init__(self, max_gap_s: float = 0.5) -> None:
        self._edges: dict[str, PoseTrack] = {}
        self.max_gap_ns = int(max_gap_s * 1e9)

    @property
    def frames(self) -> list[str]:
        """Every frame named by a transform, sorted."""
        names = set(self._edges) | {edge.parent for edge in self._edges.values()}
        return sorted(names)

    def add(self, parent: str, child: str, stamp_ns: int, pose: Pose2D, static: bool = False) -> None:
        """Record the pose of `child` in `parent` at a time (static: valid at every time)."""
        parent, child = frame_name(parent), frame_name(child)
        edge = self._edges.get(child)
        if edge is None or edge.parent != parent:
            edge = self._edges[child] = PoseTrack(parent, child, static=static)
        edge.add(stamp_ns, pose)

    def moving_root(self, frame: str, prefer: str | None = None) -> str | None:
        """The topmost frame above `frame`, or `prefer` where that lies above it, when some
        transform between the two changes over time (a frame the robot moves in, as odom is for its
        laser); None where none does."""
        chain = self.chain(frame_name(frame))
        if prefer is not None and prefer in chain[1:]:
            chain = chain[: chain.index(prefer) + 1]
        moves = any(len(set(self._edges[child].poses)) > 1 for child in chain[:-1])
        return chain[-1] if moves else None

    def parent(self, child: str) -> str | None:
        """The frame `child` hangs from, None for a root or an unknown frame."""
        edge = self._edges.get(frame_name(child))
        return edge.parent if edge is not None else None

    def chain(self, frame: str) -> list[str]:
        """`frame` and the frames above it, up to its root."""
        chain = [frame_name(frame)]
        while chain[-1] in self._edges and len(chain) <= len(self._edges):
            chain.append(self._edges[chain[-1]].parent)
        return chain

    def _to_ancestor(self, chain: list[str], ancestor: str, stamp_ns: int) -> Pose2D | None:
        pose = Pose2D()
        for child in chain[: chain.index(ancestor)]:
            step = self._edges[child].at(stamp_ns, self.max_gap_ns)
            if step is None:
                return None
            pose = step.compose(pose)
        return pose

    def lookup(self, target: str, source: str, stamp_ns: int) -> Pose2D | None:
        """Pose of frame `source` in frame `target` at a time; None if not known then.

        Raises:
            LogError: the two frames are not connected by any transform.
        """
        target, source = frame_name(target), frame_name(source)
        up_source, up_target = self.chain(source), self.chain(target)
        common = next((frame for frame in up_source if frame in up_target), None)
        if common is None:
            known = ", ".join(self.frames) or "none"
            raise LogError(f"no transform connects frame {source!r} to {target!r} (frames in the log: {known})")
        source_pose = self._to_ancestor(up_source, common, stamp_ns)
        target_pose = self._to_ancestor(up_target, common, stamp_ns)
        if source_pose is None or target_pose is None:
            return None
        return target_pose.inverse().compose(source_pose)
