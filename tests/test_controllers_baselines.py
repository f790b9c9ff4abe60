"""The built-in baselines against independent truths: the social force robot against the closed-form relaxation and the
numerical gradient of Helbing & Molnar's potential; ORCA's half-planes against the velocity obstacle found by brute
force, its velocity against a quadratic program solved by cvxpy, and the reciprocal-avoidance theorem of van den Berg
et al. (two agents choosing from their ORCA sets do not touch within the horizon)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robot_logs.physical import STEP_S, T_OBS, T_PRED
from trials.controllers.base import Observation
from trials.controllers.crowd_now import PERSON_RADIUS_M, ROBOT_RADIUS_M
from trials.controllers.orca import HalfPlane, OrcaController, best_velocity, half_plane
from trials.controllers.social_force import SocialForceController
from trials.sim.social_force import SocialForceParams


def observe(people: np.ndarray | None = None, velocity: float = 0.0, goal=(10.0, 0.0), walls=None) -> Observation:
    people = np.zeros((0, T_OBS, 2)) if people is None else people
    return Observation(0.0, np.zeros(3), np.array([velocity, 0.0]), np.array(goal, dtype=float), np.zeros((T_OBS, 2)),
                       tuple(range(len(people))), people, np.zeros((0, 2)) if walls is None else np.asarray(walls, dtype=float))


def standing(x: float, y: float) -> np.ndarray:
    return np.tile([x, y], (1, T_OBS, 1)).astype(float)


# --- the social force robot ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("start_speed", [0.0, 0.4])
def test_in_free_space_the_robot_relaxes_to_its_speed_as_the_closed_form(start_speed):
    # dv/dt = (v0 - v) / tau  =>  x(t) = v0 t - (v0 - v_start) tau (1 - exp(-t / tau))
    tau, v0 = SocialForceParams().relaxation_s, 1.0
    plan = SocialForceController(dt=0.0005).plan(observe(velocity=start_speed))
    t = STEP_S * np.arange(1, T_PRED + 1)
    exact = v0 * t - (v0 - start_speed) * tau * (1.0 - np.exp(-t / tau))
    np.testing.assert_allclose(plan.waypoints[:, 0], exact, atol=1e-3)
    np.testing.assert_allclose(plan.waypoints[:, 1], 0.0, atol=1e-12)


def potential(robot: np.ndarray, person: np.ndarray, step: np.ndarray, params: SocialForceParams) -> float:
    """V0 exp(-b / sigma) with 2b = sqrt((|r| + |r - s|)^2 - |s|^2), r from the person's to the robot's surface."""
    r = robot - person
    centres = math.hypot(*r)
    r = r * (centres - ROBOT_RADIUS_M - PERSON_RADIUS_M) / centres
    b = 0.5 * math.sqrt((math.hypot(*r) + math.hypot(*(r - step))) ** 2 - float(step @ step))
    return params.strength * math.exp(-b / params.range_m)


@pytest.mark.parametrize(("person", "walking"), [((2.0, 0.3), (0.0, 0.0)), ((2.5, -0.6), (-1.0, 0.2)), ((1.8, 1.2), (0.3, -0.8))])
def test_a_persons_push_is_minus_the_gradient_of_the_potential(person, walking):
    params = SocialForceParams()
    person, walking = np.array(person), np.array(walking)
    history = (person - walking * STEP_S * np.arange(T_OBS)[::-1, None])[None]
    controller = SocialForceController(params)
    plan = controller.plan(observe(history))
    step = walking * params.lookahead_s
    h = 1e-6
    gradient = np.array([(potential(np.array(d) * h, person, step, params) - potential(-np.array(d) * h, person, step, params)) / (2 * h)
                         for d in ((1.0, 0.0), (0.0, 1.0))])
    push = -gradient
    # the person is in front (inside the view cone) so the push counts fully; the evasion adds the part opposing the
    # goal's direction, turned sideways toward the side the robot already is on (or to the right)
    opposing = max(-push[0], 0.0)
    side = 1.0 if -person[1] > 0.1 else -1.0
    expected = push + params.evasion * opposing * side * np.array([0.0, 1.0])
    np.testing.assert_allclose(plan.record["people"], expected, rtol=1e-5, atol=1e-9)


def test_a_wall_pushes_as_helbing_and_molnars_exponential():
    plan = SocialForceController().plan(observe(walls=[[0.0, -1.0]]))
    gap = 1.0 - ROBOT_RADIUS_M
    np.testing.assert_allclose(plan.record["walls"], [0.0, (10.0 / 0.2) * math.exp(-gap / 0.2)], rtol=1e-12)


def test_the_robot_steps_aside_for_a_person_coming_head_on_and_reaches_the_goal():
    controller = SocialForceController()
    robot, person, velocity = np.zeros(2), np.array([8.0, 0.05]), np.array([-1.2, 0.0])
    trail = [robot.copy()] * T_OBS
    walked = [person - velocity * STEP_S * k for k in range(T_OBS)][::-1]
    gaps, heading, speed = [], 0.0, 0.0
    for _ in range(40):
        history = np.array(walked[-T_OBS:])[None]
        robot_history = np.array(trail[-T_OBS:])
        observation = Observation(0.0, np.array([*robot, heading]), np.array([speed, 0.0]), np.array([10.0, 0.0]), robot_history, (1,), history)
        step = controller.plan(observation).waypoints[0] - robot
        robot, heading, speed = robot + step, math.atan2(step[1], step[0]), math.hypot(*step) / STEP_S
        walked.append(walked[-1] + velocity * STEP_S)
        trail.append(robot.copy())
        gaps.append(math.hypot(*(robot - walked[-1])) - ROBOT_RADIUS_M - PERSON_RADIUS_M)
    assert min(gaps) > 0.3 and robot[0] > 9.0


# --- ORCA -----------------------------------------------------------------------------------------------------------------

def in_obstacle(v: np.ndarray, offset: np.ndarray, radius: float, horizon: float) -> np.ndarray:
    """Whether moving at relative velocities `v` ((..., 2)) brings the discs into contact within the horizon: the
    segment {v t : 0 <= t <= horizon} passes within `radius` of `offset`."""
    speed2 = np.maximum((v * v).sum(-1), 1e-300)
    t = np.clip((v @ offset) / speed2, 0.0, horizon)
    return np.linalg.norm(offset - v * t[..., None], axis=-1) < radius


def first_crossings(start: np.ndarray, angles: np.ndarray, inside: bool, offset, radius, horizon) -> np.ndarray:
    """Along each ray from `start`, the distance at which membership of the obstacle first changes (scan, then bisect)."""
    rays = np.column_stack([np.cos(angles), np.sin(angles)])
    steps = np.linspace(0.0, 3.0, 1501)
    members = in_obstacle(start + steps[:, None, None] * rays[None], offset, radius, horizon)
    changed = members != inside
    index = np.where(changed.any(axis=0), changed.argmax(axis=0), len(steps) - 1)
    low, high = steps[np.maximum(index - 1, 0)], steps[index]
    for _ in range(50):
        middle = 0.5 * (low + high)
        flips = in_obstacle(start + middle[:, None] * rays, offset, radius, horizon) != inside
        high, low = np.where(flips, middle, high), np.where(flips, low, middle)
    return high


def brute_force_exit(offset: np.ndarray, relative: np.ndarray, radius: float, horizon: float) -> np.ndarray:
    """The smallest change of `relative` that puts it on the obstacle's boundary, by searching every direction."""
    inside = bool(in_obstacle(relative, offset, radius, horizon))
    angles = np.linspace(0.0, 2.0 * math.pi, 2880, endpoint=False)
    reach = first_crossings(relative, angles, inside, offset, radius, horizon)
    best = angles[np.argmin(reach)]
    fine = best + np.linspace(-0.005, 0.005, 2001)
    reach = first_crossings(relative, fine, inside, offset, radius, horizon)
    angle = fine[np.argmin(reach)]
    return reach.min() * np.array([math.cos(angle), math.sin(angle)])


