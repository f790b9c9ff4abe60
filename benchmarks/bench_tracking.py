"""Benchmark of lidar person tracking (issues 8, 20, 37 and 42): speed, CLEAR-MOT on simulated scans
with and without furniture clutter, a person followed by a moving robot, and the learned leg
detector against the labelled legs.

    python benchmarks/bench_tracking.py [--seeds 10] [--duration 60] [--following-seeds 3] [--detector FILE]

Real logs: the learned setup tracking the labelled bags' walkers inside their labelled sector, each
bag by a detector trained without it (the figure that predicts a new log of their laser) and by the
shipped one, which learned them. Following: a walker 1 to 3 m ahead of a robot driving an outdoor
path for 60 s, seen by a narrow lidar like the person-following benchmark log's, tracked by the
learned setup at 10 and 40 Hz with odometry (odometry frame) and without (laser frame): recall,
misses, id switches, MOTP (goals: misses at most 1.7 % of person-scans, MOTP at most 0.09 m).

Speed: detection plus tracking of pre-simulated 40 Hz scans with 6 walking people among furniture,
one thread (goal: 200 scans/s, five times a 40 Hz lidar); scan-matching odometry
(robot_logs.scan_odometry) along a moving robot's path among furniture and people. Quality:
CLEAR-MOT by Leigh et al.'s protocol (robot_logs.clear_mot; match radius 0.5 m here) on held-out
seeds with 6 walkers, and false positives per scan (goals in clutter: MOTA >= 0.9, under 0.1 per
scan). As in a labelled log, only people the lidar sees (at least 3 beams on their legs) are ground
truth; a track on someone hidden is neither a match nor a false positive. Each row is also scored
within 5 m of the lidar, the range within which the bags label legs. The learned setup runs on the
simulator's default legs and lidar and on those fitted to the labelled bags (`BodyModel.fitted()`,
`LidarSpec.fitted()`), with 6 walkers and with one, and with the lidar driving a loop among the
furniture, tracked in the room's frame as odometry places it and in the laser's own frame as
`trials log track` tracks a log (odometry, or scan matching, tells how it moves). The standing log's
passers-by (legs by background subtraction) are tracked by a detector trained without that log, the
figure that predicts tracking on a new laser and place, and the log recorded with nobody present by
a driving robot, where every track is false. Leg precision and recall cross-validated by bag, for
the classifier alone and followed by static-world rejection, over every log, the labelled bags and
the standing log, come from the shipped detector's training record (the protocol is in
docs/leg_detector.md), with the held-out calls on the labelled bags inside their labelled sector and
outside it, and what the shipped detector makes of the simulator's legs, default and fitted, and of
the fitted legs seen by the following log's narrow lidar, is printed beside it; legs against the
hand labels count over whole scans and inside the labelled sector. `--detector` measures another
detector file in the shipped one's place.
"""

from __future__ import annotations

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")  # one core, before numpy loads its BLAS

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for tests.support

import numpy as np

from robot_logs.background_labels import Background, background_labels
from robot_logs.clear_mot import ClearMot, Identities, ScoredScan
from robot_logs.clutter import furnished_room
from robot_logs.convert import to_scan
from robot_logs.detection import DetectorConfig, detect, people_of
from robot_logs.frames import Pose2D
from robot_logs.leg_classifier import LegClassifier, shipped_detector
from robot_logs.leg_training import (
    TrainingSettings,
    candidates,
    collect,
    held_out_probability,
    stage_threshold,
    train,
    validate,
)
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.log_tracking import track_log
from robot_logs.pipeline import PersonTracker
from robot_logs.reader import LogReader
from robot_logs.records import Scan
from robot_logs.scan_odometry import ScanOdometry
from robot_logs.segment_features import FEATURE_NAMES, SHAPE_NAMES
from robot_logs.topics import TopicNames
from tests.support.crowd import walking_crowd
from tests.support.evaluation import labelled_scans, leg_features, score_detections, simulated_legs
from tests.support.following import FOLLOWING_LIDAR, follow

