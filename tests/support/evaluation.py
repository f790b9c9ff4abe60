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

from robot_logs.labels import labelled_scans
from robot_logs.tracking import TrackState

__all__ = ["DetectionScore", "clear_mot", "labelled_scans", "match", "score_detections"]


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
