"""Scans paired with their labels (geometry_msgs/PoseArray): hand-labelled legs or people.

Labelling tools stamp labels in different ways; a label with a header stamp goes with the scan
of the same stamp, an unstamped one with the scan recorded closest to it.
"""

from __future__ import annotations

import numpy as np

from robot_logs.convert import to_points, to_scan
from robot_logs.errors import LogError
from robot_logs.reader import LogReader
from robot_logs.records import PointSet, Scan
from robot_logs.topics import POINTS_TYPES, SCAN_TYPES, TopicNames, pick_topic


def labelled_scans(log: LogReader, topics: TopicNames = TopicNames()) -> list[tuple[Scan, PointSet]]:
    """Scans paired with their labels or ground truth (geometry_msgs/PoseArray, scan frame).

    Topics are chosen by type unless `topics.scan` / `topics.people` name them.

    Raises:
        LogError: a topic is missing (a log with no labels says so), or a scan has no label.
    """
    scan_topic = pick_topic(log.topics, SCAN_TYPES, "LaserScan", topics.scan, log.path, "--scan-topic").name
    label_topic = pick_topic(log.topics, POINTS_TYPES, "PoseArray", topics.people, log.path, "--labels-topic").name
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