SAMPLES = Path(__file__).resolve().parents[1] / "tests" / "data" / "robot_logs"
LABELLED = [SAMPLES / "legs_labelled_ros1.bag", *sorted((SAMPLES / "leg_training").glob("positive_*.bag"))]
#: The standing sample log (another laser and place) and the log recorded with nobody present.
STANDING, EMPTY = SAMPLES / "stationary_ros1.bag", SAMPLES / "leg_training" / "negative_2.bag"
PEOPLE = 6
#: Beams that must fall on a person's legs for them to count as ground truth (a segment's minimum).
VISIBLE_BEAMS = 3
#: The labelled bags mark legs within 5 m of the lidar only (farther legs are learned from copies taken
#: for twice as far): each row is also scored on the people within this range (m).
LABELLED_RANGE = 5.0
#: The simulated lidar and legs: the defaults, or fitted to the labelled bags (robot_logs.leg_fit).
SENSORS = {"default": (LidarSpec(), BodyModel()), "fitted": (LidarSpec.fitted(), BodyModel.fitted())}


#: The moving robot's loop through the room: centre (m), radius (m) and seconds a lap (0.31 m/s).
LOOP_CENTRE, LOOP_RADIUS, LOOP_PERIOD = (4.5, 0.0), 1.5, 30.0


def lidar_poses(times: np.ndarray, moving: bool) -> list[Pose2D]:
    """The lidar's pose at each time: standing at the origin, or driving the loop facing along it."""
    if not moving:
        return [Pose2D()] * len(times)
    angle = 2.0 * np.pi * times / LOOP_PERIOD
    x, y = LOOP_CENTRE[0] + LOOP_RADIUS * np.sin(angle), LOOP_CENTRE[1] - LOOP_RADIUS * np.cos(angle)
    return [Pose2D(float(a), float(b), float(h)) for a, b, h in zip(x, y, angle)]


def simulate(seed: int, duration: float, shape: str, clutter: bool, rate_hz: float = 10.0, sensor: str = "default",
             people: int = PEOPLE, moving: bool = False):
    """Ground truth, the lidar's poses, its scans and (T, N) beams on each person of one simulated
    walk, seen from a lidar at the origin or driving a loop through the room (`moving`)."""
    crowd = walking_crowd(people, duration, rate_hz, seed=seed)
    room = furnished_room(seed) if clutter else None
    spec, body = SENSORS[sensor]
    lidar = LidarSimulator(
        spec, replace(body, shape=shape), seed=seed,
        walls=None if room is None else room.walls, posts=None if room is None else (room.centres, room.radii),
    )
    poses = lidar_poses(crowd.times, moving)
    seen = [lidar.observe(t, pose, p, v) for t, pose, p, v in zip(crowd.times, poses, crowd.positions, crowd.velocities)]
    return crowd, poses, [scan for scan, _ in seen], np.array([beams for _, beams in seen]).reshape(-1, people)


def make_tracker(setup: str, classifier: LegClassifier | None = None) -> PersonTracker:
    """"rules": width rules alone; "rules+grid": `PersonTracker.rules_with_grid()`, the setup for
    simulated clutter; "learned": the setup of `trials log track`, with `classifier` (default: the shipped one)."""
    if setup == "learned":
        return PersonTracker.learned(classifier)
    if setup == "rules+grid":
        return PersonTracker.rules_with_grid()
    return PersonTracker()


def speed(duration: float, setup: str, classifier: LegClassifier | None = None) -> float:
    """Scans per CPU second of detection plus tracking in clutter (best of three passes); CPU time
    of this one-thread process, so other work on a shared machine does not count against it."""
    _, _, scans, _ = simulate(seed=1, duration=duration, shape="legs", clutter=True, rate_hz=40.0)
    best = 0.0
    for _ in range(3):
        tracker = make_tracker(setup, classifier)
        start = time.process_time()
        for scan in scans:
            tracker.process(scan)
        best = max(best, len(scans) / (time.process_time() - start))
    return best


