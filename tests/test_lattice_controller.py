"""The lattice controller in the trial scenario: robot at the origin heading +x, goal 10 m ahead."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robot_logs.physical import ROBOT_FOOTPRINT, STEP_S, T_OBS, T_PRED
from tests.support.lattice_scene import observe
from trials.controllers.lattice import TRIAL_EXPANSIONS, LatticeController
from trials.lattice.costmap import INSCRIBED, LETHAL, Window, pedestrian_costmap, predicted_centres
from trials.lattice.crowd import inscribed_radius
from trials.lattice.errors import LatticeError


def test_open_floor_drives_straight_at_nominal_speed(fresh):
    plan = fresh.plan(observe())
    assert fresh.name == "Lattice" and fresh.seed == 7
    assert plan.waypoints.shape == (T_PRED, 2) and plan.step == STEP_S
    # the path starts at the centre of the robot's 0.1 m cell, (0.05, 0.05), and runs along +x at 1 m/s
    assert plan.waypoints[:, 0] == pytest.approx(0.05 + 0.4 * np.arange(1, T_PRED + 1), abs=1e-6)
    assert plan.waypoints[:, 1] == pytest.approx(0.05)
    record = plan.record
    assert record["status"] == "solved" and record["eps"] == 1.0 and not record["holding"]
    assert record["expansions"] > 0 and record["cost"] > 0 and record["margin"] == 0.2 and record["rung"] == "margin"
    assert record["plan_seconds"] > 0 and fresh.details() == {"search_budget": f"{TRIAL_EXPANSIONS} expansions"}
    assert json.loads(json.dumps(record)) == record  # loggable as it is


def test_detours_round_a_standing_pedestrian(fresh):
    ped = np.array([3.0, 0.0])
    plan = fresh.plan(observe(peds=[(ped, (0.0, 0.0))]))
    assert plan.record["status"] == "solved"
    distance = np.hypot(*(plan.waypoints - ped).T)
    # way-points are centre positions: clear of the disc grown by the margin and the inscribed radius
    assert distance.min() >= 0.3 + 0.2 + inscribed_radius(ROBOT_FOOTPRINT) - 0.1
    assert np.abs(plan.waypoints[:, 1]).max() > 0.6  # it went round, not through
    assert plan.waypoints[-1, 0] > ped[0]             # and past


def test_too_close_for_comfort_retries_without_the_margin(fresh):
    # the robot's cell centre is 0.75 m from this pedestrian: inside 0.3 + 0.2 + 0.335, outside 0.3 + 0.335
    plan = fresh.plan(observe(peds=[((0.05, 0.8), (0.0, 0.0))]))
    assert plan.record["margin"] == 0.0 and plan.record["status"] == "solved" and not plan.record["holding"]
    assert plan.record["rung"] == "no_margin"


def test_goal_covered_by_a_pedestrian_moves_the_goal(fresh):
    plan = fresh.plan(observe(peds=[((10.0, 0.0), (0.0, 0.0))]))
    assert plan.record["goal_moved"] and plan.record["status"] == "solved"
    assert plan.waypoints[-1, 0] > 4.0


def test_at_the_goal_it_holds(fresh):
    plan = fresh.plan(observe(robot=(9.8, 0.1, 0.0)))
    assert plan.record["status"] == "at_goal" and plan.record["holding"] and "rung" not in plan.record
    assert np.allclose(plan.waypoints, [9.8, 0.1])


def test_bad_observation_holds_instead_of_raising(fresh):
    plan = fresh.plan(observe(robot=(np.nan, 0.0, 0.0)))
    assert plan.record["status"] == "bad_observation" and plan.waypoints.shape == (T_PRED, 2)


def test_walled_in_robot_heads_for_the_reachable_cell_nearest_the_goal(fresh):
    # a ring of people 1.5 m around the robot: the goal is out of reach; it still moves towards it
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = [(1.5 * np.array([np.cos(a), np.sin(a)]), (0.0, 0.0)) for a in angles]
    plan = fresh.plan(observe(peds=ring))
    record = plan.record
    assert record["goal_moved"] and record["status"] == "solved" and not record["holding"]
    assert 0.3 < record["target"][0] < 1.5 - 0.3 - 0.2 - inscribed_radius(ROBOT_FOOTPRINT) + 0.1
    assert plan.waypoints[-1, 0] == pytest.approx(record["target"][0])
    assert record["expansions"] <= TRIAL_EXPANSIONS


def test_wall_clock_budget_gone_before_the_search_says_so_and_escapes():
    # 0.021 s less the 0.02 s kept back leaves each search no time at all: partial, with only the start, on
    # both margin rungs; the robot backs off from the one pedestrian, 5 m ahead, rather than stand
    plan = LatticeController(budget_s=0.021, budget_expansions=None).plan(observe(peds=[((5.0, 0.0), (0.0, 0.0))]))
    record = plan.record
    assert record["status"] == "partial" and record["rung"] == "escape" and not record["holding"]
    assert "no path to the goal within" in record["message"] and record["expansions"] == 0
    assert record["escape_to"] == pytest.approx([-0.5, 0.0])


def test_crowd_within_budget(fresh):
    rng = np.random.default_rng(3)
    for step in range(5):
        peds = [((rng.uniform(1, 9), rng.uniform(-3, 3)), (rng.uniform(-1, 1), rng.uniform(-1, 1))) for _ in range(6)]
        plan = fresh.plan(observe(peds=peds, time=step * STEP_S))
        assert plan.waypoints.shape == (T_PRED, 2) and np.isfinite(plan.waypoints).all()
        assert plan.record["expansions"] <= TRIAL_EXPANSIONS


def test_prediction_blocks_where_a_walker_is_going():
    crosser = [((3.0, -2.0), (0.0, 1.0))]  # walking up across the robot's line at 1 m/s
    now_only = LatticeController(predict_s=0.0)
    ahead = LatticeController(predict_s=3.0)
    straight = now_only.plan(observe(peds=crosser)).waypoints
    around = ahead.plan(observe(peds=crosser)).waypoints
    assert np.abs(straight[:, 1]).max() < 0.1  # the walker is 2 m to the side now
    tube = np.array([(3.0, y) for y in np.linspace(-2.0, 1.0, 31)])
    gaps = np.hypot(*(around[:, None, :] - tube[None, :, :]).transpose(2, 0, 1)).min()
    assert gaps >= 0.3 + 0.2 + inscribed_radius(ROBOT_FOOTPRINT) - 0.1


def test_new_goal_gets_a_new_window(fresh):
    fresh.plan(observe())
    plan = fresh.plan(observe(goal=(0.0, 10.0)))
    assert plan.record["status"] == "solved"
    assert plan.waypoints[-1, 1] > 3.0 and abs(plan.waypoints[-1, 0]) < 1.5


@pytest.mark.slow
def test_five_centimetre_cells():
    plan = LatticeController(cell_size=0.05, budget_s=2.0).plan(observe(peds=[((4.0, 0.3), (-1.0, 0.0))]))
    assert plan.record["status"] == "solved" and plan.waypoints.shape == (T_PRED, 2)


@pytest.mark.parametrize("kwargs, message", [
    ({"cell_size": 0.0}, "cell_size must be positive"),
    ({"budget_s": -1.0}, "budget_s must be positive"),
    ({"comfort_margin": -0.1}, "comfort_margin must not be negative"),
    ({"eps": 0.5}, "eps must be at least 1"),
    ({"budget_expansions": 0}, "budget_expansions must be at least 1"),
])
def test_bad_settings_are_refused_at_construction(kwargs, message):
    with pytest.raises(LatticeError, match=message):
        LatticeController(**kwargs)


def test_costmap_rings_and_predictions():
    window = Window((-1.0, -1.0), 0.1, 20, 20)
    grid = pedestrian_costmap(window, np.array([[0.0, 0.0]]), 0.3, 0.2)
    # cell (10, 10) has its centre at (0.05, 0.05): lethal; (13, 10) at 0.35 m: inscribed; (16, 10) at 0.65: free
    assert (grid[10, 10], grid[10, 13], grid[10, 16]) == (LETHAL, INSCRIBED, 0)
    history = np.array([[[0.0, 0.0]] * (T_OBS - 1) + [[0.4, 0.0]], [[np.nan, np.nan]] * T_OBS])
    assert predicted_centres(history, 0.8, STEP_S) == pytest.approx(np.array([[0.4, 0.0], [0.8, 0.0], [1.2, 0.0]]))
    assert predicted_centres(history, 0.0, STEP_S).tolist() == [[0.4, 0.0]]
    assert predicted_centres(np.zeros((0, T_OBS, 2)), 1.0, STEP_S).shape == (0, 2)
