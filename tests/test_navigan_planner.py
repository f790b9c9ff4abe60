"""The planning API in world coordinates, on the shipped weights."""

from __future__ import annotations

import numpy as np
import pytest

from navigan.data import fill_tracks
from navigan.errors import NaviganError
from navigan.planner import Planner

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def walking(start, velocity, steps: int = 8) -> np.ndarray:
    return np.asarray(start, dtype=float) + np.arange(steps)[:, None] * np.asarray(velocity, dtype=float)


def crowd() -> np.ndarray:
    return np.stack([walking([6.0, 1.0 + i], [-0.5, 0.0]) for i in range(3)])


def test_default_is_the_all_scenes_navigan_r(planner):
    assert planner.model == "navigan-r"
    assert planner.checkpoint.split["name"] == "all"


def test_plan_walks_toward_the_goal(planner):
    history = walking([0.0, 0.0], [0.5, 0.0])
    goal = np.array([9.5, 0.0])
    out = planner.plan(history, crowd(), goal, seed=1)
    assert out.waypoints.shape == out.intention.shape == out.forces.shape == (12, 2)
    np.testing.assert_allclose(out.waypoints, out.intention + out.forces, atol=1e-5)
    assert np.linalg.norm(out.waypoints[-1] - goal) < 1.0
    assert np.all(np.diff(out.waypoints[:, 0]) > 0)  # keeps walking forward


def test_goal_changes_the_plan(planner):
    history = walking([0.0, 0.0], [0.5, 0.0])
    left = planner.plan(history, crowd(), np.array([9.0, 2.0]), seed=1)
    right = planner.plan(history, crowd(), np.array([9.0, -2.0]), seed=1)
    assert left.waypoints[-1, 1] > right.waypoints[-1, 1] + 2.0


def test_seeds_make_noise_reproducible(planner):
    history, goal = walking([0.0, 0.0], [0.5, 0.0]), np.array([9.5, 0.0])
    a = planner.plan(history, crowd(), goal, seed=7)
    b = planner.plan(history, crowd(), goal, seed=7)
    c = planner.plan(history, crowd(), goal, seed=8)
    np.testing.assert_array_equal(a.waypoints, b.waypoints)
    assert not np.array_equal(a.forces, c.forces)
    planner.reset(4)
    first = planner.plan(history, crowd(), goal)
    planner.reset(4)
    np.testing.assert_array_equal(planner.plan(history, crowd(), goal).waypoints, first.waypoints)


def test_agents_seen_late_and_nan_padding(planner):
    history, goal = walking([0.0, 0.0], [0.5, 0.0]), np.array([9.5, 0.0])
    others = crowd()
    late = others.copy()
    late[0, :3] = np.nan  # first seen three steps ago, standing before that
    stood = others.copy()
    stood[0, :3] = others[0, 3]
    padded = np.concatenate([late, np.full((2, 8, 2), np.nan)])
    np.testing.assert_allclose(
        planner.plan(history, padded, goal, seed=2).waypoints,
        planner.plan(history, stood, goal, seed=2).waypoints,
        atol=1e-5,
    )
    alone = planner.plan(history, np.zeros((0, 8, 2)), goal, seed=2)
    assert alone.waypoints.shape == (12, 2)


def test_fill_tracks():
    tracks = np.full((1, 2, 4, 2), np.nan)
    tracks[0, 0, 2:] = [[1.0, 1.0], [2.0, 2.0]]
    filled, present = fill_tracks(tracks)
    assert present.tolist() == [[True, False]]
    np.testing.assert_array_equal(filled[0, 0], [[1, 1], [1, 1], [1, 1], [2, 2]])


def test_batch_rows_equal_single_plans():
    planner = Planner("navil2-eth")  # no fluctuation noise: rows are comparable
    histories = np.stack([walking([0.0, 0.0], [0.5, 0.0]), walking([3.0, 3.0], [0.0, -0.4])])
    others = np.full((2, 3, 8, 2), np.nan)
    others[0] = crowd()
    others[1, 0] = walking([3.0, -2.0], [0.0, 0.4])
    goals = np.array([[9.5, 0.0], [3.0, -2.0]])
    batch = planner.plan_batch(histories, others, goals)
    assert batch.waypoints.shape == (2, 12, 2)
    for i in range(2):
        single = planner.plan(histories[i], others[i], goals[i])
        np.testing.assert_allclose(batch.waypoints[i], single.waypoints, atol=1e-5)


def test_bad_input_is_a_clear_error(planner):
    history = walking([0.0, 0.0], [0.5, 0.0])
    with pytest.raises(NaviganError, match=r"histories: expected shape \(B, 8, 2\)"):
        planner.plan(history[:5], crowd(), np.zeros(2))
    with pytest.raises(NaviganError, match="goals: expected shape"):
        planner.plan(history, crowd(), np.zeros(3))
    broken = history.copy()
    broken[0, 0] = np.nan
    with pytest.raises(NaviganError, match="target's history or goal holds NaN"):
        planner.plan(broken, crowd(), np.zeros(2))
    with pytest.raises(NaviganError, match="no checkpoint at"):
        Planner("no-such-model")
