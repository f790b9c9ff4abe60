"""The playback scores on hand-made episodes: collision, near miss, arrival, comfort boundary, path measures,
and the two ways of measuring distances (at the recorded frames, or within each step)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navigan.playback.metrics import Scoring, score_episode, step_distances
from navigan.playback.protocols import FRAMES

STEP = 0.4  # metres per step along x in these episodes: 1 m/s at 0.4 s a step


def straight(steps: int) -> np.ndarray:
    """(steps + 1, 2) a walk along +x, STEP metres a step, from the origin."""
    return np.stack([np.arange(steps + 1) * STEP, np.zeros(steps + 1)], axis=1)


def standing(point: tuple[float, float], steps: int) -> np.ndarray:
    """(steps + 1, 1, 2) one other agent standing still."""
    return np.tile(np.asarray(point, dtype=float), (steps + 1, 1, 1))


def score(path, others, goal, recorded=None, scoring=Scoring()):
    recorded = path if recorded is None else recorded
    return score_episode(path, others, np.asarray(goal, dtype=float), recorded, np.array([STEP, 0.0]), scoring)


FAR_GOAL = (100.0, 0.0)


def test_arrival_at_step_k_scores_the_discounted_goal_reward():
    k = 10
    path = straight(k)
    goal = (k * STEP + 0.3, 0.0)  # within 0.5 m only after step k
    s = score(path, standing((0.0, 50.0), k), goal)
    assert s.arrived and s.comfortable and not s.collided
    assert s.steps == k and s.time_to_goal == pytest.approx(k * 0.4)
    assert s.social_score == pytest.approx(0.9 ** ((k - 1) * 0.4 * 1.0), abs=1e-12)
    slower = score(path, standing((0.0, 50.0), k), goal, scoring=Scoring(gamma=0.95, v_pref=0.5))
    assert slower.social_score == pytest.approx(0.95 ** ((k - 1) * 0.4 * 0.5), abs=1e-12)


def test_walk_beyond_the_arrival_is_cut_at_the_arrival():
    path = straight(20)
    s = score(path, standing((0.0, 50.0), 20), (10 * STEP, 0.0))
    assert s.steps == 9  # step 9 ends at 3.6 m, 0.4 m from the goal
    assert s.path_length == pytest.approx(9 * STEP)


def test_near_miss_at_0_15_m_is_uncomfortable_and_costs_its_step():
    n = 8
    path = straight(n)
    # standing 0.15 m off the line, passed halfway through step 3 (x from 0.8 to 1.2)
    s = score(path, standing((1.0, 0.15), n), FAR_GOAL)
    assert not s.comfortable and not s.collided and not s.arrived
    assert s.min_distance == pytest.approx(0.15)
    assert s.social_score == pytest.approx((-0.1 + 0.15 / 2) * 0.9 ** (2 * 0.4), abs=1e-12)
    distances = step_distances(path, standing((1.0, 0.15), n))
    assert distances[2] == pytest.approx(0.15)
    assert distances[1] == pytest.approx(math.hypot(0.2, 0.15)) == distances[3]


def test_collision_scores_minus_a_quarter_and_fails_comfort():
    n = 6
    path = straight(n)
    s = score(path, standing((1.0, 0.05), n), FAR_GOAL)
    assert s.collided and not s.comfortable
    assert s.social_score == pytest.approx(-0.25 * 0.9 ** (2 * 0.4), abs=1e-12)
    lenient = score(path, standing((1.0, 0.05), n), FAR_GOAL, scoring=Scoring(collision=0.01))
    assert not lenient.collided
    assert lenient.social_score == pytest.approx((-0.1 + 0.05 / 2) * 0.9 ** (2 * 0.4), abs=1e-12)


def test_near_miss_then_arrival_adds_both_discounted_rewards():
    k = 12
    path = straight(k)
    s = score(path, standing((1.0, 0.15), k), (k * STEP + 0.1, 0.3))
    expected = (-0.1 + 0.075) * 0.9 ** (2 * 0.4) + 1.0 * 0.9 ** ((k - 1) * 0.4)
    assert s.arrived and s.steps == k
    assert s.social_score == pytest.approx(expected, abs=1e-12)


def test_exactly_0_2_m_is_still_comfortable():
    n = 6
    path = np.stack([np.arange(n + 1) * 0.5, np.zeros(n + 1)], axis=1)  # binary-exact positions
    s = score(path, standing((1.0, 0.2), n), FAR_GOAL)
    assert s.min_distance == 0.2
    assert s.comfortable and s.social_score == 0.0
    assert not score(path, standing((1.0, 0.19), n), FAR_GOAL).comfortable


def test_crossing_agents_meet_between_samples():
    """Two walkers crossing at right angles meet halfway through step 3, 0.28 m apart at its ends."""
    n = 4
    path = straight(n)
    other = np.stack([np.full(n + 1, 1.0), 1.0 - np.arange(n + 1) * STEP], axis=1)[:, None]
    assert step_distances(path, other)[2] == pytest.approx(0.0, abs=1e-9)
    sampled = np.linalg.norm(other[:, 0] - path, axis=-1).min()
    assert sampled > 0.2
    assert score(path, other, FAR_GOAL).collided


def test_a_crossing_closer_than_0_2_m_only_between_frames_fails_comfort_only_when_interpolated():
    """The target walks +x at 0.4 m a step; the other walks -y along x = 1.15 at the same pace. Relative
    to the target the other moves by (-0.4, -0.4) a step: from (0.35, 0.2) at frame 2 to (-0.05, -0.2)
    at frame 3, passing closest at a fraction 0.22 / 0.32 = 0.6875 of step 3, at (0.075, -0.075)."""
    n = 5
    path = straight(n)
    other = np.stack([np.full(n + 1, 1.15), 1.0 - np.arange(n + 1) * STEP], axis=1)[:, None]
    between = math.hypot(0.075, 0.075)  # 0.1061 m: uncomfortable, not a collision (0.1 m)
    at_frame_3 = math.hypot(0.05, 0.2)  # 0.2062 m: the nearest recorded frame, comfortable

    interpolated = score(path, other, FAR_GOAL)
    assert step_distances(path, other)[2] == pytest.approx(between)
    assert interpolated.min_distance == pytest.approx(between)
    assert not interpolated.comfortable and not interpolated.collided
    assert interpolated.social_score == pytest.approx((-0.1 + between / 2) * 0.9 ** (2 * 0.4), abs=1e-9)

    frames = score(path, other, FAR_GOAL, scoring=Scoring(distances=FRAMES))
    assert step_distances(path, other, FRAMES) == pytest.approx(
        [math.hypot(0.75, 0.6), math.hypot(0.35, 0.2), at_frame_3, math.hypot(0.45, 0.6), math.hypot(0.85, 1.0)])
    assert frames.min_distance == pytest.approx(at_frame_3)
    assert frames.comfortable and not frames.collided and frames.social_score == 0.0


def test_frames_ignore_time_0_and_who_is_absent_at_a_frame():
    n = 3
    path = straight(n)
    others = np.full((n + 1, 2, 2), np.nan)
    others[0, 0] = (0.0, 0.05)   # beside the target at time 0 only: not a step's frame
    others[2, 1] = (0.8, 0.1)    # at step 2's frame only
    assert step_distances(path, others, FRAMES) == pytest.approx([math.inf, 0.1, math.inf])
    assert np.isinf(step_distances(path, np.full((n + 1, 1, 2), np.nan), FRAMES)).all()


def test_agents_seen_at_one_end_of_a_step_count_there_only():
    n = 3
    path = straight(n)
    others = np.full((n + 1, 2, 2), np.nan)
    others[2:, 0] = (0.8, 0.1)   # appears at step 2's end, 0.1 m from the target then
    others[:, 1] = (0.0, 30.0)   # far away all along
    distances = step_distances(path, others)
    assert distances[0] == pytest.approx(30.0, rel=1e-3)
    assert distances[1] == pytest.approx(0.1)  # only its end-of-step instant
    alone = step_distances(path, np.full((n + 1, 1, 2), np.nan))
    assert np.isinf(alone).all()
    assert math.isinf(score(path, np.full((n + 1, 1, 2), np.nan), FAR_GOAL).min_distance)


def test_path_ratio_ade_and_irregularity():
    # the recorded path walks an L (4 steps along x, then 4 along y); the walked one cuts the corner
    recorded = np.concatenate([straight(4), np.stack([np.full(4, 1.6), np.arange(1, 5) * STEP], axis=1)])
    goal = recorded[-1]
    walked = np.linspace(recorded[0], goal, 7)
    s = score(walked, standing((50.0, 50.0), 6), goal, recorded=recorded)
    assert s.arrived
    human_length = 8 * STEP - 0.4  # the recording reaches 0.5 m of the goal one step early
    assert s.path_ratio == pytest.approx(np.linalg.norm(walked[s.steps] - walked[0]) / human_length)
    expected_ade = np.mean(np.linalg.norm(walked[1 : s.steps + 1] - recorded[1 : s.steps + 1], axis=-1))
    assert s.ade == pytest.approx(expected_ade)
    # a straight walk along its observed heading turns 0; the L turns pi/2 over 3.2 m
    assert score(straight(5), standing((0, 50), 5), FAR_GOAL).irregularity == 0.0
    turn = score(recorded, standing((50.0, 50.0), 8), (20.0, 20.0), recorded=recorded).irregularity
    assert turn == pytest.approx((math.pi / 2) / (8 * STEP))