def odometry_speed(duration: float) -> tuple[float, float]:
    """Scans per CPU second of scan-matching odometry (best of three passes) along a weaving path
    through furniture at 0.4 m/s with 6 people walking, 10 Hz, and the largest position error (m)."""
    crowd = walking_crowd(PEOPLE, duration, 10.0, seed=1)
    room = furnished_room(1)
    lidar = LidarSimulator(LidarSpec(), seed=1, walls=room.walls, posts=(room.centres, room.radii))
    path = [Pose2D(0.5 + 0.4 * t, 0.5 * np.sin(0.2 * t), 0.2 * np.sin(0.3 * t)) for t in crowd.times]
    scans = [lidar.scan(t, pose, p, v) for t, pose, p, v in zip(crowd.times, path, crowd.positions, crowd.velocities)]
    best, error = 0.0, 0.0
    for _ in range(3):
        odometry = ScanOdometry()
        start = time.process_time()
        poses = [odometry.update(scan) for scan in scans]
        best = max(best, len(scans) / (time.process_time() - start))
    for truth, pose in zip(path, poses):
        relative = path[0].inverse().compose(truth)
        error = max(error, np.inf if pose is None else float(np.hypot(pose.x - relative.x, pose.y - relative.y)))
    return best, error


#: Seconds at the start of each walk left out of the "settled" figures: the static-world grid
#: knows nothing until its cells have 1.5 s of history, and clutter reported meanwhile dies 0.5 s later.
SETTLE_S = 5.0


def quality(seeds: range, duration: float, shape: str, clutter: bool, setup: str, sensor: str = "default",
            people: int = PEOPLE, classifier: LegClassifier | None = None,
            moving: bool = False, laser_frame: str | None = None) -> tuple[ClearMot, ClearMot, ClearMot, ClearMot]:
    """CLEAR-MOT summed over seeds: over every scan, over the scans after SETTLE_S, over every
    scan with every person as ground truth, seen or not (hidden ones count as misses), and over
    every scan with the people seen within LABELLED_RANGE of the lidar as ground truth (the others
    hidden). A `moving` lidar is tracked in the room's frame, as odometry would place it, or in its
    own, as `trials log track` tracks a log, told how it moves by `laser_frame`: "odometry" (the
    log's, here the true path) or "scan matching" (a log without odometry)."""
    totals = ClearMot(), ClearMot(), ClearMot(), ClearMot()
    for seed in seeds:
        crowd, poses, scans, beams = simulate(seed, duration, shape, clutter, sensor=sensor, people=people, moving=moving)
        tracker = make_tracker(setup, classifier)
        scores = ClearMot(), ClearMot(), ClearMot(), ClearMot()
        matching = ScanOdometry() if laser_frame == "scan matching" else None
        for when, walkers, pose, scan, on in zip(crowd.times, crowd.positions, poses, scans, beams):
            if laser_frame is None:
                tracks = tracker.process(scan, pose).tracks
            else:
                if matching is not None:
                    matching.update(scan)
                motion = poses[0].inverse().compose(pose) if matching is None else matching.pose
                tracks = tracker.process(scan, motion=motion).tracks
                walkers, pose = pose.inverse().apply(walkers), Pose2D()
            ids, where = np.array([t.track_id for t in tracks], dtype=int), np.array([[t.x, t.y] for t in tracks]).reshape(-1, 2)
            seen = on >= VISIBLE_BEAMS
            visible = ScoredScan(np.flatnonzero(seen), walkers[seen], ids, where, hidden=walkers[~seen])
            for score in scores[: 1 + (when >= SETTLE_S)]:
                score.update(visible, radius=0.5)
            scores[2].update(ScoredScan(np.arange(people), walkers, ids, where), radius=0.5)
            near = seen & (np.hypot(walkers[:, 0] - pose.x, walkers[:, 1] - pose.y) <= LABELLED_RANGE)
            scores[3].update(ScoredScan(np.flatnonzero(near), walkers[near], ids, where, hidden=walkers[~near]), radius=0.5)
        for total, score in zip(totals, scores):
            total.add(score)
    return totals


