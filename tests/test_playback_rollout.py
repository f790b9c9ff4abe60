"""Playback episodes and roll-outs on the real zara1 test scene with the shipped NaviGAN-R weights."""

from __future__ import annotations

import numpy as np
import pytest

from navigan import checkpoint as ckpt
from navigan.data import load_split
from navigan.goals import toward
from navigan.playback.episodes import GOAL_STEPS, SceneGrid, episodes_of, load_episodes
from navigan.playback.evaluate import Playback, Settings, score_rollout
from navigan.playback.metrics import Scoring
from navigan.playback.protocols import OBSERVED, PRESENT
from navigan.playback.rollout import RECORDED, Policy, neighbours, recorded_rollout, roll_out
from navigan.shield import shielded_steps

WEIGHTS = ckpt.WEIGHTS_DIR / "navigan-r-zara1.pt"


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def zara1(eth_ucy_dir):
    return load_episodes(load_split(eth_ucy_dir, "zara1").test, PRESENT)


@pytest.fixture(scope="module")
def few(zara1):
    return zara1.subset(range(6))


def test_episodes_follow_the_protocol(zara1):
    assert len(zara1) == 19 and zara1.standing == 0
    assert len(set(zara1.ids)) == 19
    history = zara1.history()
    for e in range(len(zara1)):
        recorded = zara1.recorded(e)
        np.testing.assert_array_equal(history[e, -1], recorded[0])
        np.testing.assert_array_equal(zara1.goal[e], recorded[GOAL_STEPS])
        assert zara1.steps[e] <= 60 and not np.isnan(history[e]).any()
        assert np.linalg.norm(zara1.goal[e] - recorded[0]) > 0.5
        assert zara1.pace[e] == pytest.approx(np.linalg.norm(zara1.goal[e] - recorded[0]) / 14.4)


def test_who_makes_an_episode():
    frames = 50
    positions = np.full((frames, 3, 2), np.nan, dtype=np.float32)
    positions[:, 0] = np.stack([np.arange(frames) * 0.4, np.zeros(frames)], axis=1)  # walks all along
    positions[:, 1] = (5.0, 5.0)  # stands all along
    positions[10:40, 2] = (1.0, 1.0)  # leaves before its goal time
    episodes = episodes_of([SceneGrid("toy.txt", np.array([1, 2, 3]), positions)], PRESENT)
    assert episodes.ids == ["toy.txt:1"] and episodes.standing == 1
    assert episodes.start[0] == 7 and episodes.steps[0] == min(60, frames - 1 - 7)
    np.testing.assert_allclose(episodes.goal[0], [(7 + 36) * 0.4, 0.0])
    assert episodes.goal_steps[0] == 36 and episodes.pace[0] == pytest.approx(1.0)  # 0.4 m per 0.4 s


def test_the_observed_protocol_takes_targets_that_leave_early_with_their_last_position_as_goal():
    frames = 50
    positions = np.full((frames, 4, 2), np.nan, dtype=np.float32)
    positions[:, 0] = np.stack([np.arange(frames) * 0.4, np.zeros(frames)], axis=1)  # walks all along
    positions[10:40, 1] = np.stack([np.arange(30) * 0.2, np.ones(30)], axis=1)  # leaves after 30 frames
    positions[5:24, 2] = (2.0, 2.0)  # 19 frames: one short of T_obs + T_pred
    positions[30:, 3] = np.stack([np.zeros(20), np.arange(20) * 0.4], axis=1)  # there until the recording ends
    episodes = episodes_of([SceneGrid("toy.txt", np.array([1, 2, 3, 4]), positions)], OBSERVED)
    assert episodes.ids == ["toy.txt:1", "toy.txt:2", "toy.txt:4"] and episodes.standing == 0
    assert episodes.start.tolist() == [7, 17, 37] and episodes.goal_steps.tolist() == [36, 22, 12]
    np.testing.assert_allclose(episodes.goal[1], [29 * 0.2, 1.0])  # its last recorded position, frame 39
    np.testing.assert_allclose(episodes.goal[2], [0.0, 19 * 0.4])  # the recording's last frame
    assert episodes.pace[1] == pytest.approx(22 * 0.2 / (22 * 0.4))  # its own pace to where it left
    # the default protocol keeps only the pedestrian present for 44 frames
    assert episodes_of([SceneGrid("toy.txt", np.array([1, 2, 3, 4]), positions)], PRESENT).ids == ["toy.txt:1"]


@pytest.mark.slow
def test_batched_and_one_at_a_time_roll_outs_agree(few):
    for dagger, shield in ((False, None), (True, None), (False, 0.5)):
        policy = Policy.load(WEIGHTS, dagger=dagger, seed=3, shield=shield)
        batched = roll_out(policy, few)
        for e in range(len(few)):
            alone = roll_out(policy, few.subset([e]))
            assert alone.steps[0] == batched.steps[e]
            np.testing.assert_allclose(alone.path(0), batched.path(e), atol=1e-4, rtol=0)
        scores = score_rollout(few, batched, Scoring())
        singles = [score_rollout(few.subset([e]), roll_out(policy, few.subset([e])), Scoring())[0]
                   for e in range(len(few))]
        for a, b in zip(scores, singles):
            assert (a["arrived"], a["comfortable"], a["collided"], a["steps"]) == \
                   (b["arrived"], b["comfortable"], b["collided"], b["steps"])
            assert a["social_score"] == pytest.approx(b["social_score"], abs=1e-5)  # stored to 6 decimals


