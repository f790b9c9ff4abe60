"""An observation as the reactive baselines read it: where each tracked person is now and how fast they walk, the
robot's velocity as a vector, and the static world's nearest points."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.physical import PEDESTRIAN_RADIUS_M, ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M, STEP_S
from trials.controllers.base import Observation
from trials.controllers.obstacles import nearest

#: The disc the reactive baselines see the robot as (the Husky's circumscribed circle), and a person's.
ROBOT_RADIUS_M = math.hypot(ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M)
PERSON_RADIUS_M = PEDESTRIAN_RADIUS_M
#: The static world a reactive baseline keeps clear of: at most this many of its nearest points, this far apart, this near.
WALL_POINTS, WALL_SPACING_M, WALL_RANGE_M = 12, 0.4, 3.0


@dataclass(frozen=True)
class CrowdNow:
    """The scene at the observation's instant, in the world frame."""

    position: np.ndarray  # (2,) the robot's
    velocity: np.ndarray  # (2,) the robot's, from its speed along its heading
    goal: np.ndarray  # (2,)
    people: np.ndarray  # (N, 2) each person seen now
    people_velocity: np.ndarray  # (N, 2) from their last two positions (zero when seen once)
    walls: np.ndarray  # (M, 2) the static world's nearest points


def crowd_now(observation: Observation) -> CrowdNow:
    """The people tracked at the newest step (a track whose newest position is NaN is not seen now)."""
    pose = np.asarray(observation.robot_pose, dtype=float)
    heading = float(pose[2])
    speed = float(np.asarray(observation.robot_velocity, dtype=float)[0])
    history = np.asarray(observation.pedestrian_history, dtype=float).reshape(-1, np.shape(observation.robot_history)[0], 2)
    seen = np.isfinite(history[:, -1]).all(axis=1)
    history = history[seen]
    positions = history[:, -1]
    previous = history[:, -2] if history.shape[1] > 1 else positions
    velocities = np.where(np.isfinite(previous), (positions - previous) / STEP_S, 0.0)
    walls = np.asarray(observation.obstacles, dtype=float).reshape(-1, 2)
    walls = walls[np.hypot(*(walls - pose[:2]).T) <= WALL_RANGE_M]
    return CrowdNow(pose[:2].copy(), speed * np.array([math.cos(heading), math.sin(heading)]),
                    np.asarray(observation.goal, dtype=float)[:2], positions, velocities,
                    nearest(walls, pose[:2], WALL_POINTS, WALL_SPACING_M))


def along(position: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """(K, 2) way-points one step apart from `position` moving at each of `velocities` ((K, 2)) in turn."""
    return position + np.cumsum(np.asarray(velocities, dtype=float) * STEP_S, axis=0)