#: The simulated legs' lidars: the tracking rows' two, and the following log's narrow one with the fitted legs.
LEG_SENSORS = {**SENSORS, "following": (FOLLOWING_LIDAR, BodyModel.fitted())}

#: Column of a segment's range in its features.
DISTANCE = FEATURE_NAMES.index("distance")


def simulated_leg_features(sensor: str, people: int, clutter: bool = False, seconds: float = 20.0) -> np.ndarray:
    """Features of the simulated legs' segments (the candidates matched to a leg, as the training
    protocol matches labels) over `seconds` of walkers, seed 100."""
    spec, body = LEG_SENSORS[sensor]
    room = furnished_room(100) if clutter else None
    lidar = LidarSimulator(spec, body, seed=100, walls=None if room is None else room.walls,
                           posts=None if room is None else (room.centres, room.radii))
    return leg_features(simulated_legs(lidar, walking_crowd(people, seconds, 10.0, seed=100)))


def simulated_leg_recall(classifier: LegClassifier, sensor: str, people: int) -> str:
    """The share of the simulated legs' segments in open space at or above the classifier's threshold
    and its confirming level, over every range, within LABELLED_RANGE and beyond it."""
    features = simulated_leg_features(sensor, people)
    probability = classifier.probability(features)
    near = probability[features[:, DISTANCE] <= LABELLED_RANGE]
    far = probability[features[:, DISTANCE] > LABELLED_RANGE]
    return (f"{sensor} lidar and legs, {people} walker{'s' * (people > 1)}: {len(probability)} leg segments, "
            f"{np.mean(probability >= classifier.threshold):.3f} at or above the threshold; within {LABELLED_RANGE:.0f} m "
            f"{len(near)}, {np.mean(near >= classifier.threshold):.3f} at or above the threshold, "
            f"{np.mean(near >= classifier.confirm):.3f} at or above the confirming level {classifier.confirm:.3f}; "
            f"beyond, {len(far)}, {np.mean(far >= classifier.threshold):.3f} at or above the threshold")


def swapped_features(classifier: LegClassifier, bag_legs: np.ndarray, people: int, clutter: bool) -> str:
    """The share of fitted simulated legs within LABELLED_RANGE at or above the threshold, as they are
    and with their context features, or their shape features (their range kept), taken from a bag leg
    at about the same range: which of the two keeps the detector from the simulated legs."""
    legs = simulated_leg_features("fitted", people, clutter)
    legs = legs[legs[:, DISTANCE] <= LABELLED_RANGE]
    by_range = np.argsort(bag_legs[:, DISTANCE])
    nearest = np.searchsorted(bag_legs[by_range, DISTANCE], legs[:, DISTANCE])
    jitter = np.random.default_rng(0).integers(-20, 21, len(legs))  # one of the ~40 bag legs nearest in range
    bag = bag_legs[by_range[np.clip(nearest + jitter, 0, len(bag_legs) - 1)]]
    context, shape = legs.copy(), legs.copy()
    context[:, len(SHAPE_NAMES):] = bag[:, len(SHAPE_NAMES):]
    shape[:, :len(SHAPE_NAMES)] = bag[:, :len(SHAPE_NAMES)]
    shape[:, DISTANCE] = legs[:, DISTANCE]
    share = [np.mean(classifier.probability(f) >= classifier.threshold) for f in (legs, context, shape)]
    return (f"fitted, {people} walker{'s' * (people > 1)} {'among furniture' if clutter else 'in open space'}, "
            f"{len(legs)} leg segments within {LABELLED_RANGE:.0f} m: {share[0]:.3f} at or above the threshold; "
            f"with a bag leg's context features {share[1]:.3f}, with its shape features {share[2]:.3f}")


