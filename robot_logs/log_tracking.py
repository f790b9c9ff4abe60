"""Tracking the people in a recorded log, in the scan's own frame or the odometry frame.

For the odometry frame, the robot's odometry and the tf transforms are read first; each scan
is then placed by the pose of its frame in the odometry frame at the scan's header stamp
(odometry gives odom -> base, tf gives base -> laser; both interpolated in time). A log without
an Odometry topic whose tf moves the scan's frame is placed by tf alone, in `ODOM_FRAME`.

A log recorded without odometry can still be tracked in a fixed frame: with scan odometry
(`scan_odometry`) each scan is placed by matching it to the laser's earlier scans, in the frame of
the first scan placed, named `SCAN_ODOMETRY_FRAME`. Tracked in the scan's own frame, the scans are
placed in a fixed frame too, to judge which tracks walk and to keep the static-world grid there
(`PersonTracker.process`'s `motion`): the scan's frame moves with the robot, and furniture it drives
past must neither walk nor escape the grid; tracks stay in the scan's frame. The log's odometry
places them where it has some (an Odometry topic, or tf alone), scan matching where it has none.

A ROS map (`occupancy_map`) is placed the same way: at each scan, the pose of the tracking frame
(the odometry frame, or the scan's own) in the map's frame is looked up in the same tree, where a
localiser's map -> odom transform on /tf (or /tf_static) links the two; a map drawn in the odometry
frame itself needs none. Legs on its occupied cells are static (`static_world.StaticWorld.known_static`).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Literal

from robot_logs.convert import to_odometry, to_scan, to_transforms
from robot_logs.errors import LogError
from robot_logs.frames import FrameTree, Pose2D
from robot_logs.occupancy_map import OccupancyMap
from robot_logs.pipeline import PersonTracker, ScanResult
from robot_logs.reader import LogReader
from robot_logs.records import Scan, seconds
from robot_logs.scan_odometry import ScanOdometry
from robot_logs.topics import (
    ODOMETRY_TYPES,
    SCAN_TYPES,
    TopicNames,
    is_static_tf,
    pick_topic,
    tf_topics,
)
from robot_logs.tracks import TrackRow, TrackTable

Frame = Literal["sensor", "odom"]
#: Where the robot's motion comes from in the odometry frame: the log's odometry topic, or scan matching.
Odometry = Literal["log", "scan"]
#: The output frame's name with scan odometry: the laser's pose at the first scan placed.
SCAN_ODOMETRY_FRAME = "scan_odom"
#: The frame tf alone places scans in where it lies above them (REP 105's odometry frame, which
#: moves smoothly; a localiser's map frame above it may jump), else tf's topmost frame.
ODOM_FRAME = "odom"


def read_scans(log: LogReader, topic: str) -> Iterator[Scan]:
    """Every scan on a topic, in file order, each checked for consistent sizes."""
    for index, message in enumerate(log.messages({topic})):
        yield to_scan(message.data, message.record_ns, f"scan {index} on {topic} of {log.path}")


def _add_tf(tree: FrameTree, log: LogReader, skip_child: str | None = None) -> None:
    """Add every transform on the log's tf topics to `tree`, but those into `skip_child`."""
    for message in log.messages({t.name for t in tf_topics(log.topics)}):
        for edge in to_transforms(message.data, message.record_ns, is_static_tf(message.topic)):
            if edge.child != skip_child:
                tree.add(edge.parent, edge.child, edge.stamp_ns, edge.pose, static=edge.static)


def read_frame_tree(log: LogReader, odometry_topic: str) -> tuple[FrameTree, str]:
    """The odometry and tf of a log as one frame tree, and the odometry frame's name.

    Odometry supplies the robot's base in the odometry frame; tf edges into the same base
    frame are left out so one source decides the robot's pose.
    """
    tree = FrameTree()
    odometry_frame = base_frame = None
    for message in log.messages({odometry_topic}):
        odometry = to_odometry(message.data, message.record_ns)
        odometry_frame, base_frame = odometry.frame_id, odometry.child_frame_id
        tree.add(odometry.frame_id, odometry.child_frame_id, odometry.stamp_ns, odometry.pose)
    if odometry_frame is None:
        raise LogError(f"topic {odometry_topic} of {log.path} holds no odometry messages")
    _add_tf(tree, log, skip_child=base_frame)
    return tree, odometry_frame


def odometry_topic_tree(log: LogReader, topics: TopicNames, hint: str = "") -> tuple[FrameTree, str, str]:
    """`read_frame_tree` of the log's Odometry topic (`topics.odometry`, else its only one), and
    where that comes from in words; `hint` ends the error when the log has no such topic."""
    topic = pick_topic(log.topics, ODOMETRY_TYPES, "Odometry", topics.odometry, log.path, "--odom-topic", hint)
    return (*read_frame_tree(log, topic.name), f"odometry on {topic.name}")


