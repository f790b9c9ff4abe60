"""The scenario's walkers as social-force pedestrians: who is walking, toward what, and when they set off.

Oncoming walkers set off after their delay. A crosser waits at the side of the path until the
robot's approach says it should go: it sets off when the robot's front bumper, at its current
speed (at least `MIN_JUDGED_SPEED`), would be `crossing_distance` short of the crossing point by
the time the crosser reaches the path. Crossers do what they were asked: once under way they keep
clear of the robot's body but not of the path ahead of it (the social force's lookahead for the
robot is 0 for them), else nobody would cross a metre in front of a moving robot. People head for
their goal once under way and for their start spot until then (someone pushed aside steps back),
slowing down within `SLOW_RADIUS_M` of it.
"""

from __future__ import annotations

import math

import numpy as np

from trials.scenario import Scenario
from trials.sim.robot import RobotLimits, RobotState, nearest_footprint_points
from trials.sim.social_force import SocialForceParams, cap_speed, driving_acceleration, social_acceleration

#: The slowest robot speed a crosser reckons with (m/s): a standing robot is expected to move on.
MIN_JUDGED_SPEED = 0.5
#: Crossers go by this time (s) even if the robot never comes.
LATEST_START_S = 20.0
#: Within this distance (m) of where they head for, people slow down in proportion.
SLOW_RADIUS_M = 1.0


class Crowd:
    """The pedestrians of one run, stepped with the social force model.

    Args:
        scenario: the walkers.
        params: social force constants.
        seed: seeds the fluctuation force.
    """

    def __init__(self, scenario: Scenario, params: SocialForceParams, seed: int) -> None:
        walkers = scenario.walkers
        self.ids = tuple(w.id for w in walkers)
        self.start = np.array([w.start for w in walkers], dtype=float).reshape(-1, 2)
        self.position = self.start.copy()
        self.velocity = np.zeros_like(self.position)
        self.goal = np.array([w.goal for w in walkers], dtype=float).reshape(-1, 2)
        self.preferred = np.array([w.speed for w in walkers], dtype=float)
        self.walking = np.zeros(len(walkers), dtype=bool)
        crossing = np.array([w.cross_x is not None for w in walkers], dtype=bool)
        self._robot_lookahead = np.where(crossing, 0.0, params.lookahead_s)
        self._walkers = walkers
        self._distance = scenario.settings.crossing_distance
        self._params = params
        self._rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return len(self.ids)

    def _set_off(self, time: float, robot: RobotState, limits: RobotLimits) -> None:
        front = robot.x + limits.half_length * math.cos(robot.theta)
        judged_speed = max(robot.v * math.cos(robot.theta), MIN_JUDGED_SPEED)
        for i, walker in enumerate(self._walkers):
            if self.walking[i]:
                continue
            if walker.cross_x is None:
                go = time >= walker.delay_s
            else:
                reach_s = abs(walker.start[1] - robot.y) / walker.speed + self._params.relaxation_s - walker.timing_s
                go = front >= walker.cross_x - self._distance - judged_speed * reach_s or time >= LATEST_START_S
            self.walking[i] = go

    def step(self, time: float, dt: float, robot: RobotState, limits: RobotLimits) -> None:
        """Advance everyone by `dt` seconds, reacting to each other and to the robot."""
        if not len(self):
            return
        self._set_off(time, robot, limits)
        target = np.where(self.walking[:, None], self.goal, self.start)
        offset = target - self.position
        distance = np.linalg.norm(offset, axis=1)
        desired = offset / np.maximum(distance, 1e-9)[:, None]
        speed = self.preferred * np.minimum(distance / SLOW_RADIUS_M, 1.0)
        params = self._params
        acceleration = driving_acceleration(self.velocity, desired, speed, params)
        robot_points = nearest_footprint_points(robot.pose, self.position, limits)
        acceleration += social_acceleration(self.position, self.velocity, desired, robot_points, robot.position,
                                            robot.velocity_vector(), self._robot_lookahead, params)
        acceleration += np.where(self.walking[:, None], self._rng.normal(0.0, params.fluctuation, self.position.shape), 0.0)
        self.velocity = cap_speed(self.velocity + acceleration * dt, self.preferred, params)
        self.position = self.position + self.velocity * dt
