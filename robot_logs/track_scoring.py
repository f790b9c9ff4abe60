"""Scoring a tracks CSV against the people labelled in a log (`trials log score-tracks`).

Labels are leg_tracker's `Person`/`PersonArray` messages (positions with ids) or a
geometry_msgs/PoseArray (the k-th pose is person k). Every scan of the scan topic is scored:
a scan with no label message holds no labelled person, so its tracks are false positives;
the figures are also given over the labelled scans alone. An optional angular window keeps
only people and tracks whose bearing from the sensor lies inside it (tracks in the sensor frame).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robot_logs.clear_mot import MATCH_RADIUS, ClearMot, ScoredScan
from robot_logs.convert import stamp_ns
from robot_logs.errors import LogError
from robot_logs.frames import frame_name
from robot_logs.reader import LogReader
from robot_logs.topics import POINTS_TYPES, SCAN_TYPES, listing, pick_topic
from robot_logs.tracks import TrackTable


@dataclass(frozen=True)
class Labels:
    """One label message: stamp and record time (ns; equal when the label was unstamped),
    frame, (N,) person ids and (N, 2) positions."""

    stamp_ns: int
    record_ns: int
    frame: str
    ids: np.ndarray
    points: np.ndarray


def to_labels(msg: Any, record_ns: int) -> Labels:
    """Labelled people of a PersonArray (`people`, each with `pose` and `id`) or a PoseArray."""
    if hasattr(msg, "people"):
        ids = np.array([int(p.id) for p in msg.people], dtype=int)
        points = [[p.pose.position.x, p.pose.position.y] for p in msg.people]
    else:
        ids = np.arange(len(msg.poses))
        points = [[p.position.x, p.position.y] for p in msg.poses]
    points_array = np.array(points, dtype=float).reshape(-1, 2)
    return Labels(stamp_ns(msg.header, record_ns), record_ns, frame_name(msg.header.frame_id), ids, points_array)


def _label_topic(log: LogReader, override: str | None) -> str:
    if override is not None:
        return pick_topic(log.topics, tuple({t.msgtype for t in log.topics}), "labels", override, log.path, "--gt-topic").name
    fitting = [t for t in log.topics if t.msgtype in POINTS_TYPES or t.msgtype.endswith("/PersonArray")]
    if len(fitting) != 1:
        what = "no" if not fitting else "several"
        raise LogError(f"{log.path} has {what} PersonArray or PoseArray topics; name one with --gt-topic (topics: {listing(log.topics)})")
    return fitting[0].name


@dataclass(frozen=True)
class Window:
    """Bearings (rad) inside which people and tracks count."""

    low: float
    high: float

    def keep(self, points: np.ndarray) -> np.ndarray:
        bearing = np.arctan2(points[:, 1], points[:, 0])
        return (bearing >= self.low) & (bearing <= self.high)


def scored_scans(
    path: str | Path,
    tracks: TrackTable,
    scan_topic: str | None = None,
    gt_topic: str | None = None,
    gt_frame: str | None = None,
    window: Window | None = None,
) -> Iterator[tuple[ScoredScan, bool]]:
    """Each scan of the log as (people and tracks, whether a label message goes with it).

    A label goes with the scan of the same stamp, else the nearest within half a scan period; an
    unstamped label (labelling tools often leave stamps at zero) with the scan recorded nearest.

    Raises:
        LogError: no label topic, or labels and tracks in different frames.
    """
    with LogReader(path) as log:
        scan_name = pick_topic(log.topics, SCAN_TYPES, "LaserScan", scan_topic, log.path, "--scan-topic").name
        label_name = _label_topic(log, gt_topic)
        stamps, records, labels = [], [], []
        for message in log.messages({scan_name, label_name}):
            if message.topic == scan_name:
                stamps.append(stamp_ns(message.data.header, message.record_ns))
                records.append(message.record_ns)
            else:
                labels.append(to_labels(message.data, message.record_ns))
    scan_stamps, scan_records = np.array(stamps, dtype=np.int64), np.array(records, dtype=np.int64)
    if len(scan_stamps) == 0 or not labels:
        raise LogError(f"{path}: no scans on {scan_name} or no labels on {label_name}")
    frames = {row.frame for row in tracks.rows}
    label_frame = gt_frame or labels[0].frame
    if frames and frames != {label_frame}:
        raise LogError(
            f"the tracks are in frame {', '.join(sorted(frames))} but the labels of {path} in {label_frame}; "
            "track in the labels' frame (trials log track --frame) or name the labels' frame with --gt-frame"
        )
    period = float(np.median(np.diff(scan_stamps))) if len(scan_stamps) > 1 else math.inf
    by_scan: dict[int, Labels] = {}
    for label in labels:
        if label.stamp_ns == label.record_ns:
            by_scan[int(np.argmin(np.abs(scan_records - label.record_ns)))] = label
            continue
        nearest = int(np.argmin(np.abs(scan_stamps - label.stamp_ns)))
        if abs(int(scan_stamps[nearest]) - label.stamp_ns) <= period / 2:
            by_scan[nearest] = label
    rows_by_scan: dict[int, list] = {}
    for row in tracks.rows:
        rows_by_scan.setdefault(row.scan_index, []).append(row)
    for index in range(len(scan_stamps)):
        label = by_scan.get(index)
        ids = label.ids if label is not None else np.zeros(0, dtype=int)
        people = label.points if label is not None else np.zeros((0, 2))
        rows = rows_by_scan.get(index, [])
        track_ids = np.array([r.track_id for r in rows], dtype=int)
        positions = np.array([[r.x, r.y] for r in rows], dtype=float).reshape(-1, 2)
        if window is not None:
            keep_people, keep_tracks = window.keep(people), window.keep(positions)
            ids, people = ids[keep_people], people[keep_people]
            track_ids, positions = track_ids[keep_tracks], positions[keep_tracks]
        yield ScoredScan(ids, people, track_ids, positions), label is not None


def score_tracks(path: str | Path, tracks: TrackTable, radius: float = MATCH_RADIUS, **options: Any) -> dict[str, ClearMot]:
    """CLEAR-MOT over all scans and over the labelled scans alone (options: see `scored_scans`)."""
    everything, labelled = ClearMot(), ClearMot()
    for scan, has_label in scored_scans(path, tracks, **options):
        everything.update(scan, radius)
        if has_label:
            labelled.update(scan, radius)
    return {"all scans": everything, "labelled scans": labelled}
