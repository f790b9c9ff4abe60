"""A differential-drive robot with Husky-like limits, and the gap between its footprint and people.

The robot is a unicycle: commanded linear and angular velocities are limited in magnitude and
rate of change, then integrated exactly along an arc over each physics step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.physical import ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M, ROBOT_SPEED_M_S


@dataclass(frozen=True)
class RobotLimits:
    """Speed and acceleration limits (m/s, rad/s, m/s^2, rad/s^2) and the rectangular footprint (m).

    Defaults: a ClearPath Husky (0.99 x 0.67 m, 1.0 m/s, 2 rad/s); backwards at most 0.5 m/s.
    """

    max_speed: float = ROBOT_SPEED_M_S
    max_reverse_speed: float = 0.5
    max_turn_rate: float = 2.0
    max_acceleration: float = 1.5
    max_angular_acceleration: float = 3.0
    half_length: float = ROBOT_HALF_LENGTH_M
    half_width: float = ROBOT_HALF_WIDTH_M


@dataclass
class RobotState:
    """Pose (x, y, theta) in the world frame and the velocities it is moving at."""

    x: float
    y: float
    theta: float
    v: float = 0.0
    w: float = 0.0

    @property
    def pose(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta])

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y])

    def velocity_vector(self) -> np.ndarray:
        """(2,) world-frame velocity of the robot's centre."""
        return self.v * np.array([math.cos(self.theta), math.sin(self.theta)])


def _toward(current: float, target: float, max_change: float) -> float:
    return current + float(np.clip(target - current, -max_change, max_change))


def step_robot(state: RobotState, v_cmd: float, w_cmd: float, dt: float, limits: RobotLimits) -> RobotState:
    """The state `dt` seconds later under a velocity command, within the robot's limits."""
    v_target = float(np.clip(v_cmd, -limits.max_reverse_speed, limits.max_speed))
    w_target = float(np.clip(w_cmd, -limits.max_turn_rate, limits.max_turn_rate))
    v = _toward(state.v, v_target, limits.max_acceleration * dt)
    w = _toward(state.w, w_target, limits.max_angular_acceleration * dt)
    theta = state.theta + w * dt
    if abs(w) < 1e-9:
        x = state.x + v * dt * math.cos(state.theta)
        y = state.y + v * dt * math.sin(state.theta)
    else:
        radius = v / w
        x = state.x + radius * (math.sin(theta) - math.sin(state.theta))
        y = state.y - radius * (math.cos(theta) - math.cos(state.theta))
    theta = (theta + math.pi) % (2.0 * math.pi) - math.pi
    return RobotState(x, y, theta, v, w)


def footprint_gaps(pose: np.ndarray, points: np.ndarray, limits: RobotLimits, radius: float = 0.0) -> np.ndarray:
    """(N,) distance from the robot's rectangle to each point, less `radius` (negative: overlap).

    Args:
        pose: (3,) the robot's x, y, heading.
        points: (N, 2) world positions (pedestrian centres).
        radius: body radius of each point (0.25 m for a pedestrian disc).
    """
    local = _to_robot_frame(pose, points)
    outside = np.maximum(np.abs(local) - (limits.half_length, limits.half_width), 0.0)
    return np.hypot(outside[:, 0], outside[:, 1]) - radius


def nearest_footprint_points(pose: np.ndarray, points: np.ndarray, limits: RobotLimits) -> np.ndarray:
    """(N, 2) the point of the robot's rectangle nearest to each world point (the point itself inside)."""
    local = _to_robot_frame(pose, points)
    clamped = np.clip(local, (-limits.half_length, -limits.half_width), (limits.half_length, limits.half_width))
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return clamped @ np.array([[c, s], [-s, c]]) + pose[:2]


def _to_robot_frame(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return (np.asarray(points, dtype=float).reshape(-1, 2) - pose[:2]) @ np.array([[c, -s], [s, c]])
