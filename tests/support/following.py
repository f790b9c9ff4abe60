"""A simulated person-following walk: a robot drives along an outdoor path while one person
walks 1 to 3 m ahead of it, with walls and posts along the way.

The lidar is one like the person-following benchmark log's (245 beams over 86 degrees, 5.6 m),
the legs those fitted to the labelled sample bags. The ground truth is the walker's position in
the world (the odometry frame) and in the laser's frame at each scan; `follow` scores the learned
tracking setup on it (the following test and benchmarks/bench_tracking.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.clear_mot import ClearMot, ScoredScan
from robot_logs.frames import Pose2D
from robot_logs.leg_classifier import LegClassifier
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.pipeline import PersonTracker
from robot_logs.scan_odometry import ScanOdometry

#: A narrow outdoor lidar like the following log's: 245 beams over 86 degrees, 0.05-5.6 m, 1 cm noise.
FOLLOWING_LIDAR = LidarSpec(angle_min=math.radians(-43.0), angle_max=math.radians(43.0),
                            angle_increment=math.radians(86.0 / 244), range_max=5.6, range_noise_std=0.01)

#: The robot's speed along the path (m/s).
ROBOT_SPEED = 0.9


@dataclass(frozen=True)
class FollowingWalk:
    """Scans and truth of one walk: (T,) robot poses (the laser's, in the world), scans, and the
    walker's (T, 2) world positions, (T, 2) positions in the laser frame and (T,) beams on them."""

    poses: list[Pose2D]
    scans: list
    walker: np.ndarray
    walker_in_laser: np.ndarray
    beams: np.ndarray
    seed: int


def _path(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robot's weaving path: x, y and heading at times t."""
    x, y = ROBOT_SPEED * t, 0.6 * np.sin(0.12 * t)
    heading = np.arctan2(0.6 * 0.12 * np.cos(0.12 * t), ROBOT_SPEED)
    return x, y, heading


def _surroundings(seed: int, length: float) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Walls beside the path with gaps (buildings, hedges) and posts (trees, bollards) at random."""
    rng = np.random.default_rng(seed)
    walls = []
    for side in (3.0, -3.5):
        x = -5.0
        while x < length:
            run = rng.uniform(3.0, 8.0)
            offset = side + rng.uniform(-0.5, 0.5)
            walls.append([[x, offset], [x + run, offset]])
            x += run + rng.uniform(0.5, 2.0)
    count = int(length / 2.0)
    centres = np.column_stack((rng.uniform(0.0, length, count), rng.choice([-1.0, 1.0], count) * rng.uniform(1.5, 2.6, count)))
    return np.array(walls), (centres, rng.uniform(0.04, 0.2, count))


def following_walk(duration: float = 60.0, rate_hz: float = 10.0, seed: int = 0, spec: LidarSpec = FOLLOWING_LIDAR) -> FollowingWalk:
    """A walker 1 to 3 m ahead of a moving robot for `duration` s, scanned at `rate_hz`
    (`seed` draws the surroundings and the range noise)."""
    t = np.arange(int(round(duration * rate_hz))) / rate_hz
    x, y, heading = _path(t)
    ahead = 2.0 + 0.9 * np.sin(2.0 * np.pi * t / 17.0)
    aside = 0.25 * np.sin(2.0 * np.pi * t / 11.0)
    walker = np.column_stack((x + ahead * np.cos(heading) - aside * np.sin(heading),
                              y + ahead * np.sin(heading) + aside * np.cos(heading)))
    velocity = np.gradient(walker, t, axis=0)
    walls, posts = _surroundings(seed, ROBOT_SPEED * duration + 10.0)
    # Posts never stand on the walker's way.
    centres, radii = posts
    clear = np.array([np.min(np.hypot(*(walker - c).T)) > 0.6 for c in centres])
    lidar = LidarSimulator(spec, BodyModel.fitted(), seed=seed, walls=walls, posts=(centres[clear], radii[clear]))
    poses = [Pose2D(float(a), float(b), float(h)) for a, b, h in zip(x, y, heading)]
    seen = [lidar.observe(float(when), pose, p[None, :], v[None, :]) for when, pose, p, v in zip(t, poses, walker, velocity)]
    in_laser = np.array([pose.inverse().apply(p[None, :])[0] for pose, p in zip(poses, walker)])
    return FollowingWalk(poses, [scan for scan, _ in seen], walker, in_laser, np.array([b[0] for _, b in seen]), seed)


#: Beams on the walker's legs for them to count as seen (a segment's minimum).
VISIBLE_BEAMS = 3


def follow(rate_hz: float, odometry: bool, seed: int = 0, classifier: LegClassifier | None = None) -> tuple[ClearMot, int]:
    """CLEAR-MOT of the walker (0.75 m match radius) over 60 s with the learned setup (`classifier`,
    default: the shipped one), and how many scans found the walker's place on the static world.
    Without odometry the walk is tracked in the laser's frame as `trials log track` tracks it:
    scan matching tells how that frame moves."""
    walk = following_walk(60.0, rate_hz, seed)
    tracker = PersonTracker.learned(classifier)
    matching = None if odometry else ScanOdometry()
    score, absorbed = ClearMot(), 0
    for pose, scan, world, local, beams in zip(walk.poses, walk.scans, walk.walker, walk.walker_in_laser, walk.beams):
        if matching is not None:
            matching.update(scan)
        result = tracker.process(scan, pose if odometry else Pose2D(), motion=None if matching is None else matching.pose)
        truth = (world if odometry else local)[None, :]
        assert tracker.world is not None
        absorbed += int(tracker.world.is_static(truth)[0])
        ids = np.array([t.track_id for t in result.tracks], dtype=int)
        where = np.array([[t.x, t.y] for t in result.tracks]).reshape(-1, 2)
        seen = int(beams >= VISIBLE_BEAMS)
        score.update(ScoredScan(np.array([1])[:seen], truth[:seen], ids, where, hidden=truth[seen:]))
    return score, absorbed
