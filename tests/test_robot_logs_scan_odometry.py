"""Scan-matching odometry on simulated scans from a known moving path, and the static world it
lets a moving robot keep."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_logs.clutter import furnished_room
from robot_logs.detection import DetectorConfig
from robot_logs.frames import Pose2D, wrap_angle
from robot_logs.leg_training import StaticFlags, candidates
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.scan_odometry import ScanOdometry, ScanOdometryConfig

ROOM = furnished_room(2)  # walls, tables, chairs, benches and pillars around x 1-8 m, y -3.5-3.5 m


def test_poses_follow_a_path_through_a_room_with_people_walking() -> None:
    """15 s at 10 Hz along a 6.5 m weaving path, two people walking past: every pose within 5 cm
    and 1 degree of the truth, relative to the first scan (measured: 3.7 cm, 0.63 degrees)."""
    lidar = LidarSimulator(seed=2, walls=ROOM.walls, posts=(ROOM.centres, ROOM.radii))
    odometry = ScanOdometry()
    start = None
    errors = []
    for k in range(150):
        t = 0.1 * k
        truth = Pose2D(0.5 + 0.4 * t, 0.5 * math.sin(0.2 * t), 0.2 * math.sin(0.3 * t))
        walkers = np.array([[2.0 + 0.8 * t, -1.0], [6.0 - 0.6 * t, 1.0]])
        estimate = odometry.update(lidar.scan(t, truth, walkers, np.array([[0.8, 0.0], [-0.6, 0.0]])))
        start = truth if start is None else start
        relative = start.inverse().compose(truth)
        assert estimate is not None
        errors.append((math.hypot(estimate.x - relative.x, estimate.y - relative.y), abs(wrap_angle(estimate.yaw - relative.yaw))))
    position, heading = np.max(errors, axis=0)
    assert position < 0.05 and heading < math.radians(1.0)
    assert odometry.lost == 0


def test_a_scan_with_too_few_points_is_not_placed() -> None:
    """A lone post gives 23 points, 7 after thinning, under the 30 a match needs: no pose, counted lost; the first
    scan with enough points becomes the origin, and the next is placed from it."""
    post = LidarSimulator(seed=1, posts=(np.array([[2.0, 0.0]]), np.array([0.1])))
    room = LidarSimulator(seed=1, walls=ROOM.walls)
    odometry = ScanOdometry()
    assert odometry.update(post.scan(0.0, Pose2D(), np.zeros((0, 2)))) is None
    assert odometry.lost == 1
    assert odometry.update(room.scan(0.1, Pose2D(1.0, 0.0, 0.0), np.zeros((0, 2)))) == Pose2D()
    moved = odometry.update(room.scan(0.2, Pose2D(1.1, 0.0, 0.0), np.zeros((0, 2))))
    assert moved is not None and moved.x == pytest.approx(0.1, abs=0.02) and abs(moved.y) < 0.02
    flags = StaticFlags()
    segments, mask = candidates(post.scan(0.0, Pose2D(), np.zeros((0, 2))), DetectorConfig())
    assert mask.sum() == 1 and not flags(post.scan(0.0, Pose2D(), np.zeros((0, 2))), segments, mask).any()
    assert flags.lost == 1


def test_a_scan_that_matches_nothing_is_not_placed() -> None:
    """After the room, a scan of a 2 m box around the laser (another place): under half of its
    points find a partner, so it is not placed; the room seen again is, from the last pose known."""
    room = LidarSimulator(seed=3, walls=ROOM.walls)
    corners = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    box = LidarSimulator(seed=3, walls=np.stack((corners, np.roll(corners, -1, axis=0)), axis=1))
    odometry = ScanOdometry()
    nobody = np.zeros((0, 2))
    assert odometry.update(room.scan(0.0, Pose2D(1.0, 0.0, 0.0), nobody)) == Pose2D()
    assert odometry.update(box.scan(0.1, Pose2D(), nobody)) is None
    assert odometry.lost == 1
    back = odometry.update(room.scan(0.2, Pose2D(1.05, 0.0, 0.0), nobody))
    assert back is not None and back.x == pytest.approx(0.05, abs=0.02)


def test_another_place_becomes_the_keyframe_after_five_scans_are_lost() -> None:
    """The robot drives 4 cm a scan out of the room into a 3 m box (another place, as a street's walls
    leave a narrow laser's view): the box matches nothing of the room, and after 5 scans lost in a row
    its next scan becomes the keyframe where the last motion leads; every later scan is placed, each
    as far on as the robot drives."""
    room = LidarSimulator(seed=3, walls=ROOM.walls)
    corners = np.array([[-1.5, -1.5], [1.5, -1.5], [1.5, 1.5], [-1.5, 1.5]]) + [1.8, 0.0]
    box = LidarSimulator(seed=3, walls=np.stack((corners, np.roll(corners, -1, axis=0)), axis=1))
    odometry, nobody = ScanOdometry(), np.zeros((0, 2))
    poses = [odometry.update((room if k < 10 else box).scan(0.1 * k, Pose2D(1.0 + 0.04 * k, 0.0, 0.0), nobody))
             for k in range(30)]
    assert all(pose is not None for pose in poses[:10]) and poses[10:15] == [None] * 5 and odometry.lost == 5
    placed = np.array([[pose.x, pose.y] for pose in poses[15:] if pose is not None])
    assert len(placed) == 15
    assert placed[0, 0] == pytest.approx(0.6, abs=0.05)  # dead reckoning carried it across the 5 scans
    assert np.mean(np.diff(placed[:, 0])) == pytest.approx(0.04, abs=0.005) and np.abs(placed[:, 1]).max() < 0.05


@pytest.mark.parametrize(("odometry", "static_from"), [(ScanOdometryConfig(), 16), (None, None)])
def test_a_post_beside_a_walker_turns_static_while_the_robot_drives(odometry: ScanOdometryConfig | None, static_from: int | None) -> None:
    """The robot drives at 0.5 m/s turning 0.1 rad/s past a post 4 m ahead while a person walks
    beside it: placed by scan matching the post is static once the earlier scans 0-15 saw it
    for 1.5 s, as for a standing robot; in the laser's own frame it never is. The walker never is."""
    post = np.array([4.0, -0.4])
    lidar = LidarSimulator(seed=4, walls=ROOM.walls, posts=(np.vstack((ROOM.centres, post)), np.append(ROOM.radii, 0.06)))
    flags = StaticFlags(odometry)
    post_static, walker_static = [], []
    for k in range(50):
        t = 0.1 * k
        truth = Pose2D(0.5 + 0.5 * t, 0.0, 0.1 * t)
        walker = np.array([2.0 + t, -1.0])
        scan = lidar.scan(t, truth, walker[None, :], np.array([[1.0, 0.0]]))
        segments, mask = candidates(scan, DetectorConfig())
        static = flags(scan, segments, mask)
        seen = truth.apply(segments.centroids[mask])
        at_post = np.hypot(*(seen - post).T) < 0.15
        assert at_post.sum() == 1
        post_static.append(bool(static[at_post][0]))
        walker_static.extend(static[np.hypot(*(seen - walker).T) < 0.5].tolist())
    expected = [False] * 50 if static_from is None else [False] * static_from + [True] * (50 - static_from)
    assert post_static == expected
    assert len(walker_static) >= 50 and not any(walker_static)
