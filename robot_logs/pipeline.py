"""Scans in, tracked people out: detection, a change of frame, static-world rejection and
tracking, per scan.

`PersonTracker` is what both the log tracker (`track_log`) and a closed-loop simulator with
lidar perception use: hand it each scan with the sensor's pose in the output frame.
`PersonTracker.learned()` is the setup for real logs: the shipped (or a given) leg classifier,
the static-world grid and confirmation by the classifier's mean confidence;
`PersonTracker.rules_with_grid()` the one for simulated scans among furniture.

The rule for a person: a tentative track is confirmed at a hit, its 3rd or later, missing no two
scans in a row (its 2nd while its mean reaches `protect`), once the mean leg probability of its
detections reaches the detector's `confirm` level (what 75 % of held-out labelled legs reach), or
only its leg threshold while it strides (its legs' spread changes 0.07 m within 2 s): a gait tells a
person whom a laser the detector was not trained on scores low. Legs on static cells are dropped
before pairing, so clutter confirmed early loses its detections once its cells turn static and dies.
A tentative track below the `protect` level (what half the labelled legs reach) is not confirmed
until it walks (moves 0.3 m, or changes its legs' spread with a stride, within 2 s): still, it is
furniture or a person the grid would hold static within 1.5 s anyway, and a moving robot's grid can
miss a thin post for longer. A confirmed track that walks is kept through the scans where the
classifier doubts the legs (`robot_logs.tracking`), a confirmed track coasts through 0.5 s without a
detection at any scan rate, and a track that walks or reaches `protect` keeps its cells out of the
grid, so neither a person standing still nor one walking at a steady distance ahead of a moving
robot turns into static world. Tracking in a frame that moves with the robot, `process` may be told
where that frame is (`motion`, from odometry or scan matching): walking is judged there and the grid
kept there, so a post the robot drives past neither walks nor escapes the grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.detection import Detections, DetectorConfig, detect, scan_points
from robot_logs.frames import Pose2D
from robot_logs.leg_classifier import LegClassifier, shipped_detector
from robot_logs.records import Scan
from robot_logs.static_world import StaticWorld, StaticWorldConfig
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


#: Seconds a confirmed track of the learned setup lives without a hit (5 scans at 10 Hz), at any scan rate.
LEARNED_COAST_S = 0.5


#: Seconds after its last detection a walking confirmed track of the learned setup takes unsure ones.
UNSURE_S = 0.5

#: Hits that confirm a track of the learned setup whose mean leg probability reaches `protect` (3 otherwise).
SURE_HITS = 2

#: Change of the distance between a track's two legs (m) that the learned setup takes for a stride.
GAIT_SPREAD = 0.07

#: Misses in a row that drop a tentative track of the learned setup: it outlives one scan without
#: its legs, as the classifier loses a person close to the laser now and then.
TENTATIVE_MISSES = 2


def still_wait(world: StaticWorldConfig) -> float:
    """How long a still, unsure track waits: half a second more than a cell needs to turn static,
    so the grid has seen it static before the track could be confirmed."""
    return world.min_duration + 0.5


class PersonTracker:
    """Detector plus tracker over consecutive scans, in one output frame.

    Args:
        detector: segmentation and pairing settings.
        tracker: Kalman filter and track-management settings.
        classifier: the learned leg classifier; None tells legs by width alone.
        static_world: grid settings for static-world rejection; None rejects nothing.
    """

    def __init__(
        self,
        detector: DetectorConfig = DetectorConfig(),
        tracker: TrackerConfig = TrackerConfig(),
        classifier: LegClassifier | None = None,
        static_world: StaticWorldConfig | None = None,
    ) -> None:
        self.detector = detector
        self.classifier = classifier
        self.tracker = Tracker(tracker)
        self.world = StaticWorld(static_world) if static_world is not None else None

    @classmethod
    def learned(cls, classifier: LegClassifier | None = None, detector: DetectorConfig = DetectorConfig()) -> PersonTracker:
        """The setup for real scans: a leg classifier (default: the shipped one), static-world
        rejection, and tracks confirmed and protected at the classifier's levels (a striding track at its
        threshold); a still track under the protecting level is not confirmed until it walks."""
        classifier = classifier if classifier is not None else shipped_detector()
        world = StaticWorldConfig(protect_confidence=classifier.protect)
        return cls(
            detector,
            TrackerConfig(confirm_confidence=classifier.confirm, striding_confidence=classifier.threshold,
                          still_wait=math.inf, sure_confidence=classifier.protect, sure_hits=SURE_HITS,
                          death_time=LEARNED_COAST_S, gait_spread=GAIT_SPREAD, unsure_time=UNSURE_S,
                          tentative_misses=TENTATIVE_MISSES),
            classifier,
            world,
        )

    @classmethod
    def rules_with_grid(cls, detector: DetectorConfig = DetectorConfig()) -> PersonTracker:
        """The setup for simulated scans among furniture: legs by width; static-world rejection
        with cells static after 1 s, or after 0.3 s when hit in 3 scans and never seen free (a wall
        cell; a walker's cells are soon seen free); still tracks waiting 1.5 s; a tentative track
        surviving one missed scan; no track born within 0.6 m of a confirmed one (that person's
        other leg); and tracks kept 15 scans (1.5 s at 10 Hz) through misses but reported only one
        scan into them. Width rules give no confidence, so no track is protected: a person who
        stands still is taken for furniture."""
        world = StaticWorldConfig(min_duration=1.0, protect_confidence=math.inf, protect_walkers=False, never_free_hits=3,
                                  never_free_duration=0.3)
        tracker = TrackerConfig(still_wait=still_wait(world), sure_confidence=math.inf, death_misses=15,
                                report_misses=1, tentative_misses=2, birth_clearance=0.6)
        return cls(detector, tracker, None, world)

    def process(self, scan: Scan, sensor_pose: Pose2D = Pose2D(), frame: str | None = None, scan_index: int = 0,
                motion: Pose2D | None = None) -> ScanResult:
        """Detect people in `scan`, move them into the output frame, update the tracks.

        Args:
            scan: the scan.
            sensor_pose: pose of the scan's frame in the output frame at the scan time
                (identity: track in the scan's own frame).
            frame: output frame name; defaults to the scan's frame.
            scan_index: position of the scan on its topic, carried into the result.
            motion: where the output frame is in a frame fixed to the world, when it moves with
                the robot (the scan's own frame on a moving robot, placed by odometry or
                `ScanOdometry`): tracks are judged walking by their motion there, and the
                static-world grid is kept there, so furniture that the robot drives past is not
                taken for a walker.
        """
        world = self.world
        placed = sensor_pose if motion is None else motion.compose(sensor_pose)  # the sensor in the grid's frame
        reject = None if world is None else (lambda legs: world.is_static(placed.apply(legs)))
        found = detect(scan, self.detector, self.classifier, reject)
        moved = Detections(sensor_pose.apply(found.legs), sensor_pose.apply(found.people), found.confidence, found.spread,
                           sensor_pose.apply(found.unsure))
        tracks = self.tracker.step(scan.stamp, moved.people, moved.confidence, spread=found.spread, unsure=moved.unsure,
                                   motion=motion, sensor=sensor_pose)
        if world is not None:
            sure = world.config.protect_confidence
            walkers = world.config.protect_walkers
            people = [self.tracker.place(t) for t in self.tracker.tracks
                      if t.confirmed and (t.confidence_sum >= sure * t.hits or walkers and self.tracker.walking(t))]
            world.update(scan, placed.apply(scan_points(scan)), placed, np.array(people).reshape(-1, 2))
        return ScanResult(scan_index, scan.stamp_ns, frame or scan.frame_id, sensor_pose, moved, tracks)
