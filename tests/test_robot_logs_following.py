"""Following a person: a walker 1 to 3 m ahead of a moving robot for 60 s, tracked by the
learned setup with the shipped detector at 10 and 40 Hz, in the odometry frame (with odometry)
and in the laser's own frame (a log without odometry)."""

from __future__ import annotations

import numpy as np
import pytest

from robot_logs.clear_mot import ClearMot, ScoredScan
from robot_logs.frames import Pose2D
from robot_logs.pipeline import PersonTracker
from tests.support.following import following_walk

#: Beams on the walker's legs for them to count as seen (a segment's minimum).
VISIBLE_BEAMS = 3


def follow(rate_hz: float, odometry: bool, seed: int = 0) -> tuple[ClearMot, int]:
    """CLEAR-MOT of the walker (0.75 m match radius) over 60 s, and how many scans found the
    walker's place on the static world."""
    walk = following_walk(60.0, rate_hz, seed)
    tracker = PersonTracker.learned()
    score, absorbed = ClearMot(), 0
    for pose, scan, world, local, beams in zip(walk.poses, walk.scans, walk.walker, walk.walker_in_laser, walk.beams):
        result = tracker.process(scan, pose if odometry else Pose2D())
        truth = (world if odometry else local)[None, :]
        assert tracker.world is not None
        absorbed += int(tracker.world.is_static(truth)[0])
        ids = np.array([t.track_id for t in result.tracks], dtype=int)
        where = np.array([[t.x, t.y] for t in result.tracks]).reshape(-1, 2)
        seen = int(beams >= VISIBLE_BEAMS)
        score.update(ScoredScan(np.array([1])[:seen], truth[:seen], ids, where, hidden=truth[seen:]))
    return score, absorbed


@pytest.mark.slow
@pytest.mark.parametrize("rate_hz", [10.0, 40.0])
@pytest.mark.parametrize("odometry", [True, False], ids=["odometry", "no odometry"])
def test_the_followed_walker_is_kept_in_nearly_every_scan(rate_hz: float, odometry: bool) -> None:
    score, absorbed = follow(rate_hz, odometry)
    assert score.objects >= 0.97 * 60 * rate_hz  # the walker is in sight nearly all the time
    assert score.recall >= 0.99, score
    assert score.id_switches <= 2 and score.motp <= 0.05
    assert absorbed == 0  # a person walking ahead of the robot is never static world
    if odometry:  # in a fixed frame the posts and walls turn static; in the robot's they move with it
        assert score.false_positives <= 0.01 * score.scans
