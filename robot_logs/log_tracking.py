"""Tracking the people in a recorded log, in the scan's own frame or the odometry frame.

For the odometry frame, the robot's odometry and the tf transforms are read first; each scan
is then placed by the pose of its frame in the odometry frame at the scan's header stamp
(odometry gives odom -> base, tf gives base -> laser; both interpolated in time).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Literal

from robot_logs.convert import to_odometry, to_scan, to_transforms
from robot_logs.errors import LogError
from robot_logs.frames import FrameTree, Pose2D
from robot_logs.pipeline import PersonTracker, ScanResult
from robot_logs.reader import LogReader
from robot_logs.records import Scan, seconds
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


def read_scans(log: LogReader, topic: str) -> Iterator[Scan]:
    """Every scan on a topic, in file order, each checked for consistent sizes."""
    for index, message in enumerate(log.messages({topic})):
        yield to_scan(message.data, message.record_ns, f"scan {index} on {topic} of {log.path}")


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
    topics = tf_topics(log.topics)
    for message in log.messages({t.name for t in topics}):
        for edge in to_transforms(message.data, message.record_ns, is_static_tf(message.topic)):
            if edge.child != base_frame:
                tree.add(edge.parent, edge.child, edge.stamp_ns, edge.pose, static=edge.static)
    return tree, odometry_frame


class LogTracking:
    """Iterates a log's scans as (scan, result) pairs; `skipped` counts scans with no pose.

    Args:
        log: an open log.
        frame: "sensor" (the scan's own frame) or "odom" (the odometry frame).
        topics: topic names that override the choice by type.
        tracker: detection and tracking (default: `PersonTracker.learned()`, the shipped leg
            classifier with static-world rejection).

    Raises:
        LogError: a needed topic is missing (the message lists the topics there are), or the
            scan frame is not connected to the odometry frame by tf.
    """

    def __init__(
        self,
        log: LogReader,
        frame: Frame = "sensor",
        topics: TopicNames = TopicNames(),
        tracker: PersonTracker | None = None,
    ) -> None:
        self.log = log
        self.frame = frame
        self.scan_topic = pick_topic(log.topics, SCAN_TYPES, "LaserScan", topics.scan, log.path, "--scan-topic")
        self.tree: FrameTree | None = None
        self.output_frame: str | None = None
        if frame == "odom":
            odometry = pick_topic(log.topics, ODOMETRY_TYPES, "Odometry", topics.odometry, log.path, "--odom-topic")
            self.tree, self.output_frame = read_frame_tree(log, odometry.name)
        self._tracker = tracker if tracker is not None else PersonTracker.learned()
        self.skipped = 0

    def _sensor_pose(self, scan: Scan) -> Pose2D | None:
        if self.tree is None:
            return Pose2D()
        assert self.output_frame is not None
        try:
            return self.tree.lookup(self.output_frame, scan.frame_id, scan.stamp_ns)
        except LogError as exc:
            raise LogError(f"{self.log.path}: {exc}") from None

    def __iter__(self) -> Iterator[tuple[Scan, ScanResult]]:
        seen, last_stamp = 0, 0
        for index, scan in enumerate(read_scans(self.log, self.scan_topic.name)):
            seen, last_stamp = seen + 1, scan.stamp_ns
            pose = self._sensor_pose(scan)
            if pose is None:
                self.skipped += 1
                continue
            yield scan, self._tracker.process(scan, pose, self.output_frame, index)
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
) -> TrackTable:
    """All tracks of a log file, one row per confirmed track per scan (`tracker`: detection and
    tracking, default `PersonTracker.learned()`)."""
    with LogReader(path, salvage=salvage) as log:
        tracking = LogTracking(log, frame, topics, tracker)
        rows = [row for _, result in tracking for row in result_rows(result)]
    return TrackTable(rows)