class OdometryMotion:
    """Where the log's odometry places the scan's frame, relative to the first scan it places: the
    frame that tracking in the scan's own frame judges motion in. A scan it does not place (outside
    the odometry's time span, or across a gap) keeps the pose before it, as if the robot stood."""

    def __init__(self, tree: FrameTree, frame: str, path: Path) -> None:
        self.tree, self.frame, self.path = tree, frame, path
        self.pose = Pose2D()
        self._origin: Pose2D | None = None

    def update(self, scan: Scan) -> None:
        """Move `pose` to the scan's."""
        try:
            placed = self.tree.lookup(self.frame, scan.frame_id, scan.stamp_ns)
        except LogError as exc:
            raise LogError(f"{self.path}: {exc}") from None
        if placed is not None:
            if self._origin is None:
                self._origin = placed.inverse()
            self.pose = self._origin.compose(placed)


def has_odometry_topic(log: LogReader, topics: TopicNames) -> bool:
    """Whether the log's odometry is to come from an Odometry topic: one is named, or it has some."""
    return topics.odometry is not None or any(t.msgtype in ODOMETRY_TYPES for t in log.topics)


def log_odometry(log: LogReader, topics: TopicNames, scan_frame: str) -> tuple[FrameTree, str, str] | None:
    """The log's own record of how the scan's frame moves: a frame tree, the fixed frame it moves in,
    and where that comes from in words. An Odometry topic with tf comes first (one named with
    `topics.odometry` must reach the scan's frame); without one, tf alone, where a transform above
    the scan's frame changes; None when neither places the scan's frame."""
    if has_odometry_topic(log, topics):
        tree, frame, source = odometry_topic_tree(log, topics)
        try:
            tree.lookup(frame, scan_frame, 0)
        except LogError as exc:
            if topics.odometry is not None:
                raise LogError(f"{log.path}: {exc}") from None
            return None
        return tree, frame, source
    tree = FrameTree()
    _add_tf(tree, log)
    frame = tree.moving_root(scan_frame, prefer=ODOM_FRAME)
    return None if frame is None else (tree, frame, f"tf ({frame} frame)")


