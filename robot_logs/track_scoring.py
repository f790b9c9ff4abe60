"""Scoring a tracks CSV against the people labelled in a log (`trials log score-tracks`).

Labels come in three forms: leg_tracker's `PersonArray` (a stamped array of people with ids),
its `Person` (one message per person, no header: the form of Leigh et al.'s benchmark logs,
whose people are grouped by the scan recorded nearest), or a geometry_msgs/PoseArray (the k-th
pose is person k). Every scan of the scan topic is scored: a scan with no label holds no
labelled person, so its tracks are false positives; the figures are also given over the
labelled scans alone. An optional angular window keeps only people and tracks whose bearing
from the sensor lies inside it (tracks in the sensor frame).
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


def _kind(msgtype: str) -> str | None:
    """'person', 'people' or 'poses' for a label type score-tracks reads, else None."""
    if msgtype in POINTS_TYPES:
        return "poses"
    if msgtype.endswith("/PersonArray"):
        return "people"
    if msgtype.endswith("/Person"):
        return "person"
    return None


#: The label types in words, for messages.
LABEL_TYPES = "leg_tracker/Person, leg_tracker/PersonArray or geometry_msgs/PoseArray"


@dataclass(frozen=True)
class Labels:
    """One scan's labelled people: stamp and record time (ns; equal when the label was
    unstamped), frame ('' when the message names none), (N,) person ids and (N, 2) positions."""

    stamp_ns: int
    record_ns: int
    frame: str
    ids: np.ndarray
    points: np.ndarray


def to_labels(msg: Any, record_ns: int, kind: str) -> Labels:
    """Labelled people of a PersonArray (`people`, each with `pose` and `id`), of one Person
    (`pose` and `id`, unstamped and without frame) or of a PoseArray.

    Raises:
        LogError: the message lacks the fields of its kind.
    """
    try:
        if kind == "person":
            return Labels(record_ns, record_ns, "", np.array([int(msg.id)]),
                          np.array([[msg.pose.position.x, msg.pose.position.y]], dtype=float))
        if kind == "people":
            ids = np.array([int(p.id) for p in msg.people], dtype=int)
            points = [[p.pose.position.x, p.pose.position.y] for p in msg.people]
        else:
            ids = np.arange(len(msg.poses))
            points = [[p.position.x, p.position.y] for p in msg.poses]
        header = msg.header
    except AttributeError as exc:
        raise LogError(f"a label message lacks a field of {LABEL_TYPES} ({exc})") from None
    points_array = np.array(points, dtype=float).reshape(-1, 2)
    return Labels(stamp_ns(header, record_ns), record_ns, frame_name(header.frame_id), ids, points_array)


def _label_topic(log: LogReader, override: str | None) -> tuple[str, str]:
    """The label topic's name and kind (see `_kind`).

    Raises:
        LogError: the named topic is missing or of a type score-tracks does not read, or no
            topic or several have a label type when none is named.
    """
    if override is not None:
        topic = pick_topic(log.topics, tuple({t.msgtype for t in log.topics}), "labels", override, log.path, "--gt-topic")
        kind = _kind(topic.msgtype)
        if kind is None:
            raise LogError(f"topic {topic.name} of {log.path} holds {topic.msgtype}; score-tracks reads {LABEL_TYPES}")
        return topic.name, kind
    fitting = [t for t in log.topics if _kind(t.msgtype) is not None]
    if len(fitting) != 1:
        what = "no" if not fitting else "several"
        raise LogError(f"{log.path} has {what} label topics ({LABEL_TYPES}); name one with --gt-topic "
                       f"(topics: {listing(log.topics)})")
    return fitting[0].name, str(_kind(fitting[0].msgtype))


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
    unstamped label (labelling tools often leave stamps at zero, and a Person has no header)
    with the scan recorded nearest. Person labels name no frame: theirs is `gt_frame`, else the scan's.

    Raises:
        LogError: no label topic, one of a type not read, a malformed label, or labels and
            tracks in different frames.
    """
    with LogReader(path) as log:
        scan_name = pick_topic(log.topics, SCAN_TYPES, "LaserScan", scan_topic, log.path, "--scan-topic").name
        label_name, kind = _label_topic(log, gt_topic)
        stamps, records, labels, scan_frame = [], [], [], ""
        for message in log.messages({scan_name, label_name}):
            if message.topic == scan_name:
                stamps.append(stamp_ns(message.data.header, message.record_ns))
                records.append(message.record_ns)
                scan_frame = scan_frame or frame_name(message.data.header.frame_id)
            else:
                try:
                    labels.append(to_labels(message.data, message.record_ns, kind))
                except LogError as exc:
                    raise LogError(f"{path}, topic {label_name}: {exc}") from None
    scan_stamps, scan_records = np.array(stamps, dtype=np.int64), np.array(records, dtype=np.int64)
    if len(scan_stamps) == 0 or not labels:
        raise LogError(f"{path}: no scans on {scan_name} or no labels on {label_name}")
    frames = {row.frame for row in tracks.rows}
    label_frame = gt_frame or labels[0].frame or scan_frame
    if frames and frames != {label_frame}:
        raise LogError(
            f"the tracks are in frame {', '.join(sorted(frames))} but the labels of {path} in {label_frame}; "
            "track in the labels' frame (trials log track --frame) or name the labels' frame with --gt-frame"
        )
    period = float(np.median(np.diff(scan_stamps))) if len(scan_stamps) > 1 else math.inf
    by_scan: dict[int, Labels] = {}
    for label in labels:
        if label.stamp_ns == label.record_ns:
            nearest = int(np.argmin(np.abs(scan_records - label.record_ns)))
        else:
            nearest = int(np.argmin(np.abs(scan_stamps - label.stamp_ns)))
            if abs(int(scan_stamps[nearest]) - label.stamp_ns) > period / 2:
                continue
        earlier = by_scan.get(nearest)
        if kind == "person" and earlier is not None:  # one message per person: the scan's people together
            kept = earlier.ids != label.ids[0]  # a person labelled twice near one scan: the later label
            label = Labels(earlier.stamp_ns, earlier.record_ns, earlier.frame, np.append(earlier.ids[kept], label.ids),
                           np.vstack((earlier.points[kept], label.points)))
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