#: The three scanners of the log recorded with nobody present, by a robot driving 40 m in 58 s.
EMPTY_SCANS = ("/left_scan", "/rear_scan", "/right_scan")


def nobody_tracking(classifier: LegClassifier) -> dict[str, tuple[int, int]]:
    """(track rows, tracks) of the learned setup with `classifier` over the log recorded with
    nobody present, every scanner in turn, in the laser's frame and in the frame scan odometry
    places the scans in: every track is false."""
    found = {}
    for frame, odometry in (("laser frame", "log"), ("scan odometry frame", "scan")):
        rows = tracks = 0
        for topic in EMPTY_SCANS:
            table = track_log(EMPTY, "sensor" if odometry == "log" else "odom", TopicNames(scan=topic),
                              PersonTracker.learned(classifier), odometry=odometry)
            rows, tracks = rows + len(table.rows), tracks + len({row.track_id for row in table.rows})
        found[frame] = (rows, tracks)
    return found


#: The sector the labelled bags' labelling rule covered (degrees either side of the axis, m): nobody
#: outside it is labelled, so scores that count unlabelled calls as false are also given inside it.
LABELLED_SECTOR, LABELLED_REACH = 15.0, 5.0


def inside(points: np.ndarray) -> np.ndarray:
    """(N,) which laser-frame points lie inside the labelled sector."""
    bearing = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
    return (np.abs(bearing) <= LABELLED_SECTOR) & (np.hypot(*points.T) <= LABELLED_REACH)


def bag_labels(path: Path) -> list[tuple[Scan, np.ndarray]]:
    """A labelled bag's scans, each with its labelled legs."""
    with LogReader(path) as log:
        return [(scan, label.points) for scan, label in labelled_scans(log)]


def labelled_legs(detector: LegClassifier) -> str:
    """Legs detected by width rules and by `detector` against legs_labelled_ros1.bag's labels, over
    the whole scan and inside the labelled sector."""
    with LogReader(SAMPLES / "legs_labelled_ros1.bag") as log:
        pairs = labelled_scans(log)
    lines = []
    for name, classifier in (("width rules", None), ("detector (trained on this bag too)", detector)):
        found = [(detect(scan, classifier=classifier).legs, label.points) for scan, label in pairs]
        for where, kept in (("whole scans", found), ("inside the labelled sector", [(legs[inside(legs)], labels) for legs, labels in found])):
            score = score_detections(kept, 0.15)
            lines.append(f"  {name}, {where}: recall {score.recall:.3f}, precision {score.precision:.3f} within 0.15 m "
                         f"({score.matched} matched, {score.missed} missed, {score.spurious} unlabelled) over {len(pairs)} scans")
    return "\n".join(lines)


def labelled_calls_by_sector() -> str:
    """The shipped training's held-out stage calls on the labelled bags (by log, at the threshold
    that keeps 0.9 of their legs, as `validate` sets it) inside the labelled sector and outside
    it, where the protocol counts every call on something unlabelled as false; the unlabelled
    calls outside it by where they stand: beyond the labels' reach, or before each bag's
    background (someone passing the standing laser, by `robot_logs.background_labels`' rule) or on it."""
    data = collect(LABELLED, [EMPTY], standing=[STANDING])
    probability = held_out_probability(data, "log")
    labelled = ~data.augmented & (data.log < data.labelled_logs)
    threshold = stage_threshold(data.is_leg[labelled], probability[labelled], data.static[labelled], TrainingSettings().recall)
    called = labelled & ~data.ignored & ~data.static & (probability >= threshold)
    sector = inside(data.centroids)
    parts = []
    for name, where in (("inside the labelled sector", sector), ("outside it", ~sector)):
        legs, other = int((called & where & data.is_leg).sum()), int((called & where & ~data.is_leg).sum())
        parts.append(f"{name} {legs + other} calls, {legs} on labelled legs (precision {legs / max(legs + other, 1):.3f})")
    before = np.zeros(len(called), dtype=bool)
    for index, bag in enumerate(LABELLED):
        log = data.log == index
        before[log] = Background.of([scan for scan, _ in bag_labels(bag)], str(bag)).in_front(data.centroids[log])
    unlabelled = called & ~sector & ~data.is_leg
    far = np.hypot(*data.centroids.T) > LABELLED_REACH
    near = unlabelled & ~far
    parts.append(f"of its unlabelled calls {int((unlabelled & far).sum())} beyond {LABELLED_REACH:.0f} m, "
                 f"{int((near & before).sum())} nearer before the bag's background, {int((near & ~before).sum())} on it")
    return "; ".join(parts)


