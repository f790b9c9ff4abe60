"""Scoring detection and tracking against ground truth.

- Detection against labels (e.g. hand-labelled legs): one-to-one matches within a distance
  (Hungarian), giving recall, precision and the mean position error.
- Tracking against true trajectories: CLEAR-MOT (MOTA, MOTP, id switches) through
  `motmetrics`, a development dependency (which is why this lives with the tests).
- Features of labelled legs, real or simulated: the segments the training protocol calls legs,
  for a leg detector to score.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from robot_logs.detection import DetectorConfig
from robot_logs.frames import Pose2D
from robot_logs.labels import labelled_scans
from robot_logs.leg_training import TrainingSettings, candidates, match_labels
from robot_logs.lidar_sim import LidarSimulator, body_circles
from robot_logs.records import Scan
from robot_logs.segment_features import FEATURE_NAMES
from robot_logs.tracking import TrackState
from tests.support.crowd import Crowd

__all__ = ["DetectionScore", "clear_mot", "labelled_scans", "leg_features", "match", "score_detections", "simulated_legs"]


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


def simulated_legs(lidar: LidarSimulator, crowd: Crowd) -> list[tuple[Scan, np.ndarray]]:
    """Each scan of `crowd` seen by `lidar` standing at the origin, with the centres of every walker's
    legs as its labels, like the labelled bags' scans."""
    return [(lidar.scan(when, Pose2D(), people, velocities), body_circles(people, velocities, when, lidar.body)[0])
            for when, people, velocities in zip(crowd.times, crowd.positions, crowd.velocities)]


def leg_features(pairs: Iterable[tuple[Scan, np.ndarray]]) -> np.ndarray:
    """(L, len(FEATURE_NAMES)) features of the labelled legs' segments: the candidate segments matched
    one to one to a label within 0.1 m, the training protocol's positives (a leg hidden or too small to
    make a candidate segment is not among them)."""
    config, settings = DetectorConfig(), TrainingSettings()
    features = [np.zeros((0, len(FEATURE_NAMES)))]
    for scan, labels in pairs:
        segments, mask = candidates(scan, config)
        leg, _ = match_labels(segments.centroids[mask], labels, settings)
        if leg.any():
            features.append(segments.features(mask)[leg])
    return np.concatenate(features)
