"""NaviGAN-R's evasion networks (navigan/evasion.py, navigan/evasion_training.py): the features and
targets on hand-made scenes checked against the shield's own test, the turn that augments
training, the step the networks choose, and a resumed training ending where an uninterrupted one does."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from navigan import checkpoint as ckpt
from navigan.config import EvasionConfig
from navigan.data import load_split
from navigan.errors import NaviganError
from navigan.evasion import (
    CHOICES,
    NEAR,
    OWN,
    PERSON,
    RING,
    Evasion,
    candidates,
    features,
    person_shortfalls,
    turned,
)
from navigan.evasion_training import train_evasion, walk, walk_seed
from navigan.playback.episodes import load_episodes
from navigan.playback.rollout import Policy, roll_out
from navigan.shield import HORIZON, clearance, forecast
from robot_logs.physical import T_OBS

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def scene(others: list[tuple[tuple[float, float], tuple[float, float]]]) -> tuple[np.ndarray, np.ndarray]:
    """A walker at (2, 1) whose last move was 0.1 m along x, and others at positions with last moves."""
    history = np.array([[2.0 + 0.1 * (t - T_OBS + 1), 1.0] for t in range(T_OBS)], np.float32)[None]
    around = np.full((1, len(others), T_OBS, 2), np.nan, np.float32)
    for j, (where, move) in enumerate(others):
        around[0, j, -1] = where
        around[0, j, -2] = np.subtract(where, move)
    return history, around


def test_features_hold_the_nearest_people_within_reach_relative_to_the_walker():
    history, around = scene([((6.0, 1.0), (0.0, 0.1)), ((2.0, 2.0), (-0.1, 0.0)), ((9.0, 1.0), (0.0, 0.0))])
    around[0, 2, -1] = np.nan  # gone now: not seen
    x = features(history, around, np.array([[0.12, 0.0]], np.float32))
    assert x.shape == (1, OWN + NEAR * PERSON)
    np.testing.assert_allclose(x[0, :OWN], [0.12, 0.0, 0.1, 0.0], atol=1e-6)
    people = x[0, OWN:].reshape(NEAR, PERSON)
    np.testing.assert_allclose(people[0], [0.0, 1.0, -0.1, 0.0, 1.0], atol=1e-6)  # 1 m away, first
    np.testing.assert_allclose(people[1], [4.0, 0.0, 0.0, 0.1, 1.0], atol=1e-6)  # 4 m away
    assert not people[2:].any()  # the one gone, and the empty places


def test_each_persons_shortfall_is_the_shields_test_of_that_person():
    # someone standing 0.6 m ahead and someone crossing 1 m to the left, 0.2 m per step toward the walker's path
    history, around = scene([((2.6, 1.0), (0.0, 0.0)), ((2.4, 2.0), (0.0, -0.2))])
    step = np.array([[0.1, 0.0]], np.float32)
    shortfalls, present = person_shortfalls(features(history, around, step), 0.5, HORIZON)
    assert present[0].tolist() == [True, True] + [False] * (NEAR - 2)
    # held 4 steps, the planned 0.1 m along x ends 0.2 m from the one standing: 0.3 m short
    assert shortfalls[0, 0, 0] == pytest.approx(0.3, abs=1e-6)
    assert shortfalls[0, 0, 1] == pytest.approx(0.0)  # standing still keeps 0.6 m
    for j, person in enumerate(([0], [1])):  # each person's shortfall is the shield's against that person alone
        gap = clearance(history[:, -1], candidates(step), forecast(around[:, person], HORIZON))
        np.testing.assert_allclose(shortfalls[0, j], np.clip(0.5 - gap[0], 0, None), atol=1e-5)
    assert not shortfalls[0, 2:].any()


def test_a_turn_permutes_the_choices_as_the_shields_test_does():
    rng = np.random.default_rng(1)
    x = np.zeros((40, OWN + NEAR * PERSON), np.float32)
    x[:, :OWN] = rng.normal(0, 0.3, (40, OWN))
    people = rng.normal(0, 1.0, (40, NEAR, PERSON))
    people[:, :, 4] = rng.random((40, NEAR)) < 0.7
    x[:, OWN:] = people.reshape(40, -1)
    before, _ = person_shortfalls(x, 0.5, HORIZON)
    assert (before > 0).mean() > 0.05
    for turns, mirror in ((1, False), (7, True), (0, True)):
        x_turned, perm = turned(x, turns, mirror)
        assert sorted(perm.tolist()) == list(range(CHOICES)) and perm[:2].tolist() == [0, 1]
        after, _ = person_shortfalls(x_turned, 0.5, HORIZON)
        np.testing.assert_allclose(after[:, :, perm], before, atol=1e-5)
        angle = np.deg2rad(15 * turns)
        transform = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]) @ np.diag(
            [1.0, -1.0 if mirror else 1.0])
        np.testing.assert_allclose(RING[perm[1:] - 1], RING @ transform.T, atol=1e-6)  # each move turned
    np.testing.assert_allclose(turned(x, 24, False)[0], x, atol=1e-5)  # a whole turn


def networks(short: bool, shortfall: dict[int, float]) -> Evasion:
    """Evasion networks whose head says every plan falls short (or none), and whose shortfall
    network predicts about 0 m for every choice but those given."""
    net = Evasion(8)
    with torch.no_grad():
        for module in (net.head, net.shortfall):
            module.pair[-1].weight.zero_()
        net.head.pair[-1].bias.fill_(5.0 if short else -5.0)
        net.shortfall.pair[-1].bias.fill_(-20.0)
        for choice, metres in shortfall.items():
            net.shortfall.pair[-1].bias[choice] = float(np.log(np.expm1(metres))) + net.shortfall.OFFSET
    return net.eval()


def test_the_plan_is_walked_unless_the_head_calls_it_short():
    history, around = scene([((2.6, 1.0), (0.0, 0.0))])
    planned = history[:, -1] + [[0.12, 0.0]]
    np.testing.assert_array_equal(networks(False, {}).steps(history, around, planned), planned)
    # called short with no shortfall predicted anywhere: the move of the ring nearest the plan (0.3 m/s along x)
    np.testing.assert_allclose(networks(True, {}).steps(history, around, planned), planned, atol=1e-6)
    # that move predicted 0.5 m short: one 15 degrees off it costs 0.031 m, less than 10 x 0.5
    walked = networks(True, {2: 0.5}).steps(history, around, planned)[0] - history[0, -1]
    assert np.linalg.norm(walked) == pytest.approx(0.12, abs=1e-6)
    assert abs(np.degrees(np.arctan2(walked[1], walked[0]))) == pytest.approx(15.0, abs=1e-3)


@pytest.fixture(scope="module")
def zara1(eth_ucy_dir):
    """The shipped zara1 NaviGAN-R and eight playback episodes of its test scene."""
    path = ckpt.shipped("navigan-r", "zara1")
    episodes = load_episodes(load_split(eth_ucy_dir, "zara1").test, "observed").subset(range(8))
    return path, episodes


def test_a_walk_labels_every_visited_state_by_the_shields_test(zara1):
    path, episodes = zara1
    policy = Policy.load(path, seed=3)
    states = walk(policy, episodes, margin=0.5)
    walked = roll_out(policy, episodes)
    assert len(states) == walked.steps.sum() > 8 * 10
    first = states.x[:len(episodes)]  # step 0 of every episode: the planned step is where it went
    np.testing.assert_allclose(first[:, :2], walked.paths[:, 1] - walked.paths[:, 0], atol=1e-5)
    assert states.short[:, 1:].any() and set(np.unique(states.short)) <= {0.0, 1.0}


def test_a_head_that_keeps_every_plan_walks_as_the_generator_alone(zara1):
    path, episodes = zara1
    alone = roll_out(Policy.load(path, seed=2), episodes)
    kept = roll_out(Policy(**{**Policy.load(path, seed=2).__dict__, "evasion": networks(False, {})}), episodes)
    np.testing.assert_array_equal(kept.paths, alone.paths)


def without_networks(path) -> ckpt.Checkpoint:
    """A shipped checkpoint with its evasion networks left out."""
    record = ckpt.load(path)
    record.evasion = None
    return record


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_a_resumed_training_ends_where_an_uninterrupted_one_does(zara1, tmp_path):
    path, episodes = zara1
    config = EvasionConfig(rounds=2, epochs=1, batch=64, seed=5, width=16, shortfall_batches=4)
    saved: list[ckpt.Checkpoint] = []
    whole = train_evasion(without_networks(path), path, episodes, config, save=lambda r: saved.append(copy.deepcopy(r)))
    rounds = whole.evasion["rounds"]
    assert [r["round"] for r in rounds] == [0, 1, 2] and whole.evasion["resume"] is None
    assert rounds[0]["states"] == len(walk(Policy.load(path, seed=walk_seed(config, 0)), episodes, 0.5))
    assert rounds[2]["states_total"] == sum(r["states"] for r in rounds)
    assert 0 < rounds[0]["planned_short"] < 1
    assert [s.evasion["weights"] is None for s in saved] == [True, True, False]
    resumed = train_evasion(saved[0], path, episodes, config, save=lambda r: None)
    assert all(torch.equal(resumed.evasion["weights"][k], v) for k, v in whole.evasion["weights"].items())
    assert all(torch.equal(whole.generator[k], v) for k, v in ckpt.load(path).generator.items())  # left as it was
    ckpt.save(whole, tmp_path / "r.pt")
    loaded = ckpt.load(tmp_path / "r.pt").build_evasion()
    x = torch.from_numpy(walk(Policy.load(path), episodes.subset([0]), 0.5).x)
    assert torch.equal(loaded.head(x), whole.build_evasion().head(x))


def test_training_refuses_other_models_settings_and_unfinished_trainings(zara1):
    path, episodes = zara1
    navil2 = ckpt.shipped("navil2", "zara1")
    with pytest.raises(NaviganError, match="for NaviGAN-R only, not navil2"):
        train_evasion(ckpt.load(navil2), navil2, episodes, EvasionConfig(), save=lambda r: None)
    record = ckpt.load(path)
    record.evasion = {"settings": {"rounds": 9}, "rounds": [], "resume": None, "weights": None}
    with pytest.raises(NaviganError, match="evasion networks trained with other settings"):
        train_evasion(record, path, episodes, EvasionConfig(), save=lambda r: None)
    record = without_networks(path)
    record.finished = None
    with pytest.raises(NaviganError, match="starts from a finished training"):
        train_evasion(record, path, episodes, EvasionConfig(), save=lambda r: None)


def test_a_policy_asked_for_networks_a_checkpoint_lacks_is_refused():
    path = ckpt.shipped("navil2", "zara1")
    with pytest.raises(NaviganError, match="has no evasion networks: add them with trials train --evasion"):
        Policy.load(path, evasion=True)
