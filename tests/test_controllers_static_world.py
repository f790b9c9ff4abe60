"""The static world in the controllers' plans (`trials.controllers.obstacles`): a wall between the robot and its goal is
planned around by the lattice planner and never crossed by NaviGAN-R's way-points; without it both go straight through."""

from __future__ import annotations

import numpy as np
import pytest

from robot_logs.physical import T_OBS
from trials.controllers.base import Observation
from trials.controllers.lattice import LatticeController
from trials.controllers.navigan_r import CLEARANCE_M, NaviganRController
from trials.controllers.obstacles import clear_prefix, nearest, thinned


def wall(x: float, y0: float, y1: float) -> np.ndarray:
    """Points 0.05 m apart along a wall at x from y0 to y1, as the static world's cells give them."""
    ys = np.arange(y0, y1 + 1e-9, 0.05)
    return np.column_stack([np.full(len(ys), x), ys])


def observation(obstacles: np.ndarray, goal: tuple[float, float] = (6.0, 0.0)) -> Observation:
    history = np.column_stack([np.linspace(-2.8, 0.0, T_OBS), np.zeros(T_OBS)])  # driving along +x at 1 m/s
    return Observation(time=0.0, robot_pose=np.zeros(3), robot_velocity=np.array([1.0, 0.0]), goal=np.array(goal),
                       robot_history=history, pedestrian_ids=(), pedestrian_history=np.zeros((0, T_OBS, 2)), obstacles=obstacles)


def test_thinning_nearest_and_the_clear_prefix_by_hand():
    points = np.array([[0.01, 0.01], [0.05, 0.12], [0.25, 0.0], [0.31, 0.1], [1.0, 1.0]])
    assert thinned(points, 0.2).tolist() == [[0.01, 0.01], [0.25, 0.0], [1.0, 1.0]]
    assert nearest(points, np.zeros(2), 2, 0.2).tolist() == [[0.01, 0.01], [0.25, 0.0]]
    path = np.array([[0.5, 0.0], [1.0, 0.0], [1.5, 0.0], [2.0, 0.0]])
    held, count = clear_prefix(path, np.zeros(2), np.array([[2.2, 0.0]]), 0.75)
    assert count == 2 and held.tolist() == [[0.5, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]
    # Already 0.5 m from a wall beside it, the robot may drive along it (0.5 m off) but not closer.
    beside = np.column_stack([np.arange(-1.0, 3.0, 0.05), np.full(80, 0.5)])
    assert clear_prefix(path, np.zeros(2), beside, 0.75)[1] == 0
    closer = clear_prefix(np.array([[0.5, 0.1], [1.0, 0.2]]), np.zeros(2), beside, 0.75)
    assert closer[1] == 2 and closer[0].tolist() == [[0.0, 0.0], [0.0, 0.0]]


def test_the_lattice_plans_around_a_wall_through_its_opening():
    controller = LatticeController()
    controller.reset(0)
    blocked = wall(3.0, -4.0, 1.0)  # open above y = 1
    straight = controller.plan(observation(np.zeros((0, 2)))).waypoints
    assert np.abs(straight[:, 1]).max() < 0.3 and straight[:, 0].max() > 3.5  # without the wall: straight through x = 3
    around = controller.plan(observation(blocked)).waypoints
    gaps = np.hypot(*(around[:, None, :] - blocked[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert gaps.min() > 0.3, gaps.min()  # the footprint's half width beside the wall, never through it
    crossing = around[np.abs(around[:, 0] - 3.0) < 0.3]
    assert len(crossing) == 0 or crossing[:, 1].min() > 1.0, crossing


@pytest.mark.parametrize("seed", [0, 1])
def test_navigan_r_never_plans_closer_to_a_wall_than_its_clearance(seed):
    controller = NaviganRController()
    controller.reset(seed)
    across = wall(2.0, -5.0, 5.0)
    free = controller.plan(observation(np.zeros((0, 2)))).waypoints
    assert free[:, 0].max() > 2.0 + CLEARANCE_M  # without the wall its way-points pass x = 2
    plan = controller.plan(observation(across))
    gaps = np.hypot(*(plan.waypoints[:, None, :] - across[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    assert gaps.min() >= CLEARANCE_M and plan.record["waypoints_held_off_walls"] > 0
    assert plan.record["standing_obstacles"] == 6  # the wall 2 m ahead: its six nearest points, 0.5 m apart, stand as people
