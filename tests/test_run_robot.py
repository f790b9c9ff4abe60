"""The robot: Husky-like limits, exact arcs, footprint gaps, and following way-points of both shapes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trials.controllers.base import Plan
from trials.sim.follower import WaypointFollower
from trials.sim.robot import RobotLimits, RobotState, footprint_gaps, nearest_footprint_points, step_robot

LIMITS = RobotLimits()


def test_the_husky_footprint_and_limits():
    assert (LIMITS.half_length, LIMITS.half_width) == (0.495, 0.335)
    assert (LIMITS.max_speed, LIMITS.max_turn_rate) == (1.0, 2.0)


def test_speeds_ramp_at_the_acceleration_limit_and_stop_at_the_caps():
    state = RobotState(0.0, 0.0, 0.0)
    speeds = []
    for _ in range(12):
        state = step_robot(state, 5.0, 9.0, 0.1, LIMITS)
        speeds.append((state.v, state.w))
    v, w = np.array(speeds).T
    np.testing.assert_allclose(v[:6], 0.15 * np.arange(1, 7), atol=1e-12)  # 1.5 m/s^2 for 0.1 s steps
    assert v[-1] == 1.0 and w[-1] == 2.0
    state = RobotState(0.0, 0.0, 0.0)
    for _ in range(20):
        state = step_robot(state, -3.0, 0.0, 0.1, LIMITS)
    assert state.v == -0.5 and state.x < 0


def test_an_arc_is_integrated_exactly():
    state = RobotState(0.0, 0.0, 0.0, v=1.0, w=1.0)
    for _ in range(100):
        state = step_robot(state, 1.0, 1.0, math.pi / 100, LIMITS)  # half a circle of radius 1
    assert (state.x, state.y) == pytest.approx((0.0, 2.0), abs=1e-9)
    assert abs(abs(state.theta) - math.pi) < 1e-9


def test_footprint_gaps_in_the_robots_frame():
    pose = np.array([1.0, 2.0, math.pi / 2])  # facing +y
    points = np.array([[1.0, 2.495 + 0.5], [1.0 + 0.335 + 0.3, 2.0], [1.2, 2.1], [1.0 + 0.335 + 0.3, 2.495 + 0.4]])
    gaps = footprint_gaps(pose, points, LIMITS, radius=0.25)
    np.testing.assert_allclose(gaps, [0.5 - 0.25, 0.3 - 0.25, -0.25, 0.5 - 0.25])
    nearest = nearest_footprint_points(pose, points, LIMITS)
    np.testing.assert_allclose(nearest, [[1.0, 2.495], [1.335, 2.0], [1.2, 2.1], [1.335, 2.495]])


def plan_of(points) -> Plan:
    return Plan(np.asarray(points, dtype=float))


@pytest.mark.parametrize("waypoints,expect", [
    ([[0.4 * k, 0.0] for k in range(1, 13)], "forward"),
    ([[0.0, 0.0]] * 12, "stop"),
    ([[-0.1, 0.0]] * 12, "back"),        # the lattice's backward primitive: one cell behind
    ([[0.0, 0.6]] * 12, "turn"),         # beside the robot: turn on the spot first
    ([[-2.0, 0.0]] * 12, "turn"),        # far behind: turn round rather than reverse
])
def test_the_follower_picks_the_motion(waypoints, expect):
    follower = WaypointFollower(LIMITS)
    follower.follow(0.0, np.zeros(2), plan_of(waypoints))
    v, w = follower.command(0.0, RobotState(0.0, 0.0, 0.0))
    kind = "stop" if v == w == 0.0 else "back" if v < 0 else "turn" if v == 0.0 else "forward"
    assert kind == expect, (v, w)


def drive(plan: Plan, seconds: float) -> list[RobotState]:
    follower, state, states = WaypointFollower(LIMITS), RobotState(0.0, 0.0, 0.0), []
    follower.follow(0.0, state.position, plan)
    for k in range(int(round(seconds / 0.1))):
        state = step_robot(state, *follower.command(0.1 * k, state), 0.1, LIMITS)
        states.append(state)
    return states


def test_a_lattice_style_turn_in_place_then_go_is_followed():
    # hold for 1.2 s (turning in place, which way-points cannot show), then drive along +y
    points = [[0.0, 0.0]] * 3 + [[0.0, 0.4 * k] for k in range(1, 10)]
    states = drive(plan_of(points), 4.8)
    turning = [s for s in states if abs(s.v) < 0.05 and abs(s.w) > 0.3]
    assert turning, "expected a turn on the spot"
    end = states[-1]
    assert abs(end.x) < 0.35 and end.y > 2.5 and abs(end.theta - math.pi / 2) < 0.3


def test_a_lattice_style_backward_move_is_driven_in_reverse():
    states = drive(plan_of([[-0.1 * min(k, 2), 0.0] for k in range(1, 13)]), 2.0)
    assert min(s.v for s in states) < -0.05
    assert states[-1].x == pytest.approx(-0.2, abs=0.06) and abs(states[-1].theta) < 0.05


def test_a_smooth_curve_is_tracked_closely():
    t = 0.4 * np.arange(1, 13)
    points = np.column_stack([0.8 * t, 0.5 * (1 - np.cos(0.5 * t))])
    states = drive(plan_of(points), 4.8)
    assert np.hypot(states[-1].x - points[-1, 0], states[-1].y - points[-1, 1]) < 0.6
