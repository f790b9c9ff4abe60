"""The lattice controller's trial scene for tests: robot at the origin heading +x, goal 10 m ahead,
pedestrians given by where they are now and how they walk; a controller reset to seed 7 per test."""

from __future__ import annotations

import numpy as np
import pytest

from robot_logs.physical import STEP_S, T_OBS
from trials.controllers.base import Observation
from trials.controllers.lattice import LatticeController

GOAL = (10.0, 0.0)


def observe(robot=(0.0, 0.0, 0.0), goal=GOAL, peds=(), time=0.0) -> Observation:
    """An observation; `peds` are (position now, velocity) pairs walked back over T_OBS steps."""
    steps = np.arange(-(T_OBS - 1), 1)[:, None] * STEP_S
    history = np.array([np.asarray(p) + steps * np.asarray(v) for p, v in peds]).reshape(len(peds), T_OBS, 2)
    robot = np.asarray(robot, dtype=float)
    return Observation(time, robot, np.zeros(2), np.asarray(goal, dtype=float), np.repeat(robot[None, :2], T_OBS, 0),
                       tuple(range(len(peds))), history)


@pytest.fixture(scope="module")
def controller():
    return LatticeController()


@pytest.fixture
def fresh(controller):
    controller.reset(7)
    return controller
