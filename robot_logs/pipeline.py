"""Scans in, tracked people out: detection, a change of frame, and tracking, per scan.

`PersonTracker` is what both the log tracker (`track_log`) and a closed-loop simulator with
lidar perception use: hand it each scan with the sensor's pose in the output frame.
"""

from __future__ import annotations

from dataclasses import dataclass

from robot_logs.detection import Detections, DetectorConfig, detect
from robot_logs.frames import Pose2D
from robot_logs.records import Scan
from robot_logs.tracking import Tracker, TrackerConfig, TrackState


@dataclass(frozen=True)
class ScanResult:
    """One processed scan: detections and confirmed tracks, both in the output frame.

    Attributes:
        scan_index: 0-based position of the scan on its topic (file order).
        stamp_ns: the scan's header stamp.
        frame: name of the output frame (the scan's own frame, or e.g. 'odom').
        sensor_pose: pose of the scan frame in the output frame at the scan time.
        detections: legs and people found in the scan.
        tracks: confirmed tracks after this scan (positions and velocities).
    """

    scan_index: int
    stamp_ns: int
    frame: str
    sensor_pose: Pose2D
    detections: Detections
    tracks: list[TrackState]


class PersonTracker:
    """Detector plus tracker over consecutive scans, in one output frame."""

    def __init__(self, detector: DetectorConfig = DetectorConfig(), tracker: TrackerConfig = TrackerConfig()) -> None:
        self.detector = detector
        self.tracker = Tracker(tracker)

    def process(self, scan: Scan, sensor_pose: Pose2D = Pose2D(), frame: str | None = None, scan_index: int = 0) -> ScanResult:
        """Detect people in `scan`, move them into the output frame, update the tracks.

        Args:
            scan: the scan.
            sensor_pose: pose of the scan's frame in the output frame at the scan time
                (identity: track in the scan's own frame).
            frame: output frame name; defaults to the scan's frame.
            scan_index: position of the scan on its topic, carried into the result.
        """
        found = detect(scan, self.detector)
        moved = Detections(legs=sensor_pose.apply(found.legs), people=sensor_pose.apply(found.people))
        tracks = self.tracker.step(scan.stamp, moved.people)
        return ScanResult(scan_index, scan.stamp_ns, frame or scan.frame_id, sensor_pose, moved, tracks)