@pytest.mark.parametrize(("offset", "relative"), [
    ((3.0, 0.5), (1.0, 0.0)),       # inside the cone: out by a leg
    ((3.0, 0.0), (1.0, 0.9)),       # beside the cone, to the left
    ((4.0, -1.0), (0.2, -0.05)),    # inside the truncating disc: out through the arc
    ((2.0, 2.0), (-0.5, 0.3)),      # outside: the half-plane only keeps it out
])
def test_the_half_plane_leaves_the_velocity_obstacle_by_the_shortest_way(offset, relative):
    offset, relative = np.array(offset), np.array(relative)
    radius, horizon = 0.85, 5.0
    plane = half_plane(offset, relative, radius, horizon, np.zeros(2), share=1.0)
    exit_change = brute_force_exit(offset, relative, radius, horizon)
    # with share 1 and a robot at rest, the plane's point is the change itself
    np.testing.assert_allclose(plane.point, exit_change, atol=1e-4)
    assert abs(math.hypot(*plane.normal) - 1.0) < 1e-12
    # the normal points out of the obstacle: along the change when inside it, against it when outside
    inside = bool(in_obstacle(relative, offset, radius, horizon))
    assert (plane.normal @ exit_change > 0) == inside


def qp_velocity(planes: list[HalfPlane], preferred: np.ndarray, max_speed: float) -> np.ndarray | None:
    import cvxpy as cp

    v = cp.Variable(2)
    constraints = [cp.norm(v) <= max_speed] + [(v - plane.point) @ plane.normal >= 0 for plane in planes]
    problem = cp.Problem(cp.Minimize(cp.sum_squares(v - preferred)), constraints)
    problem.solve()
    return None if problem.status != cp.OPTIMAL else np.asarray(v.value)