def following(seeds: range, classifier: LegClassifier | None = None) -> list[str]:
    """The person-following scenario (tests.support.following): a walker 1 to 3 m ahead of a robot
    driving 0.9 m/s for 60 s, the learned setup at 10 and 40 Hz, in the odometry frame and in
    the laser's own frame (no odometry), summed over seeds."""
    lines = []
    for rate in (10.0, 40.0):
        for odometry in (True, False):
            total = ClearMot()
            for seed in seeds:
                total.add(follow(rate, odometry, seed, classifier)[0])
            frame = "odometry frame" if odometry else "laser frame, no odometry"
            lines.append(f"  {rate:.0f} Hz, {frame}, {len(seeds)} seeds x 60 s: recall {total.recall:.3f}, misses "
                         f"{total.misses} of {total.objects} person-scans ({total.misses / total.objects:.1%}, goal <= 1.7 %), "
                         f"id switches {total.id_switches}, MOTP {total.motp:.3f} m (goal <= 0.09), false positives "
                         f"{total.false_positives}, MOTA {total.mota:.3f}")
    return lines


def detector_without(held_out: Path) -> LegClassifier:
    """The shipped detector's training (`trials log train-detector`) without one of its logs, so
    that log is one the detector never saw."""
    labelled = [bag for bag in LABELLED if bag != held_out]
    data = collect(labelled, [EMPTY], standing=[STANDING] if held_out != STANDING else [])
    levels, validation, _ = validate(data)
    return train(data, levels, validation=validation)


def standing_tracking(classifier: LegClassifier) -> ClearMot:
    """CLEAR-MOT (0.75 m) of the learned setup with `classifier` on the standing log against its
    passers-by: the leg-wide segments in front of the background (`robot_logs.background_labels`),
    paired as the detector pairs legs, with identities by continuity (`Identities`)."""
    with LogReader(STANDING) as log:
        scans = [to_scan(m.data, m.record_ns, f"scan of {STANDING}") for m in log.messages({"/scan"})]
    background, config = Background.of(scans, str(STANDING)), DetectorConfig()
    tracker, score, identities = PersonTracker.learned(classifier), ClearMot(), Identities()
    for scan in scans:
        segments, mask = candidates(scan, config)
        legs = segments.centroids[mask][background_labels(background, segments, mask, config.leg_width)[0]]
        people = people_of(legs, config.pair_distance)
        tracks = tracker.process(scan).tracks
        where = np.array([[t.x, t.y] for t in tracks]).reshape(-1, 2)
        score.update(ScoredScan(identities(people), people, np.array([t.track_id for t in tracks], dtype=int), where))
    return score