class LogTracking:
    """Iterates a log's scans as (scan, result) pairs; `skipped` counts scans with no pose.

    Args:
        log: an open log.
        frame: "sensor" (the scan's own frame; `motion` tells how it moves) or "odom" (the
            odometry frame).
        odometry: "log" reads the log's odometry topic and tf, or tf alone where the log has no
            odometry topic (`log_odometry`); "scan" places each scan by scan matching instead (for
            a log without odometry), and with frame "odom" a scan it cannot place is skipped. In
            the scan's own frame, "log" falls back on scan matching where neither places the
            scan's frame (`motion_source` says which).
        topics: topic names that override the choice by type.
        tracker: detection and tracking (default: `PersonTracker.learned()`, the shipped leg
            classifier with static-world rejection).
        occupancy: a map whose occupied cells are static (needs odometry, in either frame); a scan
            whose tracking frame has no pose in the map's frame then is tracked without it and
            counted in `unmapped`.

    Raises:
        LogError: a needed topic is missing (the message lists the topics there are), the
            scan frame or the map's frame is not connected to the odometry frame by tf, a map is
            asked for with scan odometry, or scan matching placed no scan.
    """

    def __init__(
        self,
        log: LogReader,
        frame: Frame = "sensor",
        topics: TopicNames = TopicNames(),
        tracker: PersonTracker | None = None,
        occupancy: OccupancyMap | None = None,
        odometry: Odometry = "log",
    ) -> None:
        self.log = log
        self.frame = frame
        self.scan_topic = pick_topic(log.topics, SCAN_TYPES, "LaserScan", topics.scan, log.path, "--scan-topic")
        self.tree: FrameTree | None = None
        self.output_frame: str | None = None
        self.scan_odometry: ScanOdometry | None = None
        tree = odometry_frame = read = None
        if frame == "odom" and odometry == "scan":
            if occupancy is not None:
                raise LogError(f"{log.path}: a map is placed by the log's odometry and tf; scan odometry has no map frame")
            self.scan_odometry, self.output_frame = ScanOdometry(), SCAN_ODOMETRY_FRAME
        elif frame == "odom" or occupancy is not None:
            read = None if has_odometry_topic(log, topics) else self._log_odometry(topics)  # tf alone
            if read is None:
                # A map needs the log's own odometry; tracking alone can do without it.
                hint = "; no tf moves its scan frame either" + (
                    "" if occupancy is not None else "; scan odometry (--odometry scan) places its scans by scan matching instead")
                read = odometry_topic_tree(log, topics, hint)
            tree, odometry_frame, _ = read
            if frame == "odom":
                self.tree, self.output_frame = tree, odometry_frame
        #: Places the scan's own frame, to judge motion in, when that is the output frame; in words.
        self.motion: OdometryMotion | ScanOdometry | None = None
        self.motion_source: str | None = None
        if frame == "sensor":
            self.motion, self.motion_source = self._sensor_motion(odometry, topics, read)
        self._tracker = tracker if tracker is not None else PersonTracker.learned()
        self.occupancy = occupancy
        self._map_tree = tree
        if occupancy is not None:
            if self._tracker.world is None:
                raise ValueError("a map needs a tracker with static-world rejection")
            assert odometry_frame is not None
            self._map_pose(odometry_frame, 0)  # the map's frame must be reachable from the odometry frame
        self.skipped = 0
        self.unmapped = 0

    def _sensor_motion(self, odometry: Odometry, topics: TopicNames,
                       read: tuple[FrameTree, str, str] | None) -> tuple[OdometryMotion | ScanOdometry, str]:
        """What places the scan's frame as the robot moves, and in words: the log's odometry (`read`
        already for a map), else what `log_odometry` finds, else scan matching."""
        if odometry == "log" and read is None:
            read = self._log_odometry(topics)
        if odometry == "scan" or read is None:
            return ScanOdometry(), "scan matching"
        tree, fixed, source = read
        return OdometryMotion(tree, fixed, self.log.path), source

    def _log_odometry(self, topics: TopicNames) -> tuple[FrameTree, str, str] | None:
        """`log_odometry` for the frame of the log's first scan."""
        scans = read_scans(self.log, self.scan_topic.name)
        first = next(scans, None)
        scans.close()
        return None if first is None else log_odometry(self.log, topics, first.frame_id)

    def _sensor_pose(self, scan: Scan) -> Pose2D | None:
        if self.scan_odometry is not None:
            return self.scan_odometry.update(scan)
        if self.tree is None:
            return Pose2D()
        assert self.output_frame is not None
        try:
            return self.tree.lookup(self.output_frame, scan.frame_id, scan.stamp_ns)
        except LogError as exc:
            raise LogError(f"{self.log.path}: {exc}") from None

    def _map_pose(self, frame: str, stamp_ns: int) -> Pose2D | None:
        """The pose of `frame` in the map's frame at a time; None when tf does not say then."""
        assert self.occupancy is not None and self._map_tree is not None
        try:
            return self._map_tree.lookup(self.occupancy.frame, frame, stamp_ns)
        except LogError as exc:
            raise LogError(f"{self.log.path}: {exc}: the map {self.occupancy.source} is in frame {self.occupancy.frame!r}; "
                           "name the frame it is drawn in (--map-frame), or record the localiser's transform") from None

    def _place_map(self, scan: Scan, motion: Pose2D | None) -> None:
        """Place the map in the grid's frame: the tracking frame's, or the one `motion` places it in."""
        world = self._tracker.world
        if self.occupancy is None or world is None:
            return
        pose = self._map_pose(self.output_frame or scan.frame_id, scan.stamp_ns)
        self.unmapped += pose is None
        if pose is not None and motion is not None:
            pose = pose.compose(motion.inverse())
        world.known_static = None if pose is None else self.occupancy.placed(pose)

    def __iter__(self) -> Iterator[tuple[Scan, ScanResult]]:
        seen, last_stamp = 0, 0
        for index, scan in enumerate(read_scans(self.log, self.scan_topic.name)):
            seen, last_stamp = seen + 1, scan.stamp_ns
            pose = self._sensor_pose(scan)
            if pose is None:
                self.skipped += 1
                continue
            motion = None
            if self.motion is not None:
                self.motion.update(scan)
                motion = self.motion.pose
            self._place_map(scan, motion)
            yield scan, self._tracker.process(scan, pose, self.output_frame, index, motion)
        if self.scan_odometry is not None and seen and self.skipped == seen:
            raise LogError(f"scan matching placed none of the {seen} scans of {self.log.path} (too few points in each)")
        if self.tree is not None and seen and self.skipped == seen:
            raise LogError(
                f"no scan of {self.log.path} falls within its odometry's time span (last scan stamp "
                f"{seconds(last_stamp):.3f} s); are scans and odometry stamped on different clocks?"
            )


def result_rows(result: ScanResult) -> list[TrackRow]:
    """The track rows of one processed scan."""
    return [
        TrackRow(result.stamp_ns, result.scan_index, t.track_id, t.x, t.y, t.vx, t.vy, result.frame)
        for t in result.tracks
    ]


def track_log(
    path: str | Path,
    frame: Frame = "sensor",
    topics: TopicNames = TopicNames(),
    tracker: PersonTracker | None = None,
    salvage: bool = False,
    occupancy: OccupancyMap | None = None,
    odometry: Odometry = "log",
) -> TrackTable:
    """All tracks of a log file, one row per confirmed track per scan (`tracker`: detection and
    tracking, default `PersonTracker.learned()`; `occupancy`: a map whose occupied cells are static;
    `odometry`: as `LogTracking`'s)."""
    with LogReader(path, salvage=salvage) as log:
        tracking = LogTracking(log, frame, topics, tracker, occupancy, odometry)
        rows = [row for _, result in tracking for row in result_rows(result)]
    return TrackTable(rows)
