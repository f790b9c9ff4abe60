"""The social force pedestrians: Helbing & Molnar's forces by hand, seeding, and avoiding the robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trials.scenario import Scenario, Settings, Walker
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotLimits, RobotState, footprint_gaps, step_robot
from trials.sim.social_force import SocialForceParams, cap_speed, ellipse_repulsion, social_acceleration, view_weight

PARAMS = SocialForceParams()
LIMITS = RobotLimits()


def scene(*walkers: Walker) -> Scenario:
    return Scenario(Settings(len(walkers), "Parallel", 2.0), 0, (0.0, 0.0, 0.0), (10.0, 0.0), (10.0, 0.75), walkers)


def walk(crowd: Crowd, robot: RobotState, seconds: float, robot_speed: float = 0.0, dt: float = 0.1):
    """Step the crowd with the robot driving straight at `robot_speed`; returns (robot poses, positions)."""
    poses, positions = [], []
    for k in range(int(round(seconds / dt))):
        crowd.step(k * dt, dt, robot, LIMITS)
        robot = step_robot(robot, robot_speed, 0.0, dt, LIMITS)
        poses.append(robot.pose)
        positions.append(crowd.position.copy())
    return np.array(poses), np.array(positions)


def test_a_standing_other_repels_along_the_line_with_the_exponential_potential():
    r = np.array([0.8, 0.6])  # |r| = 1 m
    force = ellipse_repulsion(r, np.zeros(2), strength=2.1, range_m=0.3)
    expected = 2.1 / 0.3 * math.exp(-1.0 / 0.3)  # V0 / sigma * exp(-b / sigma), b = |r| when s = 0
    np.testing.assert_allclose(force, expected * r, rtol=1e-9)


def _by_hand(distance: float, step: float) -> float:
    """|f| on the other's line of motion, `distance` ahead (negative: behind) of someone taking `step`."""
    d1, d2 = abs(distance), abs(distance - step)
    b = math.sqrt((d1 + d2) ** 2 - step**2) / 2.0
    return 2.1 / 0.3 * math.exp(-b / 0.3) * (d1 + d2) / (4.0 * b) * 2.0  # grad b = (d1 + d2) / 4b * (2 unit vectors)


def test_the_ellipse_keeps_more_room_ahead_of_a_walker_than_behind():
    step = np.array([2.4, 0.0])  # the other walks along +x at 1.2 m/s, 2 s lookahead
    ahead = np.linalg.norm(ellipse_repulsion(np.array([3.0, 0.0]), step, 2.1, 0.3))
    behind = np.linalg.norm(ellipse_repulsion(np.array([-3.0, 0.0]), step, 2.1, 0.3))
    assert ahead == pytest.approx(_by_hand(3.0, 2.4), rel=1e-9)  # b = sqrt(3.6^2 - 2.4^2) / 2 = 1.34 m
    assert behind == pytest.approx(_by_hand(-3.0, 2.4), rel=1e-9)  # b = sqrt(8.4^2 - 2.4^2) / 2 = 4.02 m
    assert ahead > 1000 * behind


def test_forces_from_behind_count_at_weight_c():
    heading = np.array([[1.0, 0.0]])
    from_ahead = np.array([[-1.0, 0.0]])  # pushed back: the source is in front
    from_behind = np.array([[1.0, 0.0]])
    from_side = np.array([[0.0, 1.0]])  # source at 90 degrees, inside the 200-degree view
    assert view_weight(heading, from_ahead, PARAMS)[0] == 1.0
    assert view_weight(heading, from_behind, PARAMS)[0] == PARAMS.behind_weight == 0.5
    assert view_weight(heading, from_side, PARAMS)[0] == 1.0