def labelled_tracking(classifier: Callable[[Path], LegClassifier]) -> ClearMot:
    """CLEAR-MOT (0.75 m) of `trials log track`'s setup on the six labelled bags, in the laser's
    frame, each with the detector `classifier` gives for it: a person is a pair of labelled legs
    within 0.6 m (their midpoint) or a lone labelled leg, identified by continuity (`Identities`:
    the labels carry no ids), and people and tracks count inside the labelled sector (15 degrees
    either side of the axis, within 5 m), which the labelling rule kept clear of anyone else."""
    total = ClearMot()
    for bag in LABELLED:
        tracker, score, identities = PersonTracker.learned(classifier(bag)), ClearMot(), Identities()
        for scan, legs in bag_labels(bag):
            people = people_of(legs, DetectorConfig().pair_distance)
            people = people[inside(people)]
            tracks = tracker.process(scan).tracks
            where = np.array([[t.x, t.y] for t in tracks]).reshape(-1, 2)
            ids = np.array([t.track_id for t in tracks], dtype=int)
            score.update(ScoredScan(identities(people), people, ids[inside(where)], where[inside(where)]))
        total.add(score)
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="held-out seeds for CLEAR-MOT (100, 101, ...)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds simulated per seed")
    parser.add_argument("--following-seeds", type=int, default=3, help="seeds of the following scenario (0, 1, ...)")
    parser.add_argument("--detector", metavar="FILE", help="a leg detector file to measure (default: the shipped one)")
    args = parser.parse_args()
    detector = LegClassifier.load(args.detector) if args.detector else shipped_detector()
    print(f"person following (a lidar of {FOLLOWING_LIDAR.beams} beams over 86 deg to "
          f"{FOLLOWING_LIDAR.range_max:.1f} m, fitted legs, match radius 0.75 m):")
    print("\n".join(following(range(args.following_seeds), detector)))
    for sensor, (spec, _) in SENSORS.items():
        print(f"{sensor} lidar: {spec.beams} beams over 270 deg at {np.degrees(spec.angle_increment):.2f} deg, "
              f"range noise {spec.range_noise_std * 1000:.0f} mm")
    for setup in ("rules", "rules+grid", "learned"):
        print(f"speed, {setup}, in clutter: {speed(min(args.duration, 30.0), setup, detector):.0f} scans/s for detection + "
              "tracking on one core (goal >= 200)")
    rate, error = odometry_speed(min(args.duration, 15.0))
    print(f"scan odometry (robot_logs.scan_odometry) along {min(args.duration, 15.0):.0f} s of a moving robot's path among "
          f"furniture and people: {rate:.0f} scans/s on one core, largest position error {error:.3f} m")
    seeds = range(100, 100 + args.seeds)
    rows = [("legs", False, "rules", "default", PEOPLE, False), ("disc", False, "rules", "default", PEOPLE, False),
            ("legs", True, "rules", "default", PEOPLE, False), ("legs", True, "rules+grid", "default", PEOPLE, False)]
    rows += [("legs", clutter, "learned", sensor, people, False) for people in (PEOPLE, 1) for clutter in (False, True)
             for sensor in SENSORS]
    rows = [(*row, None) for row in rows] + [("legs", True, "learned", "fitted", PEOPLE, True, laser)
                                             for laser in (None, "odometry", "scan matching")]
    for shape, clutter, setup, sensor, people, moving, laser in rows:
        q, settled, everyone, near = quality(seeds, args.duration, shape, clutter, setup, sensor, people, detector, moving,
                                             laser)
        frame = f"laser frame, moved by {laser}" if laser else "room frame"
        where = ("among furniture" if clutter else "open space") + (f", lidar driving a loop ({frame})" if moving else "")
        print(f"CLEAR-MOT, {setup}, {shape} model, {sensor} lidar and legs, {people} walker{'s' * (people > 1)}, {where}, "
              f"{len(seeds)} seeds x {args.duration:.0f} s at 10 Hz: "
              f"MOTA {q.mota:.3f} (goal >= 0.9), MOTP {q.motp:.3f} m, false positives {q.false_positives} "
              f"({q.false_positives / q.scans:.3f} per scan, goal < 0.1), misses {q.misses} of {q.objects}, "
              f"id switches {q.id_switches}; after the first {SETTLE_S:.0f} s: MOTA {settled.mota:.3f}, "
              f"{settled.false_positives / settled.scans:.3f} false positives per scan; every person as ground truth, "
              f"seen or not: MOTA {everyone.mota:.3f}, {everyone.false_positives / everyone.scans:.3f} per scan; "
              f"people within {LABELLED_RANGE:.0f} m: MOTA {near.mota:.3f}, misses {near.misses} of {near.objects}, "
              f"false positives {near.false_positives}, id switches {near.id_switches}")
    print("the detector on simulated leg segments (seed 100, 20 s, open space):")
    for people in (PEOPLE, 1):
        for sensor in LEG_SENSORS:
            print(f"  {simulated_leg_recall(detector, sensor, people)}")
    bag_legs = leg_features(pair for bag in LABELLED for pair in bag_labels(bag))
    print(f"the same with features swapped for those of the labelled bags' {len(bag_legs)} legs (seed 100, 20 s):")
    for people, clutter in ((PEOPLE, False), (1, True), (PEOPLE, True)):
        print(f"  {swapped_features(detector, bag_legs, people, clutter)}")
    record = detector.record
    print(f"the detector: threshold {record['threshold']:.3f}, trained on {record['segments']} segments "
          f"({record['legs']} legs) of {len(record['logs'])} logs")
    for design in ("logs", "time blocks"):
        scopes = [("", "every log"), (", labelled logs", "the labelled logs"), (", standing logs", "the standing log")]
        for scope, logs in (scope for scope in scopes if f"{design}{scope[0]}" in record["cross_validation"]):
            for stage, detection in (("", "classifier alone"), (", static world", "classifier + static world")):
                for rule, scored in (("", "the documented protocol"), (", strict", "every unlabelled segment a negative")):
                    figures = record["cross_validation"][f"{design}{scope}{stage}{rule}"]
                    goal = " (goal: precision >= 0.8 at recall >= 0.9)" if design == "logs" and scope == ", labelled logs" and stage else ""
                    print(f"  cross-validated by {design}, segments of {logs}, {detection} ({scored}): leg precision "
                          f"{figures['precision']:.3f}, recall {figures['recall']:.3f}{goal}")
    print(f"  by logs, labelled logs, classifier + static world, by where the calls fall: {labelled_calls_by_sector()}")
    print(f"tracking the labelled bags' walkers (learned setup, laser frame, within {LABELLED_SECTOR:.0f} deg and "
          f"{LABELLED_REACH:.0f} m, match radius 0.75 m):")
    for name, classifier in (("each bag by a detector trained without it (held out)", detector_without),
                             ("the detector (trained on them too)", lambda bag: detector)):
        real = labelled_tracking(classifier)
        print(f"  {name}: MOTA {real.mota:.3f}, recall {real.recall:.3f}, misses {real.misses} of {real.objects}, "
              f"false positives {real.false_positives}, id switches {real.id_switches}, MOTP {real.motp:.3f} m")
    print("tracking the standing log's passers-by (legs by background subtraction, match radius 0.75 m):")
    for name, classifier in (("detector trained without it (held out)", detector_without(STANDING)),
                             ("the detector (trained on it too)", detector)):
        score = standing_tracking(classifier)
        print(f"  {name}: recall {score.recall:.3f}, misses {score.misses} of {score.objects}, false positives "
              f"{score.false_positives}, id switches {score.id_switches}, MOTP {score.motp:.3f} m, MOTA {score.mota:.3f}")
    with LogReader(EMPTY) as log:
        scans = sum(1 for _ in log.messages(set(EMPTY_SCANS)))
    print(f"tracking the log recorded with nobody present by a moving robot ({len(EMPTY_SCANS)} scanners, {scans} scans; "
          "every track false):")
    for frame, (rows, tracks) in nobody_tracking(detector).items():
        print(f"  {frame}: {tracks} tracks, {rows} track rows ({rows / scans:.3f} per scan)")
    print("detection vs hand-labelled legs (real scans):")
    print(labelled_legs(detector))


if __name__ == "__main__":
    main()
