"""Person detection in one planar lidar scan, in the scan's own frame.

The steps, as in the classic leg detectors (e.g. Leigh et al., ICRA 2015): drop NaN, inf and
out-of-range beams; split the remaining points into segments wherever two neighbours are
farther apart than a jump distance; decide which segments are legs; pair nearby legs into
people. Legs are decided by a learned classifier on segment features
(`robot_logs.leg_classifier`) when one is given, else by width alone (leg-wide segments are
legs, body-wide ones whole people), which suits simulated scans with nothing but people.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from robot_logs.leg_classifier import LegClassifier
from robot_logs.records import Scan
from robot_logs.segment_features import segment_features


@dataclass(frozen=True)
class DetectorConfig:
    """Thresholds of the detector (metres).

    Attributes:
        jump_distance: neighbouring points farther apart than this start a new segment.
        min_points: fewer points than this make no segment (noise, far thin objects).
        leg_width: (min, max) end-to-end width of a segment taken as one leg.
        body_width: (min, max) width of a segment taken as a whole person (a body disc, or
            two legs too close to split); min should equal leg_width's max.
        pair_distance: two legs closer than this belong to one person.
        candidate_width: segments at least this wide are never shown to a classifier.
    """

    jump_distance: float = 0.13
    min_points: int = 3
    leg_width: tuple[float, float] = (0.05, 0.4)
    body_width: tuple[float, float] = (0.4, 0.8)
    pair_distance: float = 0.6
    candidate_width: float = 0.8


@dataclass(frozen=True)
class Segments:
    """Contiguous groups of scan points: (K, 2) centroids, (K,) widths and point counts, and
    the (M, 2) points they split with (K,) the index of each segment's first point; `beam_angle`
    is the scan's angle between neighbouring beams (rad); (M, 2) `open_sides` is True where the
    beam just before (column 0) or after (column 1) a point returned nothing valid."""

    centroids: np.ndarray
    widths: np.ndarray
    counts: np.ndarray
    points: np.ndarray
    starts: np.ndarray
    beam_angle: float
    open_sides: np.ndarray

    def features(self, select: np.ndarray) -> np.ndarray:
        """The classifier's features (`robot_logs.segment_features`) of the `select`ed segments."""
        return segment_features(self.points, self.starts, self.beam_angle, select, self.open_sides)

    def middles(self) -> np.ndarray:
        """(K, 2) the middle point of each segment: a point the lidar hit, unlike the centroid of
        a wide arc, which lies inside the object."""
        ends = np.append(self.starts[1:], len(self.points))
        return self.points[(self.starts + ends - 1) // 2].reshape(-1, 2)

    def centres(self) -> np.ndarray:
        """(K, 2) centres of the round objects seen: a lidar sees the near half of a leg or
        body, whose centroid lies about width / pi in front of the centre, so push it back."""
        distance = np.maximum(np.hypot(self.centroids[:, 0], self.centroids[:, 1]), 1e-9)
        return self.centroids * (1.0 + self.widths / (np.pi * distance))[:, None]


@dataclass(frozen=True)
class Detections:
    """What one scan shows: (L, 2) leg centroids (the points leg labels mark) and (P, 2)
    people, each the midpoint of two paired leg centres, a lone leg centre or a body centre;
    each person's confidence (P,) is the classifier's mean leg probability (1 by width rules),
    and their (P,) `spread` the distance between their two legs (NaN for a lone leg or a body):
    a walker's changes with each stride, two pieces of furniture keep theirs. `unsure` (U, 2)
    are the leg-sized segments off the static world that the classifier scored below its
    threshold, paired the same way: evidence only for a person already tracked."""

    legs: np.ndarray
    people: np.ndarray
    confidence: np.ndarray
    spread: np.ndarray | None = None
    unsure: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def scan_points(scan: Scan) -> np.ndarray:
    """(M, 2) points of the valid beams, in beam order."""
    valid = scan.valid()
    ranges = scan.ranges[valid]
    angles = scan.angles()[valid]
    return np.column_stack((ranges * np.cos(angles), ranges * np.sin(angles)))


def _covers_circle(scan: Scan) -> bool:
    return len(scan.ranges) * scan.angle_increment >= 2.0 * math.pi - 1e-6


def open_beams(scan: Scan) -> np.ndarray:
    """(M, 2) for each valid beam's point, whether the beam just before it and the one just after
    returned nothing valid: nothing seen there within the laser's range, whatever value the
    laser writes for it (inf, NaN, 0). Beyond the first and last beam of a partial scan nothing
    was looked at, which is not open."""
    valid = scan.valid()
    circle = _covers_circle(scan)
    before = np.concatenate(([circle and not valid[-1]], ~valid[:-1]))
    after = np.concatenate((~valid[1:], [circle and not valid[0]]))
    return np.column_stack((before, after))[valid]


def segment(scan: Scan, jump_distance: float) -> Segments:
    """Split a scan's valid points at every jump longer than `jump_distance`.

    A full 360-degree scan is rotated to start at a jump, so an object straddling the first
    and last beam stays one segment.
    """
    points = scan_points(scan)
    if len(points) == 0:
        empty = np.zeros((0, 2))
        return Segments(empty, np.zeros(0), np.zeros(0, dtype=int), empty, np.zeros(0, dtype=int), scan.angle_increment,
                        np.zeros((0, 2), dtype=bool))
    opening = open_beams(scan)
    jumps = np.hypot(*np.diff(points, axis=0).T) > jump_distance
    if _covers_circle(scan) and jumps.any() and np.hypot(*(points[0] - points[-1])) <= jump_distance:
        shift = int(np.flatnonzero(jumps)[0]) + 1
        points, opening = np.roll(points, -shift, axis=0), np.roll(opening, -shift, axis=0)
        jumps = np.hypot(*np.diff(points, axis=0).T) > jump_distance
    starts = np.concatenate(([0], np.flatnonzero(jumps) + 1))
    ends = np.concatenate((starts[1:], [len(points)]))
    counts = ends - starts
    centroids = np.add.reduceat(points, starts, axis=0) / counts[:, None]
    widths = np.hypot(*(points[ends - 1] - points[starts]).T)
    return Segments(centroids, widths, counts, points, starts, scan.angle_increment, opening)


def pair_legs(legs: np.ndarray, max_distance: float) -> tuple[list[tuple[int, int]], list[int]]:
    """Greedy pairing, closest pairs first: (pairs of leg indices, indices left single)."""
    count = len(legs)
    if count < 2:
        return [], list(range(count))
    distances = np.hypot(*(legs[:, None, :] - legs[None, :, :]).transpose(2, 0, 1))
    first, second = np.triu_indices(count, k=1)
    order = np.argsort(distances[first, second], kind="stable")
    used = np.zeros(count, dtype=bool)
    pairs = []
    for k in order:
        i, j = int(first[k]), int(second[k])
        if distances[i, j] > max_distance:
            break
        if not used[i] and not used[j]:
            used[i] = used[j] = True
            pairs.append((i, j))
    return pairs, [i for i in range(count) if not used[i]]


def people_of(legs: np.ndarray, max_distance: float) -> np.ndarray:
    """(P, 2) people of (L, 2) legs (`pair_legs`): each pair's midpoint, then each lone leg."""
    pairs, singles = pair_legs(legs, max_distance)
    return np.array([legs[[i, j]].mean(axis=0) for i, j in pairs] + [legs[i] for i in singles], dtype=float).reshape(-1, 2)


def leg_probabilities(segments: Segments, config: DetectorConfig, classifier: LegClassifier) -> np.ndarray:
    """(K,) each segment's probability of being a leg; 0 for those too small or too wide to be one."""
    candidates = (segments.counts >= config.min_points) & (segments.widths < config.candidate_width)
    probability = np.zeros(len(segments.counts))
    if candidates.any():
        probability[candidates] = classifier.probability(segments.features(candidates))
    return probability


def detect(
    scan: Scan,
    config: DetectorConfig = DetectorConfig(),
    classifier: LegClassifier | None = None,
    reject: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Detections:
    """Legs and people in one scan (scan frame); a single unpaired leg counts as a person.

    With a classifier, legs are the segments it scores at or above its threshold; without,
    legs and bodies are told by width. `reject` maps (K, 2) segment middle points to (K,) True
    for segments to leave out before pairing (those on the static world). The people are as many as the
    leg pairs, lone legs and (by width rules) body-wide segments together.
    """
    segments = segment(scan, config.jump_distance)
    centres = segments.centres()
    enough = segments.counts >= config.min_points
    widths = segments.widths
    leg_sized = enough & (widths >= config.leg_width[0]) & (widths < config.leg_width[1])
    if classifier is not None:
        probability = leg_probabilities(segments, config, classifier)
        is_leg = probability >= classifier.threshold
        is_body = np.zeros_like(is_leg)
        is_unsure = leg_sized & ~is_leg
        leg_scores = probability[is_leg]
    else:
        is_leg = leg_sized
        is_body = enough & (widths >= config.body_width[0]) & (widths <= config.body_width[1])
        is_unsure = np.zeros_like(is_leg)
        leg_scores = np.ones(int(is_leg.sum()))
    if reject is not None and (is_leg | is_body | is_unsure).any():
        rejected = reject(segments.middles())
        leg_scores = leg_scores[~rejected[is_leg]]
        is_leg, is_body, is_unsure = is_leg & ~rejected, is_body & ~rejected, is_unsure & ~rejected
    legs = centres[is_leg]
    pairs, singles = pair_legs(legs, config.pair_distance)
    people = [legs[[i, j]].mean(axis=0) for i, j in pairs]
    people.extend(legs[singles])
    people.extend(centres[is_body])
    confidence = [leg_scores[[i, j]].mean() for i, j in pairs]
    confidence.extend(leg_scores[singles])
    confidence.extend(np.ones(int(is_body.sum())))
    spread = [float(np.hypot(*(legs[i] - legs[j]))) for i, j in pairs]
    spread.extend(np.full(len(singles) + int(is_body.sum()), np.nan))
    people_array = np.array(people, dtype=float).reshape(-1, 2)
    return Detections(legs=segments.centroids[is_leg], people=people_array, confidence=np.array(confidence, dtype=float),
                      spread=np.array(spread, dtype=float), unsure=people_of(centres[is_unsure], config.pair_distance))
