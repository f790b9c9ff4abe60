"""Tracking in the scan's own frame on a moving robot: where the log's odometry, its tf alone, or
scan matching places that frame, and what it changes for a post driven past and a person followed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_logs.errors import LogError
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.log_tracking import LogTracking, OdometryMotion, track_log
from robot_logs.pipeline import PersonTracker
from robot_logs.reader import LogReader
from robot_logs.records import Odometry, Transform
from robot_logs.scan_odometry import ScanOdometry
from robot_logs.topics import TopicNames
from tests.support.bag_writer import BagWriter
from trials.cli import main

MOUNT = Pose2D(0.3, 0.0, 0.0)  # the laser on the robot's base
POST = np.array([[8.0, 1.2]])  # a leg-sized post beside the robot's way, in the odometry frame
SPEED = 0.8  # m/s, the robot's and the followed walker's
SCANS = 150  # 15 s at 10 Hz


def base_pose(t: float) -> Pose2D:
    """The robot's base in the odometry frame: driving along x, turning slowly (the log starts at 1 s)."""
    return Pose2D(SPEED * (t - 1.0), 0.0, 0.02 * (t - 1.0))


def write_drive(path: Path, motion: str, mount: bool = True) -> None:
    """A robot driving 12 m through open ground past a post, a walker 2.5 m ahead of it keeping its
    pace: nothing for scan matching to hold on to. `motion` is how the log records the drive: "odometry"
    (nav_msgs/Odometry), "tf" (odom -> base_link on /tf, under a localiser's map -> odom) or "none";
    `mount`: base_link -> laser on /tf_static."""
    lidar = LidarSimulator(seed=3, posts=(POST, np.array([0.06])))
    with BagWriter(path, "ros1") as bag:
        if mount:
            bag.transforms([Transform(1_000_000_000, "base_link", "laser", MOUNT, True)], "/tf_static")
        for k in range(SCANS):
            t = 1.0 + 0.1 * k
            stamp, base = int(round(t * 1e9)), base_pose(t)
            if motion == "odometry":
                bag.odometry(Odometry(stamp, "odom", "base_link", base, SPEED, 0.02))
            elif motion == "tf":
                bag.transforms([Transform(stamp, "odom", "base_link", base, False)])
                if k % 10 == 0:  # a localiser's corrections: map -> odom jumps once a second
                    bag.transforms([Transform(stamp, "map", "odom", Pose2D(0.05 * k / 10, 0.0, 0.0), False)])
            laser = base.compose(MOUNT)
            walker = laser.apply(np.array([[2.5, -0.3]]))
            heading = np.array([[np.cos(laser.yaw), np.sin(laser.yaw)]]) * SPEED
            bag.scan(lidar.scan(t, laser, walker, heading))


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("drives")
    paths = {}
    for motion in ("odometry", "tf", "none"):
        paths[motion] = root / f"{motion}.bag"
        write_drive(paths[motion], motion)
    paths["unmounted"] = root / "unmounted.bag"
    write_drive(paths["unmounted"], "odometry", mount=False)
    return paths


def motions(path: Path, topics: TopicNames = TopicNames()) -> tuple[str | None, list[Pose2D]]:
    """Where tracking in the scan's frame placed that frame at each scan, and from what."""
    with LogReader(path) as log:
        tracking = LogTracking(log, "sensor", topics, PersonTracker())
        placed = []
        for _ in tracking:
            assert tracking.motion is not None
            placed.append(tracking.motion.pose)
    return tracking.motion_source, placed


@pytest.mark.parametrize(("motion", "source"), [("odometry", "odometry on /odom"), ("tf", "tf (odom frame)")])
def test_the_log_s_odometry_places_the_scan_frame(drives, motion: str, source: str) -> None:
    """Each scan's frame is where odometry (or tf alone, in odom rather than the jumping map frame
    above it) and the laser's mount put it, relative to the first scan."""
    found, placed = motions(drives[motion])
    assert found == source and len(placed) == SCANS
    first = base_pose(1.0).compose(MOUNT).inverse()
    for k, pose in enumerate(placed):
        truth = first.compose(base_pose(1.0 + 0.1 * k).compose(MOUNT))
        assert (pose.x, pose.y, pose.yaw) == pytest.approx((truth.x, truth.y, truth.yaw), abs=1e-6)


def test_without_odometry_scan_matching_places_the_scan_frame(drives) -> None:
    """A log with neither odometry nor a moving transform is matched scan to scan; here there is
    too little to match, so the frame stays where it started."""
    source, placed = motions(drives["none"])
    assert source == "scan matching" and placed[-1] == Pose2D()


def test_odometry_that_does_not_reach_the_laser(drives) -> None:
    """Without the laser's mount the odometry does not place the scan's frame: scan matching does,
    unless the odometry topic was named, which then is a one-line error naming the frames."""
    source, _ = motions(drives["unmounted"])
    assert source == "scan matching"
    with pytest.raises(LogError, match=r"unmounted\.bag: no transform connects frame 'laser' to 'odom'"):
        motions(drives["unmounted"], TopicNames(odometry="/odom"))