def test_the_new_velocity_is_the_nearest_allowed_one_as_a_quadratic_program_finds_it():
    rng = np.random.default_rng(2026)
    compared = 0
    for _ in range(200):
        count = int(rng.integers(1, 7))
        planes = []
        for _ in range(count):
            angle = rng.uniform(0, 2 * math.pi)
            planes.append(HalfPlane(rng.uniform(-0.8, 0.8, 2), np.array([math.cos(angle), math.sin(angle)])))
        preferred = rng.uniform(-1.5, 1.5, 2)
        ours, feasible = best_velocity(planes, preferred, 1.0)
        truth = qp_velocity(planes, preferred, 1.0)
        assert feasible == (truth is not None)
        if truth is not None:
            compared += 1
            # as near as the solver's tolerance, inside every half-plane and the disc, and never farther from preferred
            np.testing.assert_allclose(ours, truth, atol=1e-4)
            assert max(plane.violation(ours) for plane in planes) <= 1e-9 and math.hypot(*ours) <= 1.0 + 1e-9
            assert math.hypot(*(ours - preferred)) <= math.hypot(*(truth - preferred)) + 1e-9
        else:
            assert max(plane.violation(ours) for plane in planes) > 0.0
            assert math.hypot(*ours) <= 1.0 + 1e-9
    assert compared > 100


def test_two_orca_agents_do_not_touch_within_the_horizon():
    # van den Berg et al.'s theorem: each taking half the avoidance, their new velocities are collision-free for tau
    rng = np.random.default_rng(7)
    radius, horizon = 0.5, 5.0
    for _ in range(300):
        a, b = rng.uniform(-3, 3, 2), rng.uniform(-3, 3, 2)
        if math.hypot(*(a - b)) <= 2 * radius + 0.05:
            continue
        va, vb = rng.uniform(-1, 1, 2), rng.uniform(-1, 1, 2)
        new_a, ok_a = best_velocity([half_plane(b - a, va - vb, 2 * radius, horizon, va, 0.5)], (b - a) * 0.5, 1.5)
        new_b, ok_b = best_velocity([half_plane(a - b, vb - va, 2 * radius, horizon, vb, 0.5)], (a - b) * 0.5, 1.5)
        assert ok_a and ok_b
        t = np.linspace(0.0, horizon, 2001)[:, None]
        gaps = np.hypot(*((b + new_b * t) - (a + new_a * t)).T)
        assert gaps.min() >= 2 * radius - 1e-6


def test_orca_drives_straight_in_free_space_and_takes_half_the_avoidance_of_a_person_in_the_way():
    free = OrcaController().plan(observe())
    np.testing.assert_allclose(free.waypoints, np.column_stack([STEP_S * np.arange(1, T_PRED + 1), np.zeros(T_PRED)]))
    # a person 4 m ahead walking toward the robot at 1 m/s, a little to its left
    walking = np.column_stack([4.0 + STEP_S * np.arange(T_OBS)[::-1], np.full(T_OBS, 0.2)])
    plan = OrcaController().plan(observe(walking[None], velocity=1.0))
    chosen = np.array(plan.record["velocity"])
    assert plan.record["feasible"] and plan.record["half_planes"] == 1
    # if the person also takes half (steps aside by the same change, mirrored), the two never touch within 5 s
    change = chosen - np.array([1.0, 0.0])
    person_velocity = np.array([-1.0, 0.0]) - change
    t = np.linspace(0.0, 5.0, 2001)[:, None]
    gaps = np.hypot(*((np.array([4.0, 0.2]) + person_velocity * t) - chosen * t).T)
    assert gaps.min() >= ROBOT_RADIUS_M + PERSON_RADIUS_M - 1e-6
    assert chosen[1] < -0.05  # it passes on the right, the side away from the person
