"""NaviGAN-R as a trial controller: the shipped all-scenes weights planning for the robot.

Each step the scene is moved into the robot's frame (origin at the robot, x along its heading),
so the network sees its own track and the goal as the robot does; the generator then plans in its
target-centric frame (origin at the robot's oldest observed position). The goal is passed as a
sub-goal `reach_m` ahead in the direction of the real one (`navigan.goals.toward`), since the
network was trained on goals one prediction horizon (4.8 s) away; near the end it lies beyond the
goal, so the robot drives up to the goal (where the trial ends) instead of creeping toward it. The
way-points, the intention path and the social forces come back in the world frame; the last two
and the timing go to the plan's record. The static world (`Observation.obstacles`) enters as the nearest walls' points
standing still, and no way-point takes the robot closer to a wall than `CLEARANCE_M` (`trials.controllers.obstacles`).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from navigan.goals import toward
from robot_logs.physical import ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M, STEP_S, T_OBS, T_PRED
from trials.controllers.base import Observation, Plan
from trials.controllers.obstacles import clear_prefix, nearest
from trials.controllers.registry import NAVIGAN_R

#: A sub-goal one prediction horizon ahead at the Husky's 1 m/s.
REACH_M = 1.0 * T_PRED * STEP_S
#: The static world's points given to the network as people standing still: at most this many, this far apart, this near.
STANDING, STANDING_SPACING_M, STANDING_RANGE_M = 6, 0.5, 3.0
#: No way-point closer to a wall than this (m): the Husky's circumscribed radius and 0.1 m.
CLEARANCE_M = math.hypot(ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M) + 0.1


def _rotation(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


class NaviganRController:
    """NaviGAN-R (the `Controller` protocol) on a `navigan.planner.Planner`.

    Args:
        weights: a checkpoint path or shipped name (default: the shipped all-scenes NaviGAN-R).
        reach_m: how far ahead of the robot the sub-goal lies.

    Raises:
        NaviganError: the weights cannot be read.
    """

    name = NAVIGAN_R

    def __init__(self, weights: str | Path | None = None, reach_m: float = REACH_M) -> None:
        from navigan.planner import Planner

        self.planner = Planner(weights)
        self.reach_m = reach_m

    @property
    def weights(self) -> Path:
        return self.planner.path

    def details(self) -> dict[str, str]:
        return {"weights": str(self.weights)}

    def reset(self, seed: int) -> None:
        self.planner.reset(seed)

    def plan(self, observation: Observation) -> Plan:
        started = time.perf_counter()
        origin = np.asarray(observation.robot_pose[:2], dtype=float)
        rotation = _rotation(float(observation.robot_pose[2]))

        def to_robot(points: np.ndarray) -> np.ndarray:
            return (np.asarray(points, dtype=float) - origin) @ rotation

        subgoal = toward(origin, np.asarray(observation.goal, dtype=float)[:2], self.reach_m)
        obstacles = np.asarray(observation.obstacles, dtype=float).reshape(-1, 2)
        near = obstacles[np.hypot(*(obstacles - origin).T) <= STANDING_RANGE_M]
        standing = np.repeat(nearest(near, origin, STANDING, STANDING_SPACING_M)[:, None, :], T_OBS, axis=1)
        others = np.concatenate([np.asarray(observation.pedestrian_history, dtype=float).reshape(-1, T_OBS, 2), standing])
        out = self.planner.plan(to_robot(observation.robot_history), to_robot(others), to_robot(subgoal))
        waypoints, held = clear_prefix(out.waypoints.astype(float) @ rotation.T + origin, origin, obstacles, CLEARANCE_M)
        record = {
            "controller": self.name,
            "standing_obstacles": len(standing),
            "waypoints_held_off_walls": held,
            "subgoal": subgoal.tolist(),
            "intention": (out.intention.astype(float) @ rotation.T + origin).tolist(),
            "forces": (out.forces.astype(float) @ rotation.T).tolist(),
            "plan_seconds": time.perf_counter() - started,
        }
        return Plan(waypoints, out.step, record)
