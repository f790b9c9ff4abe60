"""The lattice planner as a trial controller: the A/B study's pure collision-avoidance baseline.

A thin adapter: the observation's pose, goal, pedestrian tracks and static world go to `trials.lattice.crowd`'s
planner, built for the Husky (`robot_logs.physical`), and its way-points and record come back as a
`Plan`. Trials run offline (simulated, or a log played back), so each search is bounded by a number
of expansions rather than by the wall clock, and a run reproduces from its seed at any machine load.
"""

from __future__ import annotations

from typing import Any

from robot_logs.physical import ROBOT_FOOTPRINT, ROBOT_SPEED_M_S, STEP_S, T_PRED
from trials.controllers.base import Observation, Plan
from trials.controllers.registry import LATTICE
from trials.lattice.crowd import CrowdPlanner

#: The trials' search budget: about what the 0.25 s wall-clock budget allows less its reserve
#: (1.7 to 1.8 million expansions a second measured on the development machine in a 6-pedestrian trial).
TRIAL_EXPANSIONS = 400_000


class LatticeController:
    """SBPL-like lattice planning among pedestrians (the `Controller` protocol).

    Args:
        options: `CrowdPlanner`'s settings; the footprint, speed, step and horizon default to the
            Husky's and NaviGAN's (`robot_logs.physical`), the search budget to `TRIAL_EXPANSIONS`
            expansions (`budget_expansions=None`: the wall-clock `budget_s` instead).

    Raises:
        LatticeError: a setting out of range.
    """

    name = LATTICE

    def __init__(self, **options: Any) -> None:
        robot = {"footprint": ROBOT_FOOTPRINT, "speed": ROBOT_SPEED_M_S, "step_s": STEP_S, "horizon_steps": T_PRED,
                 "budget_expansions": TRIAL_EXPANSIONS}
        self.planner = CrowdPlanner(**{**robot, **options})
        self.seed = 0

    @property
    def budget_s(self) -> float:
        return self.planner.budget_s

    def details(self) -> dict[str, str]:
        """The search budget, so that a run's settings say how it was bounded."""
        expansions = self.planner.budget_expansions
        return {"search_budget": f"{self.budget_s:g} s" if expansions is None else f"{expansions} expansions"}

    def reset(self, seed: int) -> None:
        self.seed = seed
        self.planner.reset()

    def plan(self, observation: Observation) -> Plan:
        out = self.planner.plan(observation.robot_pose, observation.goal, observation.pedestrian_history, observation.obstacles)
        return Plan(out.waypoints, self.planner.step_s, {"controller": self.name, **out.record})