def test_noise_comes_from_the_seed_and_episode(few):
    policy = Policy.load(WEIGHTS, seed=1)
    names = few.ids
    table = policy.noise(names)
    assert table.shape == (len(names), 60, 8)
    np.testing.assert_array_equal(policy.noise(names[::-1])[::-1], table)  # order does not matter
    np.testing.assert_array_equal(policy.noise(names[2:3])[0], table[2])
    assert not np.allclose(Policy.load(WEIGHTS, seed=2).noise(names), table)
    assert Policy.load(WEIGHTS.with_name("navil2-zara1.pt")).noise(names) is None  # NaviL2 runs without z
    a = roll_out(policy, few)
    np.testing.assert_array_equal(roll_out(Policy.load(WEIGHTS, seed=1), few).paths, a.paths)
    reordered = roll_out(policy, few.subset([5, 4, 3, 2, 1, 0]))
    np.testing.assert_allclose(reordered.paths[::-1], a.paths, atol=1e-4)


def test_full_walks_the_way_points_and_dagger_the_intention(few):
    first = few.subset([0])
    history = first.history()
    assert np.linalg.norm(first.goal - history[:, -1]) == pytest.approx(3.39, abs=0.01)
    own = toward(history[:, -1], first.goal, first.pace[:, None] * 4.8)  # 12 steps at the recorded pace
    assert np.linalg.norm(own - history[:, -1]) == pytest.approx(3.39 / 14.4 * 4.8, abs=0.01)
    fast = toward(history[:, -1], first.goal, 4.8)  # 12 steps at 1 m/s: beyond the goal
    assert np.linalg.norm(fast - history[:, -1]) == pytest.approx(4.8)
    for speed, goal in ((RECORDED, own), (1.0, fast), (None, first.goal)):
        for dagger in (False, True):
            policy = Policy.load(WEIGHTS, dagger=dagger)
            waypoints, intention, forces = policy.plan(history, neighbours(first, np.array([0]), 0), goal,
                                                       policy.noise(first.ids)[:, 0])
            np.testing.assert_allclose(waypoints, intention + forces, atol=1e-5)
            walked = roll_out(policy, first, record=True, subgoal_speed=speed)
            expected = intention if dagger else waypoints
            np.testing.assert_allclose(walked.paths[0, 1], expected[0, 0], atol=1e-6)
            np.testing.assert_allclose(walked.plans[0, 0, 1], intention[0], atol=1e-6)


def test_a_shield_checks_the_first_step_and_keeps_zara1_comfortable(zara1, few):
    first = few.subset([0])
    policy = Policy.load(WEIGHTS, shield=3.0)  # so wide that the planned step cannot keep it
    around = neighbours(first, np.array([0]), 0)
    goal = toward(first.history()[:, -1], first.goal, first.pace[:, None] * 4.8)
    waypoints, _, _ = policy.plan(first.history(), around, goal, policy.noise(first.ids)[:, 0])
    checked = shielded_steps(first.history()[:, -1], waypoints[:, 0], around, 3.0)
    assert np.linalg.norm(checked - waypoints[:, 0]) > 0.05
    np.testing.assert_allclose(roll_out(policy, first).paths[0, 1], checked[0], atol=1e-6)
    comfortable = {}
    for shield in (None, 0.5):
        walked = roll_out(Policy.load(WEIGHTS, shield=shield), zara1)
        comfortable[shield] = sum(r["comfortable"] for r in score_rollout(zara1, walked, Scoring()))
    assert comfortable == {None: 18, 0.5: 19}


def test_a_subgoal_lies_one_reach_toward_the_goal_even_past_it():
    position = np.array([[1.0, 1.0], [0.0, 0.0]])
    goals = np.array([[11.0, 1.0], [0.0, -2.0]])
    np.testing.assert_allclose(toward(position, goals, 4.8), [[5.8, 1.0], [0.0, -4.8]])
    np.testing.assert_allclose(toward(position[0], goals[0], 2.0), [3.0, 1.0])


def test_human_row_is_the_recording_itself(eth_ucy_dir, zara1, tmp_path):
    # read the file independently of the grid code
    rows = np.loadtxt(eth_ucy_dir / "all_data" / "crowds_zara01.txt")
    human = recorded_rollout(zara1)
    for e, name in enumerate(zara1.ids):
        ped = float(name.split(":")[1])
        track = rows[rows[:, 1] == ped]
        track = track[np.argsort(track[:, 0])]
        start = int(np.flatnonzero(np.all(np.isclose(track[:, 2:], zara1.history()[e, -1], atol=1e-5), axis=1))[0])
        np.testing.assert_allclose(human.path(e), track[start : start + human.steps[e] + 1, 2:], atol=1e-5)
        assert np.linalg.norm(human.path(e)[-1] - zara1.goal[e]) <= 0.5
        assert human.steps[e] <= GOAL_STEPS
    # no weights needed: an empty checkpoint folder is fine for the human row
    (tmp_path / "none").mkdir()
    playback = Playback(data=eth_ucy_dir, out=tmp_path / "out", checkpoints=tmp_path / "none",
                        settings=Settings(limit=5))
    table = playback.evaluate(["zara1"], ["human"], progress=False)[0]
    assert table.values["human"]["A"] == 1.0 and table.values["human"]["ade_m"] == 0.0
    assert table.values["human"]["path_ratio"] == pytest.approx(1.0)
