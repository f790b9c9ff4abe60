"""Static-world rejection: a leg-like post beside a walking person is dropped once its cells stay
occupied, the walker is kept, and a person the detector is sure of is kept while standing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_logs.clutter import furnished_room
from robot_logs.detection import scan_points
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.pipeline import PersonTracker
from robot_logs.static_world import StaticWorld, StaticWorldConfig
from robot_logs.tracking import TrackerConfig
from tests.support.leg_classifiers import constant


def run(probability: float, static_world: StaticWorldConfig | None, standing: bool = False, scans: int = 60):
    """Tracks after each of `scans` 10 Hz scans: a 6 cm post at (3, 1), a person at y = -1."""
    lidar = LidarSimulator(seed=4, posts=(np.array([[3.0, 1.0]]), np.array([0.06])))
    tracker = PersonTracker(tracker=TrackerConfig(confirm_confidence=0.5), classifier=constant(probability),
                            static_world=static_world)
    history = []
    for k in range(scans):
        t = 0.1 * k
        position = np.array([[4.0, -1.0]]) if standing else np.array([[1.5 + 1.0 * t, -1.0]])
        velocity = np.zeros((1, 2)) if standing else np.array([[1.0, 0.0]])
        history.append(tracker.process(lidar.scan(t, Pose2D(), position, velocity)).tracks)
    return history


def near(tracks, point) -> bool:
    return any(math.hypot(s.x - point[0], s.y - point[1]) < 0.3 for s in tracks)


def test_a_static_post_is_dropped_and_the_walker_kept() -> None:
    without = run(0.6, None)
    assert near(without[-1], (3.0, 1.0))  # width rules alone cannot tell the post from a leg
    history = run(0.6, StaticWorldConfig())
    assert near(history[5], (3.0, 1.0))  # confirmed at first, before its cells have a history
    assert not any(near(tracks, (3.0, 1.0)) for tracks in history[30:])  # static after 1.5 s, gone by 3 s
    for k in range(10, 60):
        assert near(history[k], (1.5 + 0.1 * k, -1.0))


def test_a_standing_person_the_detector_is_sure_of_is_kept() -> None:
    unsure = run(0.6, StaticWorldConfig(), standing=True)
    assert not near(unsure[-1], (4.0, -1.0))  # shows the grid would take them
    sure = run(0.9, StaticWorldConfig(), standing=True)
    assert all(near(tracks, (4.0, -1.0)) for tracks in sure[3:])


def test_furnished_rooms_are_seeded() -> None:
    room = furnished_room(seed=5)
    again = furnished_room(seed=5)
    assert np.array_equal(room.centres, again.centres) and np.array_equal(room.walls, again.walls)
    assert not np.array_equal(room.centres, furnished_room(seed=6).centres)
    assert len(room.centres) == 3 * 4 + 6 * 4 + 2 * 2 + 2 and len(room.walls) == 5
    table = room.centres[:4]
    sides = sorted(np.hypot(*(table[1:] - table[0]).T))
    assert sides == pytest.approx([0.8, 1.2, math.hypot(0.8, 1.2)])


def test_a_pillar_taken_for_a_body_by_width_rules_is_dropped_too() -> None:
    lidar = LidarSimulator(seed=4, posts=(np.array([[3.0, 1.0]]), np.array([0.25])))
    grid = PersonTracker(static_world=StaticWorldConfig(protect_confidence=math.inf))  # width rules: no confidence
    alone = PersonTracker()
    for k in range(40):
        t = 0.1 * k
        scan = lidar.scan(t, Pose2D(), np.array([[1.5 + t, -1.0]]), np.array([[1.0, 0.0]]))
        with_grid, without = grid.process(scan).tracks, alone.process(scan).tracks
    assert near(without, (3.0, 1.0)) and not near(with_grid, (3.0, 1.0))
    assert near(with_grid, (5.4, -1.0))


def test_a_still_unsure_track_waits_for_the_grid_and_is_never_reported() -> None:
    lidar = LidarSimulator(seed=4, posts=(np.array([[3.0, 1.0]]), np.array([0.06])))
    waiting = TrackerConfig(confirm_confidence=0.5, still_wait=2.0, sure_confidence=0.7)
    tracker = PersonTracker(tracker=waiting, classifier=constant(0.6), static_world=StaticWorldConfig())
    sure = PersonTracker(tracker=waiting, classifier=constant(0.9), static_world=StaticWorldConfig())
    reported, sure_from = [], []
    for k in range(40):
        t = 0.1 * k
        scan = lidar.scan(t, Pose2D(), np.array([[1.5 + t, -1.0]]), np.array([[1.0, 0.0]]))
        reported.append(near(tracker.process(scan).tracks, (3.0, 1.0)))
        sure_from.append(near(sure.process(scan).tracks, (3.0, 1.0)))
    assert not any(reported)  # static after 1.5 s, before its 2 s wait was over
    assert sure_from.index(True) == 2  # a sure detection is confirmed at its third hit, still or not


def test_the_clutter_setup_never_reports_a_post_or_a_wall_beside_a_walker() -> None:
    """`PersonTracker.rules_with_grid`: a walker crossing in front of a wall cuts leg-wide pieces
    out of it, and passes a 6 cm post; neither is ever reported, and the walker is tracked from
    their fifth scan. Width rules alone report both."""
    wall = np.array([[[5.0, -2.0], [5.0, 2.0]]])
    for setup, clutter_reported in ((PersonTracker, True), (PersonTracker.rules_with_grid, False)):
        lidar = LidarSimulator(seed=4, walls=wall, posts=(np.array([[3.6, 0.5]]), np.array([0.03])))
        tracker = setup()
        others, walker = [], []
        for k in range(30):
            t = 0.1 * k
            position = (3.0, -0.8 + 1.0 * t)
            tracks = tracker.process(lidar.scan(t, Pose2D(), np.array([position]), np.array([[0.0, 1.0]]))).tracks
            walker.append(near(tracks, position))
            others.append(sum(math.hypot(s.x - position[0], s.y - position[1]) >= 0.3 for s in tracks))
        assert any(others) == clutter_reported
        assert all(walker[4:])


def test_a_cell_never_seen_free_is_static_sooner_only_when_asked() -> None:
    lidar = LidarSimulator(seed=4, posts=(np.array([[3.0, 1.0]]), np.array([0.06])))
    quick = StaticWorld(StaticWorldConfig(never_free_hits=2, never_free_duration=0.2))
    usual = StaticWorld(StaticWorldConfig())
    post = np.array([[2.95, 1.0]])  # the post's near side
    walked = []
    for k in range(16):
        t = 0.1 * k
        scan = lidar.scan(t, Pose2D(), np.array([[1.5 + 1.0 * t, -1.0]]), np.array([[1.0, 0.0]]))
        if k < 3:
            walked.append(scan_points(scan)[scan_points(scan)[:, 1] < 0])  # the walker's legs
        for world in (quick, usual):
            world.update(scan, scan_points(scan), Pose2D(), np.zeros((0, 2)))
        if k == 1:
            assert not quick.is_static(post)[0]  # hit twice, but only 0.1 s apart
        if k == 3:
            assert quick.is_static(post)[0] and not usual.is_static(post)[0]  # 0.3 s of hits, never free
    assert usual.is_static(post)[0]  # after 1.5 s the usual rule agrees
    assert not quick.is_static(np.concatenate(walked)).any()  # the walker's old cells were seen free


def test_a_walker_coming_straight_at_the_lidar_leaves_no_static_cells_behind() -> None:
    """Walking along the beams towards the lidar, a person hides the cells their legs just left,
    so no beam ever passes them free; counted as seen without a hit (`hidden_gap`), they stay
    free of the static world. Without that count, 17 of the 62 points of the first steps lie on
    static cells by the end of the 3 s walk (measured)."""
    lidar = LidarSimulator(seed=4)
    worlds = {gap: StaticWorld(StaticWorldConfig(hidden_gap=gap)) for gap in (1.0, 0.0)}
    first_steps = []
    for k in range(30):  # 10 Hz, from 4.5 m to 1.6 m at 1 m/s
        t = 0.1 * k
        scan = lidar.scan(t, Pose2D(), np.array([[4.5 - 1.0 * t, 0.0]]), np.array([[-1.0, 0.0]]))
        if k < 5:
            first_steps.append(scan_points(scan))
        for world in worlds.values():
            world.update(scan, scan_points(scan), Pose2D(), np.zeros((0, 2)))
    steps = np.concatenate(first_steps)
    assert len(steps) == 62
    assert not worlds[1.0].is_static(steps).any()
    assert worlds[0.0].is_static(steps).sum() == 17
