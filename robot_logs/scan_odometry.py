"""Scan-matching odometry: a laser's planar pose scan by scan, for logs recorded without odometry.

Each scan is aligned to a keyframe, an earlier scan of the same laser, by small_gicp's
point-to-point ICP on the scan's points (z = 0), seeded with the motion of the scan before.
Two passes: a coarse one whose wide correspondence distance takes up what the seed missed, then a
fine one that leaves out every point with no partner close by, so people who walked since the
keyframe pull little on the pose. A scan that moved far enough from its keyframe becomes the
next one; matching against a keyframe rather than the scan before keeps the drift of a robot
standing still at zero. A scan that cannot be placed moves the expected pose on by the last
motion (dead reckoning), and after a few such scans in a row the next one with enough points
becomes the keyframe where the robot is expected to be: the keyframe may have left the view (a
robot driving along a street), and nothing could be placed again. Poses are of the scan's frame
in the frame of the first scan matched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import small_gicp

from robot_logs.detection import scan_points
from robot_logs.frames import Pose2D
from robot_logs.records import Scan


@dataclass(frozen=True)
class ScanOdometryConfig:
    """How scans are matched.

    Attributes:
        voxel: scans are thinned to one point per square of this side before matching (m).
        coarse_distance, fine_distance: the largest distance between matched points in the first
            and the second pass (m).
        max_iterations: ICP iterations of each pass.
        min_points: a scan with fewer points than this after thinning is not matched.
        min_inliers: share of a scan's thinned points that must find a partner within
            `fine_distance` for its match to count.
        keyframe_distance, keyframe_angle: a scan this far (m) or turned this much (rad) from
            its keyframe becomes the next keyframe.
        reanchor_after: after this many scans in a row not placed, a scan with enough points that
            does not match becomes the keyframe at the pose dead reckoning expects (still not placed).
    """

    voxel: float = 0.05
    coarse_distance: float = 0.5
    fine_distance: float = 0.15
    max_iterations: int = 30
    min_points: int = 30
    min_inliers: float = 0.5
    keyframe_distance: float = 0.3
    keyframe_angle: float = math.radians(10.0)
    reanchor_after: int = 5


def _matrix(pose: Pose2D) -> np.ndarray:
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    matrix = np.eye(4)
    matrix[:2, :2] = [[c, -s], [s, c]]
    matrix[:2, 3] = pose.x, pose.y
    return matrix


def _pose(matrix: np.ndarray) -> Pose2D:
    return Pose2D(float(matrix[0, 3]), float(matrix[1, 3]), math.atan2(matrix[1, 0], matrix[0, 0]))


class ScanOdometry:
    """The pose of one laser's scans, each matched to a keyframe; `update` once per scan, in order.

    `update` returns None for a scan it cannot place (too few points, or too few of them matched),
    counted in `lost`; the next scan is matched to the same keyframe from the pose the last motion
    leads to, until `reanchor_after` scans in a row were lost.
    """

    def __init__(self, config: ScanOdometryConfig = ScanOdometryConfig()) -> None:
        self.config = config
        self.lost = 0
        self._keyframe: small_gicp.PointCloud | None = None
        self._keyframe_tree: small_gicp.KdTree | None = None
        self._keyframe_pose = Pose2D()
        self._pose = Pose2D()
        self._motion = Pose2D()
        self._missed = 0

    def _cloud(self, scan: Scan) -> small_gicp.PointCloud:
        """The scan's valid points at z = 0, thinned to one per `voxel` square."""
        points = scan_points(scan)
        return small_gicp.voxelgrid_sampling(np.column_stack((points, np.zeros(len(points)))), self.config.voxel)

    def _align(self, cloud: small_gicp.PointCloud, seed: Pose2D) -> tuple[Pose2D, float]:
        """(pose in the keyframe's frame, matched share) of a thinned scan."""
        config = self.config
        seed_matrix = _matrix(seed)
        for distance in (config.coarse_distance, config.fine_distance):
            result = small_gicp.align(self._keyframe, cloud, self._keyframe_tree, seed_matrix, registration_type="ICP",
                                      max_correspondence_distance=distance, max_iterations=config.max_iterations)
            seed_matrix = result.T_target_source
        return _pose(result.T_target_source), result.num_inliers / cloud.size()

    @property
    def pose(self) -> Pose2D:
        """The latest scan's pose: placed, or where the last motion led when it could not be
        placed (the origin before any scan was placed)."""
        return self._pose

    def update(self, scan: Scan) -> Pose2D | None:
        """The pose of `scan`'s frame in the frame of the first scan placed; None if it cannot be placed."""
        config = self.config
        cloud = self._cloud(scan)
        if self._keyframe is None:
            if cloud.size() < config.min_points:
                self.lost += 1
                return None
            self._set_keyframe(cloud, Pose2D())
            return self._pose
        expected = self._pose.compose(self._motion)
        if cloud.size() < config.min_points:
            self._lose(expected)
            return None
        relative, inliers = self._align(cloud, self._keyframe_pose.inverse().compose(expected))
        if inliers < config.min_inliers:
            if self._missed + 1 >= config.reanchor_after:
                self._set_keyframe(cloud, expected)
            self._lose(expected)
            return None
        pose = self._keyframe_pose.compose(relative)
        self._motion, self._pose, self._missed = self._pose.inverse().compose(pose), pose, 0
        if math.hypot(relative.x, relative.y) >= config.keyframe_distance or abs(relative.yaw) >= config.keyframe_angle:
            self._set_keyframe(cloud, pose)
        return pose

    def _lose(self, expected: Pose2D) -> None:
        """Count a scan not placed; the robot is taken to have moved on as it did."""
        self.lost += 1
        self._missed += 1
        self._pose = expected

    def _set_keyframe(self, cloud: small_gicp.PointCloud, pose: Pose2D) -> None:
        self._keyframe, self._keyframe_pose = cloud, pose
        self._keyframe_tree = small_gicp.KdTree(cloud)
