"""Scoring detection and tracking against ground truth.

- Detection against labels (e.g. hand-labelled legs): one-to-one matches within a distance
  (Hungarian), giving recall, precision and the mean position error.
- Tracking against true trajectories: CLEAR-MOT (MOTA, MOTP, id switches) through
  `motmetrics`, a development dependency (which is why this lives with the tests).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from robot_logs.convert import to_points, to_scan
from robot_logs.errors import LogError
from robot_logs.reader import LogReader
from robot_logs.records import PointSet, Scan
from robot_logs.topics import POINTS_TYPES, SCAN_TYPES, TopicNames, pick_topic
from robot_logs.tracking import TrackState


def match(detected: np.ndarray, truth: np.ndarray, max_distance: float) -> np.ndarray:
    """Distances of the one-to-one matches (closest total first) that lie within max_distance."""
    if len(detected) == 0 or len(truth) == 0:
        return np.zeros(0)
    cost = np.hypot(*(detected[:, None, :] - truth[None, :, :]).transpose(2, 0, 1))
    rows, cols = linear_sum_assignment(cost)
    distances = cost[rows, cols]
    return distances[distances <= max_distance]


@dataclass(frozen=True)
class DetectionScore:
    """Counts of matched, spurious and missed detections over many scans, and the mean error (m)."""

    matched: int
    spurious: int
    missed: int
    mean_error: float

    @property
    def recall(self) -> float:
        return self.matched / max(self.matched + self.missed, 1)

    @property
    def precision(self) -> float:
        return self.matched / max(self.matched + self.spurious, 1)


def score_detections(pairs: Iterable[tuple[np.ndarray, np.ndarray]], max_distance: float) -> DetectionScore:
    """Score (detected, true) point sets scan by scan."""
    matched = spurious = missed = 0
    errors: list[float] = []
    for detected, truth in pairs:
        distances = match(detected, truth, max_distance)
        matched += len(distances)
        spurious += len(detected) - len(distances)
        missed += len(truth) - len(distances)
        errors.extend(distances.tolist())
    return DetectionScore(matched, spurious, missed, float(np.mean(errors)) if errors else float("nan"))


def labelled_scans(log: LogReader, topics: TopicNames = TopicNames()) -> list[tuple[Scan, PointSet]]:
    """Scans paired with their labels or ground truth (geometry_msgs/PoseArray, scan frame).

    Topics are chosen by type unless `topics.scan` / `topics.people` name them. A label with
    a header stamp goes with the scan of the same stamp; an unstamped one with the scan
    recorded closest to it (labelling tools often leave stamps at zero).

    Raises:
        LogError: a topic is missing, or a scan has no label.
    """
    scan_topic = pick_topic(log.topics, SCAN_TYPES, "LaserScan", topics.scan, log.path, "--scan-topic").name
    label_topic = pick_topic(log.topics, POINTS_TYPES, "PoseArray", topics.people, log.path, "--people-topic").name
    scans: list[tuple[Scan, int]] = []
    labels: list[PointSet] = []
    for message in log.messages({scan_topic, label_topic}):
        if message.topic == scan_topic:
            where = f"scan {len(scans)} on {scan_topic} of {log.path}"
            scans.append((to_scan(message.data, message.record_ns, where), message.record_ns))
        else:
            labels.append(to_points(message.data, message.record_ns))
    by_stamp = {label.stamp_ns: label for label in labels if label.stamp_ns != label.record_ns}
    unstamped = [label for label in labels if label.stamp_ns == label.record_ns]
    record_times = np.array([label.record_ns for label in unstamped])
    pairs = []
    for scan, record_ns in scans:
        label = by_stamp.get(scan.stamp_ns)
        if label is None and len(unstamped):
            label = unstamped[int(np.argmin(np.abs(record_times - record_ns)))]
        if label is None:
            raise LogError(f"scan at {scan.stamp} s on {scan_topic} of {log.path} has no label on {label_topic}")
        pairs.append((scan, label))
    return pairs


def clear_mot(
    truth: Sequence[np.ndarray], tracks: Sequence[Sequence[TrackState]], max_distance: float = 0.5
) -> dict[str, float]:
    """CLEAR-MOT of tracks against true positions, frame by frame.

    Args:
        truth: per frame, (N, 2) true positions; row i is always person i.
        tracks: per frame, the tracker's confirmed tracks.
        max_distance: farthest a track may be from a person to count as tracking them (m).

    Returns:
        mota, motp (mean distance of matches, m), id_switches, false_positives, misses, objects.
    """
    import motmetrics

    accumulator = motmetrics.MOTAccumulator(auto_id=True)
    for people, states in zip(truth, tracks, strict=True):
        hypotheses = np.array([[s.x, s.y] for s in states]).reshape(-1, 2)
        squared = motmetrics.distances.norm2squared_matrix(people, hypotheses, max_d2=max_distance**2)
        accumulator.update(list(range(len(people))), [s.track_id for s in states], np.sqrt(squared))
    names = {"mota": "mota", "motp": "motp", "num_switches": "id_switches", "num_false_positives": "false_positives",
             "num_misses": "misses", "num_objects": "objects"}
    row = motmetrics.metrics.create().compute(accumulator, metrics=list(names), name="run").iloc[0]
    return {names[key]: float(row[key]) for key in names}
