"""The lattice planner as a trial controller: the A/B study's pure collision-avoidance baseline.

A thin adapter: the observation's pose, goal and pedestrian tracks go to `trials.lattice.crowd`'s
planner, built for the Husky (`robot_logs.physical`), and its way-points and record come back as a
`Plan`.
"""

from __future__ import annotations

from typing import Any

from robot_logs.physical import ROBOT_FOOTPRINT, ROBOT_SPEED_M_S, STEP_S, T_PRED
from trials.controllers.base import Observation, Plan
from trials.controllers.registry import LATTICE
from trials.lattice.crowd import CrowdPlanner


class LatticeController:
    """SBPL-like lattice planning among pedestrians (the `Controller` protocol).

    Args:
        options: `CrowdPlanner`'s settings; the footprint, speed, step and horizon default to the
            Husky's and NaviGAN's (`robot_logs.physical`).

    Raises:
        LatticeError: a setting out of range.
    """

    name = LATTICE

    def __init__(self, **options: Any) -> None:
        robot = {"footprint": ROBOT_FOOTPRINT, "speed": ROBOT_SPEED_M_S, "step_s": STEP_S, "horizon_steps": T_PRED}
        self.planner = CrowdPlanner(**{**robot, **options})
        self.seed = 0

    @property
    def budget_s(self) -> float:
        return self.planner.budget_s

    def details(self) -> dict[str, str]:
        return {}

    def reset(self, seed: int) -> None:
        self.seed = seed
        self.planner.reset()

    def plan(self, observation: Observation) -> Plan:
        out = self.planner.plan(observation.robot_pose, observation.goal, observation.pedestrian_history)
        return Plan(out.waypoints, self.planner.step_s, {"controller": self.name, **out.record})
