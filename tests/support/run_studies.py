"""Helpers for the `trials run` tests: small study folders designed once, and a scripted controller."""

from __future__ import annotations

import numpy as np

from robot_logs.physical import STEP_S, T_PRED
from trials.cli import main
from trials.controllers.base import Observation, Plan

SMALL_SPEC = """
[study]
name = "{name}"
runs = 6
model = "main"
seed = 11

[[factors]]
name = "Pedestrians"
type = "discrete"
levels = [2, 4]

[[factors]]
name = "Direction"
type = "categorical"
levels = ["Parallel", "ParallelCrossing", "Crossing"]

[[factors]]
name = "Controller"
type = "categorical"
blind = {blind}
levels = ["NaviGAN-R", "Lattice"]

[[factors]]
name = "CrossingDistance"
type = "fixed"
value = 2
"""


def design_small_study(folder, blind: bool) -> None:
    """A 6-run study of both controllers (Pedestrians 2/4, the three directions), blinded or open."""
    folder.mkdir(parents=True)
    spec = folder / "spec.toml"
    spec.write_text(SMALL_SPEC.format(name="small-ab" if blind else "small-open", blind=str(blind).lower()))
    assert main(["design", "--spec", str(spec), "--study", str(folder)]) == 0
    spec.unlink()


class Straight:
    """A scripted controller: straight along +x at a fixed speed (the robot does not avoid anyone)."""

    name = "straight"

    def __init__(self, speed: float) -> None:
        self.speed = speed

    def details(self) -> dict[str, str]:
        return {}

    def reset(self, seed: int) -> None:
        pass

    def plan(self, observation: Observation) -> Plan:
        x, y = observation.robot_pose[:2]
        ahead = self.speed * STEP_S * np.arange(1, T_PRED + 1)
        return Plan(np.column_stack([x + ahead, np.full(T_PRED, y)]))
