"""The lidar simulator: exact ray geometry, limits, seeded noise, leg and disc bodies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec, body_circles

EXACT = LidarSpec(range_noise_std=0.0)
DISC = BodyModel(shape="disc", disc_radius=0.25)


def beam(spec: LidarSpec, bearing: float) -> int:
    return int(round((bearing - spec.angle_min) / spec.angle_increment))


def test_a_beam_stops_at_the_near_side_of_a_disc() -> None:
    scan = LidarSimulator(EXACT, DISC).scan(0.0, Pose2D(), np.array([[3.0, 0.0]]))
    assert len(scan.ranges) == 1081 and scan.frame_id == "laser"
    assert scan.ranges[beam(EXACT, 0.0)] == pytest.approx(2.75)
    assert np.isinf(scan.ranges[beam(EXACT, math.radians(30))])  # nothing there: no return


def test_the_sensor_pose_places_the_rays() -> None:
    pose = Pose2D(1.0, -1.0, math.pi / 2)  # looking along +y
    scan = LidarSimulator(EXACT, DISC).scan(0.0, pose, np.array([[1.0, 2.0]]))
    assert scan.ranges[beam(EXACT, 0.0)] == pytest.approx(2.75)


def test_walls_and_range_limits() -> None:
    wall = np.array([[[4.0, -20.0], [4.0, 20.0]]])
    scan = LidarSimulator(EXACT, DISC, walls=wall).scan(0.0, Pose2D(), np.zeros((0, 2)))
    for degrees in (0.0, 30.0, -45.0):
        assert scan.ranges[beam(EXACT, math.radians(degrees))] == pytest.approx(4.0 / math.cos(math.radians(degrees)))
    assert np.isinf(scan.ranges[beam(EXACT, math.radians(70.0))])  # 11.7 m: beyond range_max 10 m
    assert np.isinf(scan.ranges[beam(EXACT, math.radians(120.0))])  # facing away from the wall


def test_noise_is_seeded() -> None:
    people = np.array([[3.0, 0.0], [5.0, 2.0]])
    first = LidarSimulator(seed=4).scan(0.5, Pose2D(), people).ranges
    again = LidarSimulator(seed=4).scan(0.5, Pose2D(), people).ranges
    other = LidarSimulator(seed=5).scan(0.5, Pose2D(), people).ranges
    assert np.array_equal(first, again)
    hit = np.isfinite(first)
    assert not np.array_equal(first[hit], other[hit])
    exact = LidarSimulator(EXACT).scan(0.5, Pose2D(), people).ranges
    assert np.std(first[hit] - exact[hit]) == pytest.approx(0.01, rel=0.3)


def test_dropouts_read_nan() -> None:
    wall = np.array([[[2.0, -20.0], [2.0, 20.0]]])
    scan = LidarSimulator(LidarSpec(dropout=0.2), walls=wall, seed=1).scan(0.0, Pose2D(), np.zeros((0, 2)))
    assert np.isnan(scan.ranges).mean() == pytest.approx(0.2, abs=0.04)


def test_legs_swing_along_the_walking_direction() -> None:
    body = BodyModel()
    standing, radii = body_circles(np.array([[0.0, 0.0]]), np.zeros((1, 2)), 0.3, body)
    assert np.allclose(standing, [[0.0, 0.1], [0.0, -0.1]]) and np.allclose(radii, 0.06)
    quarter = 1.0 / (4.0 * body.cadence_hz)  # swing at its widest
    walking, _ = body_circles(np.array([[0.0, 0.0]]), np.array([[0.0, 1.3]]), quarter, body)
    assert np.allclose(walking, [[-0.1, 0.25], [0.1, -0.25]])  # walking along +y


def test_the_simulator_counts_the_beams_on_each_person() -> None:
    lidar = LidarSimulator(EXACT, DISC, posts=(np.array([[2.0, -2.0]]), np.array([0.3])))
    people = np.array([[3.0, 0.0], [6.0, 0.0], [4.0, -4.0], [4.0, 3.0]])  # the second behind the first,
    scan, beams = lidar.observe(0.0, Pose2D(), people)  # the third behind the post
    assert beams[1] == 0 and beams[2] == 0
    # a 0.25 m disc at 3 m spans 2 * asin(0.25 / 3) = 9.6 degrees: 38 or 39 beams of 0.25 degrees
    assert 38 <= beams[0] <= 39 and beams[3] > 0
    assert np.array_equal(scan.ranges, LidarSimulator(EXACT, DISC, posts=(np.array([[2.0, -2.0]]), np.array([0.3]))).scan(0.0, Pose2D(), people).ranges)
    _, legs = LidarSimulator(EXACT).observe(0.0, Pose2D(), people[:1])
    assert legs[0] > 0  # both leg circles count for their person
