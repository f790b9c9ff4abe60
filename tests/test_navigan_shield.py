"""The constant-velocity check of a plan's first step, on hand-made walkers."""

from __future__ import annotations

import numpy as np
import pytest

from navigan.shield import HORIZON, MOVES, forecast, shielded_steps
from robot_logs.physical import STEP_S


def track(now: tuple[float, float], move: tuple[float, float]) -> np.ndarray:
    """(8, 2) a walker's last 8 positions, ending at `now`, one `move` per step."""
    return np.asarray(now) + np.arange(-7, 1)[:, None] * np.asarray(move)


def closest(position: np.ndarray, step: np.ndarray, others: np.ndarray, horizon: int = HORIZON) -> float:
    """The closest approach over the horizon of `step` held from `position`, by plain loops."""
    best = np.inf
    for other in others:
        if np.isnan(other[-1, 0]):
            continue
        move = np.zeros(2) if np.isnan(other[-2, 0]) else other[-1] - other[-2]
        for k in range(1, horizon + 1):
            best = min(best, float(np.linalg.norm(position + k * step - (other[-1] + k * move))))
    return best


def test_forecast_keeps_the_last_move_and_holds_the_newly_seen_still():
    others = np.full((1, 3, 8, 2), np.nan)
    others[0, 0] = track((1.0, 0.0), (0.4, 0.0))
    others[0, 1, -1] = (2.0, 2.0)  # seen only now
    ahead = forecast(others, 3)
    np.testing.assert_allclose(ahead[0, 0], [[1.4, 0.0], [1.8, 0.0], [2.2, 0.0]])
    np.testing.assert_allclose(ahead[0, 1], [[2.0, 2.0]] * 3)
    assert np.isnan(ahead[0, 2]).all()  # absent now: no forecast


def test_a_step_that_keeps_its_distance_is_walked_as_planned():
    position, planned = np.zeros((1, 2)), np.array([[0.4, 0.0]])
    others = np.full((1, 2, 8, 2), np.nan)
    others[0, 0] = track((0.0, 2.0), (0.4, 0.0))  # walks alongside, 2 m away
    others[0, 1, :-1] = track((0.8, 0.0), (-0.4, 0.0))[:-1]  # gone now: ignored, though it was head-on
    np.testing.assert_array_equal(shielded_steps(position, planned, others, margin=0.5), planned)


def test_head_on_the_nearest_move_that_keeps_the_margin_is_taken():
    position, planned = np.zeros((1, 2)), np.array([[0.4, 0.0]])
    others = track((1.5, 0.0), (-0.4, 0.0))[None, None]  # 1.5 m ahead, walking straight at us
    assert closest(position[0], planned[0], others[0]) == pytest.approx(0.1)
    step = shielded_steps(position, planned, others, margin=0.5)[0] - position[0]
    assert closest(position[0], step, others[0]) >= 0.5
    keeping = [m * STEP_S for m in MOVES if closest(position[0], m * STEP_S, others[0]) >= 0.5]
    change = np.linalg.norm(step - planned[0])
    assert change == pytest.approx(min(np.linalg.norm(m - planned[0]) for m in keeping))
    assert 0.1 < change < 0.6


def test_someone_standing_in_the_way_is_avoided_and_each_walker_is_checked_alone():
    positions = np.array([[0.0, 0.0], [10.0, 0.0]])
    planned = positions + (0.4, 0.0)
    others = np.full((2, 1, 8, 2), np.nan)
    others[0, 0, -1] = (0.9, 0.0)  # first seen now, 0.9 m ahead of walker 0: held still
    others[1, 0] = track((10.0, 5.0), (0.0, 0.4))  # far from walker 1
    steps = shielded_steps(positions, planned, others, margin=0.5)
    assert closest(positions[0], steps[0] - positions[0], others[0]) >= 0.5
    assert not np.allclose(steps[0], planned[0])
    np.testing.assert_array_equal(steps[1], planned[1])
