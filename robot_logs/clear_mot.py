"""CLEAR-MOT scoring of tracks against labelled people, by the protocol of Leigh et al. (ICRA 2015).

Scan by scan: a track matches a labelled person within `radius` (0.75 m); a match of the
previous scan is carried over while it still holds; the rest are assigned by the Hungarian
method on distance (scipy). A person left unmatched is a miss, a track left unmatched a false
positive, and a person matched to another track than the one last matched to them an id switch.
MOTA = 1 - (misses + false positives + switches) / labelled person-scans; MOTP is the mean
distance of the matches (m).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

#: Largest distance at which a track counts as tracking a person (m), as in Leigh et al.
MATCH_RADIUS = 0.75


@dataclass(frozen=True)
class ScoredScan:
    """One scan's labelled people and tracks: ids (N,), (M,) and positions (N, 2), (M, 2), one frame.

    `hidden` (H, 2) are people known to be there but out of the sensor's sight (simulated ground
    truth): neither counted nor missed, and a track on one of them is no false positive, as in
    a labelled log, where a person nobody could see carries no label and a track kept through
    their occlusion is not held against the tracker.
    """

    person_ids: np.ndarray
    people: np.ndarray
    track_ids: np.ndarray
    tracks: np.ndarray
    hidden: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


@dataclass
class ClearMot:
    """Counts over a run of scans, and the MOTA and MOTP they give."""

    scans: int = 0
    objects: int = 0
    matches: int = 0
    misses: int = 0
    false_positives: int = 0
    id_switches: int = 0
    distance: float = 0.0
    _last: dict[int, int] = field(default_factory=dict, repr=False)
    _previous: dict[int, int] = field(default_factory=dict, repr=False)

    @property
    def mota(self) -> float:
        """NaN when no person was labelled."""
        if not self.objects:
            return float("nan")
        return 1.0 - (self.misses + self.false_positives + self.id_switches) / self.objects

    @property
    def motp(self) -> float:
        return self.distance / self.matches if self.matches else float("nan")

    @property
    def recall(self) -> float:
        return self.matches / max(self.objects, 1)

    def update(self, scan: ScoredScan, radius: float = MATCH_RADIUS) -> None:
        """Score one scan, carrying matches over from the one before."""
        people, tracks = scan.people.reshape(-1, 2), scan.tracks.reshape(-1, 2)
        person_ids, track_ids = [int(i) for i in scan.person_ids], [int(i) for i in scan.track_ids]
        distance = np.hypot(*(people[:, None, :] - tracks[None, :, :]).transpose(2, 0, 1)).reshape(len(people), len(tracks))
        matched: dict[int, int] = {}
        column = {track_id: j for j, track_id in enumerate(track_ids)}
        for i, person in enumerate(person_ids):
            j = column.get(self._previous.get(person, -1))
            if j is not None and distance[i, j] <= radius and j not in matched.values():
                matched[i] = j
        free_rows = [i for i in range(len(people)) if i not in matched]
        free_cols = [j for j in range(len(tracks)) if j not in matched.values()]
        if free_rows and free_cols:
            cost = distance[np.ix_(free_rows, free_cols)]
            rows, cols = linear_sum_assignment(np.where(cost <= radius, cost, 1e6))
            for r, c in zip(rows, cols):
                if cost[r, c] <= radius:
                    matched[free_rows[r]] = free_cols[c]
        unmatched = [j for j in range(len(tracks)) if j not in matched.values()]
        excused = _within(scan.hidden.reshape(-1, 2), tracks[unmatched], radius)
        for i, j in matched.items():
            person, track = person_ids[i], track_ids[j]
            if person in self._last and self._last[person] != track:
                self.id_switches += 1
            self._last[person] = track
            self.distance += float(distance[i, j])
        self._previous = {person_ids[i]: track_ids[j] for i, j in matched.items()}
        self.scans += 1
        self.objects += len(people)
        self.matches += len(matched)
        self.misses += len(people) - len(matched)
        self.false_positives += len(unmatched) - excused

    def add(self, other: ClearMot) -> None:
        """Add another run's counts to these (sums over several sequences)."""
        for name in ("scans", "objects", "matches", "misses", "false_positives", "id_switches", "distance"):
            setattr(self, name, getattr(self, name) + getattr(other, name))


class Identities:
    """Ids for people labelled without them (legs paired by position, passers-by found by
    background subtraction): each scan's people take the ids of the previous scan's people they
    pair with one to one within `reach` (m; the Hungarian method on distance), the rest new
    ones, so labels listed in another order do not count as id switches."""

    def __init__(self, reach: float = 0.5) -> None:
        self.reach = reach
        self._ids = np.zeros(0, dtype=int)
        self._points = np.zeros((0, 2))
        self._next = 0

    def __call__(self, people: np.ndarray) -> np.ndarray:
        """(N,) ids of one scan's (N, 2) people."""
        people = np.asarray(people, dtype=float).reshape(-1, 2)
        ids = np.full(len(people), -1, dtype=int)
        if len(people) and len(self._points):
            distance = np.hypot(*(people[:, None, :] - self._points[None, :, :]).transpose(2, 0, 1))
            rows, cols = linear_sum_assignment(np.where(distance <= self.reach, distance, 1e6))
            kept = distance[rows, cols] <= self.reach
            ids[rows[kept]] = self._ids[cols[kept]]
        for index in np.flatnonzero(ids < 0):
            ids[index], self._next = self._next, self._next + 1
        self._ids, self._points = ids, people
        return ids


def _within(hidden: np.ndarray, tracks: np.ndarray, radius: float) -> int:
    """How many tracks the Hungarian method can pair one to one with hidden people within `radius`."""
    if len(hidden) == 0 or len(tracks) == 0:
        return 0
    distance = np.hypot(*(hidden[:, None, :] - tracks[None, :, :]).transpose(2, 0, 1))
    rows, cols = linear_sum_assignment(np.where(distance <= radius, distance, 1e6))
    return int((distance[rows, cols] <= radius).sum())


def clear_mot(scans: Iterable[ScoredScan], radius: float = MATCH_RADIUS) -> ClearMot:
    """CLEAR-MOT counts over scans in time order."""
    score = ClearMot()
    for scan in scans:
        score.update(scan, radius)
    return score
