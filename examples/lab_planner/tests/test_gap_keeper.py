"""GapKeeper's own tests: what it answers in free space, beside a person, and as navtrials loads it."""

from __future__ import annotations

import math

import numpy as np
from lab_planner import GapKeeper, make_controller
from lab_planner.gap_keeper import CREEP, CRUISE

from trials.controllers.base import Observation, Plan


def observe(people: list[tuple[float, float]] = (), walls: np.ndarray | None = None) -> Observation:
    history = np.array([[[x, y]] * 8 for x, y in people], dtype=float).reshape(-1, 8, 2)
    return Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((8, 2)), tuple(range(len(people))),
                       history, np.zeros((0, 2)) if walls is None else walls)


def test_free_space_is_a_straight_line_at_cruising_speed():
    plan = make_controller().plan(observe())
    assert isinstance(plan, Plan) and plan.waypoints.shape == (12, 2)
    np.testing.assert_allclose(plan.waypoints[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.diff(plan.waypoints[:, 0]), CRUISE * 0.4)


def test_a_person_standing_ahead_is_passed_with_room_and_slowly_when_near():
    far = GapKeeper().plan(observe([(3.0, 0.0)]))
    gaps = np.hypot(*(far.waypoints - [3.0, 0.0]).T)
    assert gaps.min() > 1.0 and far.record["speed"] == CRUISE
    near = GapKeeper().plan(observe([(1.0, 0.2)]))
    assert near.record["speed"] == CREEP and math.isclose(near.record["nearest_person_m"], math.hypot(1.0, 0.2))


def test_a_wall_ahead_turns_the_path_away_from_it():
    wall = np.column_stack([np.full(21, 2.0), np.linspace(-0.5, 3.0, 21)])
    plan = GapKeeper().plan(observe(walls=wall))
    assert plan.waypoints[-1, 1] < -0.5


def test_navtrials_finds_it_by_its_entry_point():
    from trials.controllers import registry

    controller = registry.build("GapKeeper")
    controller.reset(7)
    assert controller.plan(observe()).waypoints.shape == (12, 2)
    assert controller.details()["source"].startswith("entry point navtrials-lab-planner 0.1.0")