def test_two_odometry_topics_must_be_told_apart(tmp_path: Path) -> None:
    """A log with two Odometry topics is tracked in the scan's frame once one is named; unnamed,
    it is a one-line error that says how."""
    path = tmp_path / "two.bag"
    with BagWriter(path, "ros1") as bag:
        bag.transforms([Transform(1_000_000_000, "base_link", "laser", MOUNT, True)], "/tf_static")
        lidar = LidarSimulator(seed=3, posts=(POST, np.array([0.06])))
        for k in range(5):
            t = 1.0 + 0.1 * k
            for topic in ("/odom", "/odometry/filtered"):
                bag.odometry(Odometry(int(round(t * 1e9)), "odom", "base_link", base_pose(t), SPEED, 0.0), topic)
            bag.scan(lidar.scan(t, base_pose(t).compose(MOUNT), np.zeros((0, 2)), None))
    with pytest.raises(LogError, match=r"several Odometry topics \(/odom, /odometry/filtered\); choose one with --odom-topic"):
        motions(path)
    source, placed = motions(path, TopicNames(odometry="/odometry/filtered"))
    last = base_pose(1.0).compose(MOUNT).inverse().compose(base_pose(1.4).compose(MOUNT))
    assert source == "odometry on /odometry/filtered"
    assert (placed[-1].x, placed[-1].y, placed[-1].yaw) == pytest.approx((last.x, last.y, last.yaw), abs=1e-6)


def test_scan_odometry_asked_for_is_used_though_the_log_has_odometry(drives) -> None:
    with LogReader(drives["odometry"]) as log:
        tracking = LogTracking(log, "sensor", tracker=PersonTracker(), odometry="scan")
        assert isinstance(tracking.motion, ScanOdometry) and tracking.motion_source == "scan matching"
        assert isinstance(LogTracking(log, "sensor", tracker=PersonTracker()).motion, OdometryMotion)


def test_tf_alone_gives_the_odometry_frame(drives) -> None:
    """A log whose robot moves only on /tf tracks in `--frame odom` too: the followed walker's
    track runs along x at the robot's pace in frame odom."""
    table = track_log(drives["tf"], frame="odom", tracker=PersonTracker.rules_with_grid())
    assert {row.frame for row in table.rows} == {"odom"}
    walker = max(table.ids, key=lambda i: len(table.track(i)[0]))
    stamps, xy = table.track(walker)
    speed = np.diff(xy[:, 0]).sum() / (stamps[-1] - stamps[0])
    assert len(stamps) >= SCANS - 10 and speed == pytest.approx(SPEED, abs=0.05)


def tracked(path: Path, tracker: PersonTracker) -> dict[int, list[tuple[int, float, float]]]:
    """Each confirmed track's (scan index, x, y) rows, tracked in the scan's frame."""
    rows: dict[int, list[tuple[int, float, float]]] = {}
    with LogReader(path) as log:
        for _, result in LogTracking(log, "sensor", tracker=tracker):
            for track in result.tracks:
                rows.setdefault(track.track_id, []).append((result.scan_index, track.x, track.y))
    return rows


@pytest.mark.parametrize("setup", ["rules_with_grid", "learned"])
def test_with_odometry_the_post_stands_and_the_followed_walker_is_kept(drives, setup: str) -> None:
    """Placed by the log's odometry, the post the robot drives past is never a track and the walker
    ahead is one track to the end. Unplaced (the same drive logged without odometry, and scan matching
    finds nothing to match), the post glides back through the laser's frame and is tracked as a
    walker; with the width rules the walker, still in that frame, is taken for static world."""
    found = {}
    for motion in ("odometry", "none"):
        rows = tracked(drives[motion], getattr(PersonTracker, setup)())
        post = [track for track in rows.values() if any(abs(y - 1.2) < 0.3 for _, _, y in track)]
        walker = [track for track in rows.values() if all(abs(x - 2.5) < 0.4 and abs(y + 0.3) < 0.3 for _, x, y in track)]
        found[motion] = (len(post), len(walker), sum(len(track) for track in walker))
    assert found["odometry"][:2] == (0, 1) and found["odometry"][2] >= SCANS - 5
    assert found["none"][0] == 1
    if setup == "rules_with_grid":
        assert found["none"][2] <= SCANS - 40


def test_trials_log_track_names_what_moved_the_scan_frame(drives, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for motion, source in (("tf", "tf (odom frame)"), ("none", "scan matching")):
        assert main(["log", "track", str(drives[motion]), "--out", str(tmp_path / f"{motion}.csv")]) == 0
        assert capsys.readouterr().err.rstrip().endswith(f"; motion from {source}")
