"""Multi-person tracking: one constant-velocity Kalman filter per track (filterpy), detections
assigned to tracks by the Hungarian method (scipy) on Mahalanobis distances, with gating.

Life of a track: it is born tentative from an unassigned detection that is not on the static world,
confirmed (and given the next id, never reused) on a scan that detects it, once it has `birth_hits`
hits (`sure_hits` while its mean confidence reaches `sure_confidence`) and the detector's mean confidence
over its hits so far reaches `confirm_confidence` (`striding_confidence` for a track whose legs
stride; one that does not walk and whose mean confidence is under `sure_confidence` also waits
`still_wait` seconds, long enough for the static world to tell; an infinite wait lasts until it
walks), dropped after `tentative_misses` misses in a row while still tentative (a detection on the
static world counts as a miss for a tentative track), reported while it has missed at most
`report_misses` scans in a row, and deleted after `death_misses` consecutive misses once confirmed.
A detection beside a confirmed track (`birth_clearance`) starts no track: it is that person's other
leg. A confirmed person who stands still is kept: only confirmation may ask for motion.

A track walks while it is `still_distance` from where it was `walk_window` seconds before, or its
legs' spread changes with a stride; a walker needs no wait, however still they are in the output
frame. Where the output frame moves with the robot (the laser's own), `step` may be told where that
frame is in a frame fixed to the world (odometry's or scan matching's), and motion is judged there:
a post that the robot drives past moves in the laser's frame but does not walk. Seen from a moving
sensor two posts seem to change their spread as one hides the other, so a change of spread seen
while the sensor moved `view_shift` counts as a stride towards confirming a track only if the track
moved as well. A confirmed track that walks and that no detection reached takes the nearest
unsure one (a leg-sized segment off the static world that the classifier scored low) inside the gate
its filter predicts, for `unsure_time` seconds after its last detection, so a person already
followed is kept through the scans where the classifier doubts their legs. A confirmed track coasts
on its filter's prediction, its gate growing with the filter's uncertainty, and lives `death_misses`
scans and at least `death_time` seconds without a hit, so it outlives the same gap at any scan rate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment

from robot_logs.frames import Pose2D

#: Chi-square quantile with 2 degrees of freedom: 99 % of true matches fall inside the gate.
CHI2_2DOF_99 = 9.21


@dataclass(frozen=True)
class TrackerConfig:
    """Noise levels and track-management rules.

    Attributes:
        measurement_std: standard deviation of a detected position (m).
        acceleration_std: white-noise acceleration of walking people (m/s^2).
        initial_speed_std: velocity uncertainty of a newborn track (m/s).
        gate: largest squared Mahalanobis distance of an accepted detection.
        birth_hits: hits that confirm a tentative track (it dies at `tentative_misses` misses in a row).
        sure_hits: the hits that do while its mean confidence reaches `sure_confidence` (None: as many).
        death_misses: consecutive misses that delete a confirmed track, once it has also
            missed for `death_time` seconds.
        death_time: seconds without a hit a confirmed track outlives (0: scans alone count).
        report_misses: a confirmed track is reported only while it has missed at most this many
            scans in a row; it lives on unreported until `death_misses`, so a person coming out
            from behind someone keeps their track and id.
        tentative_misses: consecutive misses that drop a tentative track (1: its first miss).
        birth_clearance: an unassigned detection closer than this (m) to a confirmed track starts
            no track (a person's second leg or a piece of them, not a second person).
        confirm_confidence: the mean detection confidence a tentative track needs to be confirmed.
        striding_confidence: the mean a tentative track that strides (see `gait_spread`) needs
            instead (None: the same): a gait is evidence of a person beside the detector's scores,
            in any frame (displacement is not, where the robot's motion moves furniture).
        still_wait, still_distance, sure_confidence: a tentative track that has not walked
            (see `walk_window`), with a mean confidence under `sure_confidence`, is confirmed no
            earlier than `still_wait` seconds after its birth (inf: not until it walks).
        gait_spread: a change of the distance between a track's two legs (m) that shows a
            stride, however still the person is in the output frame (someone followed by the
            robot, tracked in the robot's frame); inf leaves strides out.
        view_shift: a change of spread seen while the sensor moved this far (m) counts as a
            stride for a tentative track (a walk, and confirmation at `striding_confidence`) only
            if the track also moved `still_distance`: from a moving sensor two posts seem to
            change their spread as one hides the other.
        walk_window: a track walks while its detections of the last this many seconds moved
            `still_distance` or changed their spread by `gait_spread`.
        unsure_time: a confirmed track that walks takes unsure detections for this many seconds
            after its last detection (0: never), so it cannot live on doubted segments alone.
    """

    measurement_std: float = 0.2
    acceleration_std: float = 3.0
    initial_speed_std: float = 1.0
    gate: float = CHI2_2DOF_99
    birth_hits: int = 3
    sure_hits: int | None = None
    death_misses: int = 5
    death_time: float = 0.0
    confirm_confidence: float = 0.0
    striding_confidence: float | None = None
    still_wait: float = 0.0
    still_distance: float = 0.3
    gait_spread: float = np.inf
    view_shift: float = 0.1
    walk_window: float = 2.0
    unsure_time: float = 0.0
    sure_confidence: float = 1.0
    report_misses: int = 1_000_000
    tentative_misses: int = 1
    birth_clearance: float = 0.0


@dataclass(frozen=True)
class TrackState:
    """A confirmed track after one scan: stable id, position (m) and velocity (m/s)."""

    track_id: int
    x: float
    y: float
    vx: float
    vy: float


class Seen(NamedTuple):
    """One detection of a track as remembered for judging its motion: when, where the filter put
    the track and where the sensor was (m, in the frame motion is judged in), and the legs' spread
    (m; NaN for one leg)."""

    time: float
    x: float
    y: float
    spread: float
    sensor_x: float
    sensor_y: float


class Track:
    """One person's filter (state x, y, vx, vy) and its hit and miss counts."""

    def __init__(self, position: np.ndarray, config: TrackerConfig) -> None:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = np.array([position[0], position[1], 0.0, 0.0])
        kf.H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
        kf.R = np.eye(2) * config.measurement_std**2
        kf.P = np.diag([config.measurement_std**2] * 2 + [config.initial_speed_std**2] * 2)
        self.kf = kf
        self.track_id: int | None = None
        self.hits = 1
        self.birth = np.array(position[:2], dtype=float)
        self.born: float | None = None
        self.misses = 0
        self.last_hit: float | None = None
        self.last_sure: float | None = None
        #: Its detections within `walk_window`, oldest first.
        self.recent: list[Seen] = []
        self.confidence_sum = 0.0

    @property
    def confirmed(self) -> bool:
        return self.track_id is not None

    def moved(self, config: TrackerConfig, place: np.ndarray) -> bool:
        """Whether, now at `place`, it is `still_distance` from where it was `walk_window` ago (or
        at its birth, if younger)."""
        return bool(self.recent) and bool(np.hypot(place[0] - self.recent[0].x, place[1] - self.recent[0].y)
                                          >= config.still_distance)

    def walking(self, config: TrackerConfig, place: np.ndarray) -> bool:
        """Whether it moved (see `moved`) or strides: a walker, not furniture (which neither moves nor strides)."""
        return self.moved(config, place) or self.striding(config)

    def striding(self, config: TrackerConfig) -> bool:
        """Whether its legs' spread changed by `gait_spread` within `walk_window`: a gait, which
        furniture never shows, even where the robot's own motion moves it in the output frame."""
        spread = np.array([seen.spread for seen in self.recent], dtype=float)
        spread = spread[np.isfinite(spread)]
        return bool(len(spread) > 1 and np.ptp(spread) >= config.gait_spread)

    def gait(self, config: TrackerConfig, place: np.ndarray) -> bool:
        """Whether it strides as a person does: seen from a sensor that stayed within `view_shift`
        of where it was, or while the track moved too (see `moved`)."""
        if not self.striding(config):
            return False
        first, last = self.recent[0], self.recent[-1]
        view = np.hypot(last.sensor_x - first.sensor_x, last.sensor_y - first.sensor_y)
        return bool(view < config.view_shift) or self.moved(config, place)

    def note(self, time: float, place: np.ndarray, spread: float, sensor: np.ndarray, window: float) -> None:
        """Remember a detection (where it put the filter, and where the sensor was), forgetting
        those older than `window` seconds."""
        self.recent = [seen for seen in self.recent if time - seen.time <= window]
        self.recent.append(Seen(time, float(place[0]), float(place[1]), spread, float(sensor[0]), float(sensor[1])))
        self.last_sure = time

    def state(self) -> TrackState:
        x, y, vx, vy = (float(v) for v in self.kf.x)
        assert self.track_id is not None
        return TrackState(self.track_id, x, y, vx, vy)


class Tracker:
    """Tracks people through a sequence of detection sets; call `step` once per scan."""

    def __init__(self, config: TrackerConfig = TrackerConfig()) -> None:
        self.config = config
        self.tracks: list[Track] = []
        self.time: float | None = None
        #: The output frame's pose in the frame motion is judged in, and the sensor's place there (see `step`).
        self.motion = Pose2D()
        self.sensor = np.zeros(2)
        self._next_id = 1

    def _predict(self, time: float) -> None:
        dt = 0.0 if self.time is None else max(time - self.time, 0.0)
        self.time = time
        if dt == 0.0 or not self.tracks:
            return
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        Q = Q_discrete_white_noise(dim=2, dt=dt, var=self.config.acceleration_std**2, block_size=2, order_by_dim=False)
        for track in self.tracks:
            track.kf.predict(F=F, Q=Q)

    def distances(self, detections: np.ndarray) -> np.ndarray:
        """(T, D) squared Mahalanobis distances of detections from the predicted tracks."""
        if not self.tracks or len(detections) == 0:
            return np.zeros((len(self.tracks), len(detections)))
        means = np.array([t.kf.x[:2] for t in self.tracks])
        S = np.array([t.kf.P[:2, :2] + t.kf.R for t in self.tracks])
        innovation = detections[None, :, :] - means[:, None, :]
        return np.einsum("tdi,tij,tdj->td", innovation, np.linalg.inv(S), innovation)

    def associate(self, detections: np.ndarray, tracks: list[int] | None = None) -> list[tuple[int, int]]:
        """(track index, detection index) pairs: the Hungarian optimum inside the gate, over every
        track or the given ones."""
        cost = self.distances(detections)
        if tracks is not None:
            cost = cost[tracks]
        if cost.size == 0:
            return []
        rows, cols = linear_sum_assignment(np.minimum(cost, 2.0 * self.config.gate))
        index = list(range(len(self.tracks))) if tracks is None else tracks
        return [(index[r], int(c)) for r, c in zip(rows, cols) if cost[r, c] <= self.config.gate]

    def place(self, track: Track) -> np.ndarray:
        """(2,) where the track's filter is, in the frame motion is judged in."""
        return self.motion.apply(track.kf.x[:2])[0]

    def walking(self, track: Track) -> bool:
        """Whether the track walks (`Track.walking`), judged in the frame motion is judged in."""
        return track.walking(self.config, self.place(track))

    def _ready(self, track: Track, time: float) -> bool:
        """Whether a tentative track has enough hits, is confident enough and walks (moved, or
        strides as `Track.gait` judges), is sure, or has waited enough."""
        config = self.config
        mean = track.confidence_sum / track.hits
        sure = config.sure_hits is not None and mean >= config.sure_confidence
        if track.hits < (config.sure_hits if sure else config.birth_hits):
            return False
        place = self.place(track)
        gait = track.gait(config, place)  # a stride, not one a moving sensor's change of view could show
        striding = config.striding_confidence is not None and gait
        if mean < (config.striding_confidence if striding else config.confirm_confidence):
            return False
        assert track.born is not None
        return gait or track.moved(config, place) or mean >= config.sure_confidence or time - track.born >= config.still_wait

    def _beside_confirmed(self, detections: np.ndarray) -> np.ndarray:
        """(D,) True for detections closer than `birth_clearance` to a confirmed track: the
        other leg or a piece of someone already tracked, which may not start a track of its own."""
        confirmed = np.array([t.kf.x[:2] for t in self.tracks if t.confirmed]).reshape(-1, 2)
        if self.config.birth_clearance <= 0.0 or len(confirmed) == 0 or len(detections) == 0:
            return np.zeros(len(detections), dtype=bool)
        distance = np.hypot(*(detections[:, None, :] - confirmed[None, :, :]).transpose(2, 0, 1))
        return distance.min(axis=1) < self.config.birth_clearance

    def step(
        self, time: float, detections: np.ndarray, confidence: np.ndarray | None = None, static: np.ndarray | None = None,
        spread: np.ndarray | None = None, unsure: np.ndarray | None = None, motion: Pose2D | None = None,
        sensor: Pose2D | None = None,
    ) -> list[TrackState]:
        """Advance to `time` (s), take this scan's (D, 2) detections, return confirmed tracks.

        Args:
            time: the scan time (s).
            detections: (D, 2) detected people.
            confidence: (D,) the detector's confidence in each (default: 1).
            static: (D,) True for detections on the static world (default: none).
            spread: (D,) the distance between each detection's two legs, NaN for one (default: none).
            unsure: (U, 2) people the detector doubts, which only keep confirmed tracks that walk (default: none).
            motion: where the output frame is in a frame fixed to the world, when the output frame
                moves with the robot: tracks walk by their motion there (default: the output frame is fixed).
            sensor: the sensor's pose in the output frame (default: its origin), so a change of
                spread seen while it moved is not taken for a stride (`view_shift`).

        A confirmed track is reported while it coasts through up to `report_misses` misses.
        """
        detections = np.asarray(detections, dtype=float).reshape(-1, 2)
        confidence = np.ones(len(detections)) if confidence is None else np.asarray(confidence, dtype=float)
        static = np.zeros(len(detections), dtype=bool) if static is None else np.asarray(static, dtype=bool)
        self._predict(time)
        self.motion = motion if motion is not None else Pose2D()
        at = sensor if sensor is not None else Pose2D()
        self.sensor = self.motion.apply([at.x, at.y])[0]
        pairs = [(t, d) for t, d in self.associate(detections) if self.tracks[t].confirmed or not static[d]]
        hit = {t for t, _ in pairs}
        for t, d in pairs:
            track = self.tracks[t]
            track.kf.update(detections[d])
            track.hits += 1
            track.confidence_sum += confidence[d]
            track.note(time, self.place(track), np.nan if spread is None else spread[d], self.sensor, self.config.walk_window)
        if unsure is not None and len(unsure):
            waiting = [t for t, track in enumerate(self.tracks) if t not in hit and track.confirmed
                       and time - (track.last_sure or -np.inf) <= self.config.unsure_time and self.walking(track)]
            for t, u in self.associate(np.asarray(unsure, dtype=float).reshape(-1, 2), waiting) if waiting else []:
                self.tracks[t].kf.update(unsure[u])
                hit.add(t)
        for index, track in enumerate(self.tracks):
            if index in hit:
                track.misses, track.last_hit = 0, time
            else:
                track.misses += 1
        self.tracks = [t for t in self.tracks if not self._dead(t, time)]
        used = {d for _, d in pairs}
        crowded = self._beside_confirmed(detections)
        for d in range(len(detections)):
            if d not in used and not static[d] and not crowded[d]:
                self.tracks.append(Track(detections[d], self.config))
                self.tracks[-1].confidence_sum = confidence[d]
                self.tracks[-1].last_hit = time
                self.tracks[-1].note(time, self.place(self.tracks[-1]), np.nan if spread is None else spread[d], self.sensor,
                                     self.config.walk_window)
        for track in self.tracks:
            if track.born is None:
                track.born = time
            # A prediction is no evidence: a tentative track coasting through a miss waits for its next hit.
            if not track.confirmed and track.misses == 0 and self._ready(track, time):
                track.track_id = self._next_id
                self._next_id += 1
        return [t.state() for t in self.tracks if t.confirmed and t.misses <= self.config.report_misses]

    def _dead(self, track: Track, time: float) -> bool:
        """Whether a track has missed too long: `tentative_misses` scans while tentative;
        `death_misses` scans and `death_time` seconds once confirmed."""
        config = self.config
        if not track.confirmed:
            return track.misses >= config.tentative_misses
        assert track.last_hit is not None
        return track.misses >= config.death_misses and time - track.last_hit >= config.death_time
