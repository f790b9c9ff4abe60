"""Detection and tracking: track life cycle, gating, ids, frames, and CLEAR-MOT on simulated walks."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robot_logs.detection import detect, pair_legs
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.log_tracking import track_log
from robot_logs.pipeline import PersonTracker
from robot_logs.records import Odometry, Transform
from robot_logs.tracking import Tracker, TrackerConfig
from tests.support.bag_writer import BagWriter
from tests.support.crowd import walking_crowd
from tests.support.evaluation import clear_mot


def test_a_track_is_born_after_three_hits_and_dies_after_five_misses() -> None:
    tracker = Tracker(TrackerConfig(birth_hits=3, death_misses=5))
    person = np.array([[2.0, 1.0]])
    assert tracker.step(0.0, person) == []
    assert tracker.step(0.1, person) == []
    confirmed = tracker.step(0.2, person)
    assert [t.track_id for t in confirmed] == [1]
    coasting = [len(tracker.step(0.3 + 0.1 * k, np.zeros((0, 2)))) for k in range(5)]
    assert coasting == [1, 1, 1, 1, 0]  # reported while coasting, deleted at the fifth miss


def test_a_person_the_detector_is_sure_of_is_confirmed_at_the_second_hit() -> None:
    """`sure_hits`: two people, one scored 0.95 (over `sure_confidence`), one 0.7 (over the confirming
    level only); the sure one gets its id a scan earlier, and the other still needs `birth_hits`."""
    config = TrackerConfig(birth_hits=3, sure_hits=2, confirm_confidence=0.6, sure_confidence=0.9)
    tracker, people = Tracker(config), np.array([[2.0, 1.0], [2.0, -1.0]])
    scores = np.array([0.95, 0.7])
    confirmed = [[(round(s.y), s.track_id) for s in tracker.step(0.1 * k, people, scores)] for k in range(3)]
    assert confirmed == [[], [(1, 1)], [(1, 1), (-1, 2)]]
    without = Tracker(replace(config, sure_hits=None))
    assert [len(without.step(0.1 * k, people, scores)) for k in range(3)] == [0, 0, 2]


def test_a_tentative_track_dies_at_its_first_miss() -> None:
    tracker = Tracker()
    tracker.step(0.0, np.array([[2.0, 1.0]]))
    tracker.step(0.1, np.array([[2.0, 1.0]]))
    tracker.step(0.2, np.zeros((0, 2)))
    assert tracker.tracks == []


def test_ids_are_stable_and_never_reused() -> None:
    tracker = Tracker(TrackerConfig(death_misses=2))
    for k in range(5):  # two people walking in parallel, 2 m apart
        t = 0.1 * k
        states = tracker.step(t, np.array([[1.0 + t, 0.0], [1.0 + t, 2.0]]))
    assert {s.track_id: round(s.y) for s in states} == {1: 0, 2: 2}
    for k in range(5, 8):  # the first leaves; a newcomer appears
        t = 0.1 * k
        states = tracker.step(t, np.array([[1.0 + t, 2.0], [4.0, -3.0]]))
    assert {s.track_id for s in states} == {2, 3}


def test_mahalanobis_gating_keeps_far_detections_out() -> None:
    tracker = Tracker(TrackerConfig(measurement_std=0.1, birth_hits=1))
    tracker.step(0.0, np.array([[0.0, 0.0]]))
    # a fresh track: S = P + R = 0.01 + 0.01 per axis, so 0.4 m off is d^2 = 0.16 / 0.02 = 8
    assert tracker.distances(np.array([[0.4, 0.0], [0.0, 0.5]])) == pytest.approx(np.array([[8.0, 12.5]]))
    states = tracker.step(0.0, np.array([[0.0, 0.5]]))  # outside the 9.21 gate: a second track
    assert sorted(s.track_id for s in states) == [1, 2]


def test_velocity_is_estimated() -> None:
    tracker = Tracker()
    for k in range(30):
        states = tracker.step(0.1 * k, np.array([[1.0 + 1.2 * 0.1 * k, 0.5]]))
    assert states[0].vx == pytest.approx(1.2, abs=0.05) and states[0].vy == pytest.approx(0.0, abs=0.05)


def test_legs_pair_into_people() -> None:
    legs = np.array([[2.0, 0.1], [2.0, -0.1], [4.0, 2.0], [6.0, 0.0], [6.3, 0.3]])
    pairs, singles = pair_legs(legs, 0.6)
    assert sorted(pairs) == [(0, 1), (3, 4)] and singles == [2]


def test_a_simulated_person_is_detected_at_their_position() -> None:
    lidar = LidarSimulator(seed=0)
    for velocity in ([0.0, 0.0], [1.2, 0.4]):
        scan = lidar.scan(0.3, Pose2D(), np.array([[3.0, 1.0]]), np.array([velocity]))
        found = detect(scan)
        assert len(found.people) == 1
        assert np.hypot(*(found.people[0] - [3.0, 1.0])) < 0.1


def test_clear_mot_with_six_walkers() -> None:
    crowd = walking_crowd(6, duration=20.0, seed=7)
    lidar = LidarSimulator(LidarSpec(), BodyModel(), seed=7)
    tracker = PersonTracker()
    tracks = [tracker.process(lidar.scan(t, Pose2D(), p, v)).tracks for t, p, v in zip(crowd.times, crowd.positions, crowd.velocities)]
    figures = clear_mot(list(crowd.positions), tracks)
    assert figures["objects"] == 1200
    assert figures["mota"] >= 0.9
    assert figures["motp"] <= 0.15
    assert figures["id_switches"] <= 20


@pytest.fixture(scope="module")
def moving_robot_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Path], np.ndarray]:
    """A robot driving and turning past two standing people, with a laser 0.3 m ahead of its base.

    tf names frames with leading slashes, as ROS1 logs often do.
    """
    root = tmp_path_factory.mktemp("moving")
    people = np.array([[6.0, 1.5], [4.0, -2.0]])
    bags = {"ros1": root / "moving.bag", "ros2-sqlite3": root / "moving_sqlite"}
    mount = Pose2D(0.3, 0.0, 0.0)
    for bag_format, path in bags.items():
        lidar = LidarSimulator(seed=11)
        with BagWriter(path, bag_format) as bag:
            bag.transforms([Transform(1_000_000_000, "/base_link", "/laser", mount, True)], "/tf_static")
            for k in range(60):
                t = 1.0 + 0.1 * k
                base = Pose2D(0.4 * (t - 1.0), 0.1 * (t - 1.0), 0.15 * (t - 1.0))
                bag.odometry(Odometry(int(round(t * 1e9)), "odom", "base_link", base, 0.4, 0.15))
                bag.scan(lidar.scan(t, base.compose(mount), people, None))
    return bags, people


@pytest.mark.parametrize("bag_format", ["ros1", "ros2-sqlite3"])
def test_tracks_in_the_odometry_frame_stay_put_while_the_robot_moves(moving_robot_bags, bag_format: str) -> None:
    bags, people = moving_robot_bags
    table = track_log(bags[bag_format], frame="odom", tracker=PersonTracker())  # simulated legs: width rules
    assert {row.frame for row in table.rows} == {"odom"}
    assert len(table.ids) == 2
    for track_id in table.ids:
        _, xy = table.track(track_id)
        nearest = people[np.argmin(np.hypot(*(people - xy[-1]).T))]
        assert np.hypot(*(xy - nearest).T).max() < 0.15  # still people stay still in odom


def test_tracks_in_the_sensor_frame_move_with_the_robot(moving_robot_bags) -> None:
    bags, people = moving_robot_bags
    table = track_log(bags["ros1"], frame="sensor", tracker=PersonTracker())
    assert {row.frame for row in table.rows} == {"laser"}
    last = max(row.stamp_ns for row in table.rows)
    t = last * 1e-9
    sensor = Pose2D(0.4 * (t - 1.0), 0.1 * (t - 1.0), 0.15 * (t - 1.0)).compose(Pose2D(0.3, 0.0, 0.0))
    expected = sensor.inverse().apply(people)
    seen = np.array([[r.x, r.y] for r in table.rows if r.stamp_ns == last])
    for point in expected:
        assert np.hypot(*(seen - point).T).min() < 0.15
    assert math.isclose(t, 6.9, abs_tol=1e-6)


def test_a_track_lives_on_unreported_through_an_occlusion_and_keeps_its_id() -> None:
    tracker = Tracker(TrackerConfig(death_misses=15, report_misses=1))
    for k in range(3):
        reported = tracker.step(0.1 * k, np.array([[2.0 + 0.1 * k, 1.0]]))
    assert [s.track_id for s in reported] == [1]
    hidden = [len(tracker.step(0.1 * k, np.zeros((0, 2)))) for k in range(3, 8)]
    assert hidden == [1, 0, 0, 0, 0]  # reported one scan into the occlusion, then kept quietly
    back = tracker.step(0.8, np.array([[2.8, 1.0]]))  # walked on at 1 m/s behind the occluder
    assert [(s.track_id, round(s.x, 1)) for s in back] == [(1, 2.8)]


def test_a_detection_beside_a_confirmed_track_starts_no_track() -> None:
    clear = TrackerConfig(birth_hits=1, birth_clearance=0.6)
    tracker = Tracker(clear)
    tracker.step(0.0, np.array([[2.0, 1.0]]))
    beside = tracker.step(0.1, np.array([[2.0, 1.0], [2.0, 1.45]]))  # the same person's other leg
    assert [s.track_id for s in beside] == [1] and len(tracker.tracks) == 1
    apart = tracker.step(0.2, np.array([[2.0, 1.0], [2.0, 1.8]]))  # someone 0.8 m away
    assert sorted(s.track_id for s in apart) == [1, 2]
    without = Tracker(TrackerConfig(birth_hits=1))
    without.step(0.0, np.array([[2.0, 1.0]]))
    assert len(without.step(0.1, np.array([[2.0, 1.0], [2.0, 1.45]]))) == 2


def test_a_tentative_track_may_survive_a_missed_scan() -> None:
    person, nobody = np.array([[2.0, 1.0]]), np.zeros((0, 2))
    for misses, confirmed in ((1, []), (2, [1])):
        tracker = Tracker(TrackerConfig(tentative_misses=misses))
        for k, seen in enumerate((person, person, nobody, person)):
            states = tracker.step(0.1 * k, seen)
        assert [s.track_id for s in states] == confirmed
    tracker = Tracker(TrackerConfig(tentative_misses=2))
    for k, seen in enumerate((person, nobody, nobody, person)):
        tracker.step(0.1 * k, seen)
    assert [t.hits for t in tracker.tracks] == [1]  # two misses in a row: dropped, born again


def test_a_tentative_track_is_confirmed_only_on_a_scan_that_detects_it() -> None:
    """A walker seen three times at 1 m/s, 0.2 m along (a track must walk 0.3 m), then lost for
    0.6 s: coasting, the filter's prediction passes 0.3 m, but a prediction is no evidence; the
    track is confirmed at its next detection."""
    tracker = Tracker(TrackerConfig(still_wait=np.inf, sure_confidence=np.inf, tentative_misses=2))
    for when, x in ((0.0, 2.0), (0.1, 2.1), (0.2, 2.2)):
        assert tracker.step(when, np.array([[x, 1.0]])) == []
    assert tracker.step(0.8, np.zeros((0, 2))) == []
    assert tracker.walking(tracker.tracks[0])  # its prediction has walked; it has not been seen to
    assert [s.track_id for s in tracker.step(0.9, np.array([[2.9, 1.0]]))] == [1]


def test_the_learned_setup_confirms_a_walker_whose_legs_were_lost_for_one_scan() -> None:
    """Someone walking up to the laser at 1.5 m/s, scored between the confirming and the protecting
    level, whom the classifier loses at the third scan: the learned setup confirms them at the
    fourth; dropped at its first miss, the track starts again and is confirmed three scans later."""
    config = PersonTracker.learned().tracker.config
    score = (config.confirm_confidence + config.sure_confidence) / 2
    confirmed_at = {}
    for misses in (config.tentative_misses, 1):
        tracker = Tracker(replace(config, tentative_misses=misses))
        for k in range(10):
            people = np.zeros((0, 2)) if k == 2 else np.array([[3.0 - 0.15 * k, 0.0]])
            if tracker.step(0.1 * k, people, np.full(len(people), score)) and misses not in confirmed_at:
                confirmed_at[misses] = k
    assert confirmed_at == {2: 3, 1: 6}


def test_a_walking_confirmed_track_takes_unsure_detections_for_a_while() -> None:
    """A walker confirmed at 1.5 m/s: ten scans the classifier doubts keep them (in the gate, no
    confidence gained); a tentative track and a standing one are never kept so, and after
    `unsure_time` without a sure detection nor is the walker."""
    config = TrackerConfig(unsure_time=1.0)
    walker, standing, tentative = Tracker(config), Tracker(config), Tracker(config)
    for k in range(4):
        walker.step(0.1 * k, np.array([[2.0 + 0.15 * k, 1.0]]))
        standing.step(0.1 * k, np.array([[2.0, 1.0]]))
    tentative.step(0.0, np.array([[2.0, 1.0]]))
    for k in range(4, 14):
        kept = walker.step(0.1 * k, np.zeros((0, 2)), unsure=np.array([[2.0 + 0.15 * k, 1.02]]))
        assert [s.track_id for s in kept] == [1] and walker.tracks[0].misses == 0
    assert walker.tracks[0].hits == 4 and walker.tracks[0].kf.x[0] == pytest.approx(3.95, abs=0.05)
    walker.step(1.4, np.zeros((0, 2)), unsure=np.array([[4.1, 1.0]]))
    assert walker.tracks[0].misses == 1  # 1 s after its last sure detection: no longer
    standing.step(0.4, np.zeros((0, 2)), unsure=np.array([[2.0, 1.0]]))
    assert standing.tracks[0].misses == 1
    tentative.step(0.1, np.zeros((0, 2)), unsure=np.array([[2.0, 1.0]]))
    assert tentative.tracks == []


def test_a_confirmed_track_outlives_the_same_time_at_any_scan_rate() -> None:
    for rate in (10.0, 40.0):
        tracker = Tracker(TrackerConfig(death_misses=5, death_time=0.5))
        for k in range(3):
            tracker.step(k / rate, np.array([[2.0, 1.0]]))
        alive = [bool(tracker.step((3 + k) / rate, np.zeros((0, 2)))) for k in range(int(0.8 * rate))]
        missed = (alive.index(False) + 1) / rate  # seconds from the last hit to the scan that drops it
        assert 0.5 - 1e-9 <= missed <= 0.5 + 1.0 / rate + 1e-9


def test_a_stride_shows_a_walker_who_keeps_still_in_the_output_frame() -> None:
    """A person followed at a steady distance, tracked in the robot's frame, barely moves there:
    the changing spread of their legs confirms them before `still_wait`; a pair of furniture legs
    keeps its spread and waits."""
    config = TrackerConfig(still_wait=2.0, sure_confidence=0.9, gait_spread=0.07)
    walker, furniture = Tracker(config), Tracker(config)
    for k in range(6):
        spread = 0.17 + 0.15 * abs(math.sin(k * 0.5))
        walker.step(0.1 * k, np.array([[2.0, 0.0]]), np.array([0.5]), spread=np.array([spread]))
        furniture.step(0.1 * k, np.array([[2.0, 0.0]]), np.array([0.5]), spread=np.array([0.4 + 0.01 * (k % 2)]))
    assert walker.walking(walker.tracks[0]) and walker.tracks[0].confirmed
    assert not furniture.walking(furniture.tracks[0]) and not furniture.tracks[0].confirmed
    for k in range(6, 30):  # the walker stops: 2 s later their stride no longer shows
        walker.step(0.1 * k, np.array([[2.0, 0.0]]), np.array([0.5]), spread=np.array([0.17]))
    assert not walker.walking(walker.tracks[0])


def test_a_striding_track_is_confirmed_on_weaker_evidence_than_a_still_or_gliding_one() -> None:
    """Detections at a mean confidence of 0.3, under the confirming 0.5 but over the walking 0.2:
    legs whose spread changes with a stride are confirmed; a pair of posts standing still, and one
    gliding at 1 m/s (furniture in the frame of a robot moving without odometry), never are."""
    config = TrackerConfig(confirm_confidence=0.5, striding_confidence=0.2, still_wait=math.inf, sure_confidence=0.9,
                           gait_spread=0.07)
    walker, post, glider = Tracker(config), Tracker(config), Tracker(config)
    confidence = np.array([0.3])
    for k in range(30):
        stride = np.array([0.17 + 0.15 * abs(math.sin(k * 0.5))])
        walker.step(0.1 * k, np.array([[2.0, 0.0]]), confidence, spread=stride)
        post.step(0.1 * k, np.array([[2.0, 1.0]]), confidence, spread=np.array([0.3]))
        glider.step(0.1 * k, np.array([[2.0 + 0.1 * k, -1.0]]), confidence, spread=np.array([0.3]))
    assert walker.tracks[0].confirmed and walker.tracks[0].striding(config)
    assert not post.tracks[0].confirmed and not glider.tracks[0].confirmed and glider.walking(glider.tracks[0])
    assert not Tracker(replace(config, striding_confidence=None))._ready(walker.tracks[0], 3.0)  # 0.3 < 0.5


def test_a_change_of_spread_seen_from_a_moving_sensor_is_no_stride_of_a_still_pair() -> None:
    """Two posts 1 m beside the path of a sensor driving 1 m/s seem to change their spread as one
    hides the other: at a mean confidence of 0.3, under the confirming 0.5, the pair is confirmed
    on that "stride" if the sensor stood, never while it moves; at 0.6, over the confirming level, a
    still track must walk, and that "stride" is no walk either; a walker whose legs stride as they
    walk beside it is confirmed either way."""
    config = TrackerConfig(confirm_confidence=0.5, striding_confidence=0.2, still_wait=math.inf, sure_confidence=0.9,
                           gait_spread=0.07)
    confirmed = {}
    for speed in (0.0, 1.0):
        posts, confident_posts, walker = Tracker(config), Tracker(config), Tracker(config)
        for k in range(30):
            t, stride = 0.1 * k, np.array([0.17 + 0.15 * abs(math.sin(k * 0.5))])
            sensor = Pose2D(speed * t, 0.0, 0.0)
            posts.step(t, np.array([[3.0, 1.0]]), np.array([0.3]), spread=stride, sensor=sensor)
            confident_posts.step(t, np.array([[3.0, 1.0]]), np.array([0.6]), spread=stride, sensor=sensor)
            walker.step(t, np.array([[3.0 + 1.2 * t, -1.0]]), np.array([0.3]), spread=stride, sensor=sensor)
        confirmed[speed] = tuple(tracker.tracks[0].confirmed for tracker in (posts, confident_posts, walker))
    assert confirmed == {0.0: (True, True, True), 1.0: (False, False, True)}


def test_told_how_the_laser_frame_moves_a_passing_post_stands_and_a_followed_walker_walks() -> None:
    """A robot drives along x at 1 m/s, tracking in its laser's frame: a post beside its way glides
    back through that frame, a walker 2 m ahead keeps still there. Judged in the laser's frame the
    post walks and is confirmed, the walker waits; told where the laser frame is (`motion`), the post
    stands and the walker walks."""
    config = TrackerConfig(confirm_confidence=0.5, still_wait=math.inf, sure_confidence=0.9)
    confirmed = {}
    for told in (False, True):
        tracker = Tracker(config)
        for k in range(20):
            t = 0.1 * k
            laser = Pose2D(t, 0.0, 0.0)  # the laser's pose in the world
            people = laser.inverse().apply(np.array([[5.0, 1.0], [2.0 + t, 0.0]]))
            tracker.step(t, people, np.array([0.6, 0.6]), motion=laser if told else None)
        confirmed[told] = [track.confirmed for track in tracker.tracks]  # [post, walker]
    assert confirmed == {False: [True, False], True: [False, True]}


def test_a_person_s_spread_is_the_distance_between_their_legs() -> None:
    """Two leg-sized posts 0.3 m apart at 2 m pair into one person with spread 0.3 m; a lone one
    is a person without a spread."""
    centres = np.array([[2.0, 0.15], [2.0, -0.15], [2.0, 2.5]])
    lidar = LidarSimulator(LidarSpec(range_noise_std=0.0), seed=0, posts=(centres, np.full(3, 0.06)))
    found = detect(lidar.scan(0.0, Pose2D(), np.zeros((0, 2))))
    pair, lone = np.argsort(found.people[:, 1])
    assert found.people[pair] == pytest.approx([2.0, 0.0], abs=0.04) and found.spread[pair] == pytest.approx(0.3, abs=0.02)
    assert found.people[lone] == pytest.approx([2.0, 2.5], abs=0.04) and np.isnan(found.spread[lone])