def test_social_acceleration_sums_pairs_and_skips_oneself():
    positions = np.array([[0.0, 0.0], [1.0, 0.0]])
    desired = np.array([[1.0, 0.0], [1.0, 0.0]])
    params = SocialForceParams(evasion=0.0)
    acc = social_acceleration(positions, np.zeros((2, 2)), desired, None, np.zeros(2), np.zeros(2), np.zeros(2), params)
    magnitude = 2.1 / 0.3 * math.exp(-1.0 / 0.3)
    np.testing.assert_allclose(acc, [[-magnitude, 0.0], [0.5 * magnitude, 0.0]])  # the second feels it from behind
    # with evasion the one pushed back also steps aside, to its right (-y when heading +x) on a tie
    acc = social_acceleration(positions, np.zeros((2, 2)), desired, None, np.zeros(2), np.zeros(2), np.zeros(2), PARAMS)
    np.testing.assert_allclose(acc, [[-magnitude, -magnitude], [0.5 * magnitude, 0.0]])


def test_speed_is_capped_at_1_3_times_the_preferred_speed():
    capped = cap_speed(np.array([[3.0, 4.0], [0.3, 0.4]]), np.array([1.0, 1.0]), PARAMS)
    np.testing.assert_allclose(np.linalg.norm(capped, axis=1), [1.3, 0.5])


def test_the_crowd_is_seeded():
    walkers = (Walker(0, "oncoming", (8.0, 0.5), (-5.0, 0.5), 1.2), Walker(1, "oncoming", (9.0, -0.5), (-5.0, -0.5), 1.3))
    runs = [walk(Crowd(scene(*walkers), PARAMS, seed), RobotState(0.0, 0.0, 0.0), 5.0)[1] for seed in (1, 1, 2)]
    np.testing.assert_array_equal(runs[0], runs[1])
    assert np.abs(runs[0] - runs[2]).max() > 0.01


@pytest.mark.parametrize("robot_speed", [0.0, 0.8])
def test_a_pedestrian_walking_at_the_robot_steps_around_it(robot_speed):
    walker = Walker(0, "oncoming", (8.0, 0.05), (-6.0, 0.05), 1.2)
    poses, positions = walk(Crowd(scene(walker), PARAMS, 3), RobotState(0.0, 0.0, 0.0), 12.0, robot_speed)
    gaps = np.array([footprint_gaps(pose, p, LIMITS, 0.25)[0] for pose, p in zip(poses, positions)])
    assert gaps.min() > 0.2  # never closer than 0.2 m to the footprint
    passing = np.argmin(np.abs(positions[:, 0, 0] - poses[:, 0]))
    assert abs(positions[passing, 0, 1]) > 0.8  # beside the robot when passing it
    assert positions[-1, 0, 0] < poses[-1, 0] - 3.0  # and walked on


def test_without_the_robots_repulsion_the_same_walker_runs_into_it():
    """The control: the avoidance above comes from the robot's social force."""
    walker = Walker(0, "oncoming", (8.0, 0.05), (-6.0, 0.05), 1.2)
    params = SocialForceParams(robot_strength=0.0, fluctuation=0.0)
    poses, positions = walk(Crowd(scene(walker), params, 3), RobotState(0.0, 0.0, 0.0), 8.0)
    gaps = np.array([footprint_gaps(pose, p, LIMITS, 0.25)[0] for pose, p in zip(poses, positions)])
    assert gaps.min() < 0.0


def test_two_pedestrians_head_on_pass_each_other():
    walkers = (Walker(0, "oncoming", (0.0, 3.0), (10.0, 3.0), 1.2), Walker(1, "oncoming", (10.0, 3.05), (0.0, 3.05), 1.2))
    _, positions = walk(Crowd(scene(*walkers), PARAMS, 5), RobotState(-20.0, -20.0, 0.0), 12.0)
    distance = np.linalg.norm(positions[:, 0] - positions[:, 1], axis=1)
    assert distance.min() > 0.5
    assert positions[-1, 0, 0] > 9.0 and positions[-1, 1, 0] < 1.0


def test_waiting_crossers_hold_their_spot_until_the_robot_comes():
    crosser = Walker(0, "crossing", (6.0, 2.5), (6.0, -5.0), 1.2, cross_x=6.0)
    crowd = Crowd(scene(crosser), PARAMS, 1)
    walk(crowd, RobotState(-30.0, 0.0, 0.0), 5.0)  # robot far away and standing
    np.testing.assert_allclose(crowd.position[0], [6.0, 2.5], atol=1e-6)
    assert not crowd.walking[0]
