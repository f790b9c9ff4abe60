"""Closed-loop tuning (navigan/closed_loop.py): its terms on a hand-made state, the states a walk
records, and a resumed tuning ending where an uninterrupted one does."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from navigan import checkpoint as ckpt
from navigan.closed_loop import States, losses, tune, visited, walk_seed
from navigan.config import ClosedLoopConfig
from navigan.data import load_split
from navigan.errors import NaviganError
from navigan.generators import Prediction
from navigan.playback.episodes import load_episodes
from navigan.playback.rollout import Policy, roll_out
from robot_logs.physical import T_OBS, T_PRED

pytestmark = pytest.mark.usefixtures("one_torch_thread")


class Planned(torch.nn.Module):
    """A generator that plans the same way-points whatever it sees."""

    def __init__(self, waypoints: np.ndarray) -> None:
        super().__init__()
        self.waypoints = torch.nn.Parameter(torch.as_tensor(waypoints, dtype=torch.float32))

    def forward(self, obs, mask, goals, targets=None, noise=None) -> Prediction:
        return Prediction(self.waypoints, self.waypoints, torch.zeros_like(self.waypoints))


def standing_walker_state(kept: bool) -> tuple[Planned, States]:
    """A walker standing at the origin that plans 0.1 m per step along x, toward someone standing
    0.6 m ahead; the teacher planned the same 0.1 m to the left."""
    plan = np.arange(1, T_PRED + 1)[:, None] * np.array([0.1, 0.0])
    around = np.full((1, 1, T_OBS, 2), [0.6, 0.0], dtype=np.float32)
    state = States(np.zeros((1, T_OBS, 2), np.float32), around, np.array([[5.0, 0.0]], np.float32),
                   np.zeros((1, 8), np.float32), (plan + [0.0, 0.1])[None].astype(np.float32), np.array([kept]))
    return Planned(plan[None]), state


def test_terms_on_a_hand_made_state():
    generator, state = standing_walker_state(kept=True)
    terms = losses(generator, state, margin=0.5)
    # the first step held 4 steps ends 0.5, 0.4, 0.3, 0.2 m from the one standing: short by 0, 0.1, 0.2, 0.3
    assert terms["hinge"].item() == pytest.approx(0.1**2 + 0.2**2 + 0.3**2, abs=1e-6)
    assert terms["first"].item() == pytest.approx(0.01, abs=1e-7)
    assert terms["rest"].item() == pytest.approx(0.01, abs=1e-7)
    terms["hinge"].backward()
    assert generator.waypoints.grad[0, 0, 0] > 0 and not generator.waypoints.grad[0, 1:].any()  # hinge: back off


def test_a_step_the_shield_replaces_answers_to_the_hinge_alone():
    generator, state = standing_walker_state(kept=False)
    terms = losses(generator, state, margin=0.5)
    assert terms["first"].item() == 0.0 and terms["hinge"].item() == pytest.approx(0.14, abs=1e-6)


@pytest.fixture(scope="module")
def zara1(eth_ucy_dir):
    """The shipped zara1 NaviGAN-R and six playback episodes of its test scene."""
    path = ckpt.shipped("navigan-r", "zara1")
    episodes = load_episodes(load_split(eth_ucy_dir, "zara1").test, "observed").subset(range(6))
    return path, episodes


def test_walk_records_every_state_with_the_teachers_plan(zara1):
    path, episodes = zara1
    policy = Policy.load(path, seed=3)
    parts = visited(policy, policy, episodes, margin=0.5)
    walked = roll_out(policy, episodes)
    assert sum(len(p) for p in parts) == walked.steps.sum() > 6 * 10
    # the teacher walking: each state's planned first way-point is where the walker went next
    np.testing.assert_allclose(parts[0].teacher[:, 0], walked.paths[:, 1], atol=1e-6)
    np.testing.assert_allclose(parts[1].histories[:, -1], walked.paths[:, 1], atol=1e-6)
    # the widest crowd at time 0: everyone present at an episode's first frame but its target
    widest = max(np.count_nonzero(~np.isnan(episodes.scenes[s].positions[f, :, 0])) - 1
                 for s, f in zip(episodes.scene, episodes.start))
    assert widest > 0 and parts[0].around.shape[1:] == (widest, T_OBS, 2)


def test_a_resumed_tuning_ends_where_an_uninterrupted_one_does(zara1):
    path, episodes = zara1
    config = ClosedLoopConfig(rounds=2, epochs=1, batch=64, seed=5)
    saved: list[ckpt.Checkpoint] = []
    whole = tune(ckpt.load(path), path, episodes, config, save=lambda r: saved.append(copy.deepcopy(r)))
    assert [r["round"] for r in whole.closed_loop["rounds"]] == [1, 2] and whole.closed_loop["resume"] is None
    assert ckpt.load(path).evasion is not None and whole.evasion is None  # the shipped networks fit the old weights
    first, second = whole.closed_loop["rounds"]
    assert first["states"] == first["states_total"] == sum(len(p) for p in visited(
        Policy.load(path, seed=walk_seed(config, 1)), Policy.load(path), episodes, config.margin))  # round 1 walks the teacher
    assert second["states_total"] == first["states"] + second["states"]
    start = ckpt.load(path).generator
    after_one = saved[0]
    assert all(torch.equal(after_one.generator[k], start[k]) for k in start)  # the teacher's until the last round
    resumed = tune(after_one, path, episodes, config, save=lambda r: None)
    assert all(torch.equal(resumed.generator[k], whole.generator[k]) for k in start)
    changed = [k for k in start if not torch.equal(whole.generator[k], start[k])]
    assert changed and not any(k.startswith("intention_") for k in changed)  # the social-force branch alone


def test_tuning_refuses_other_models_and_walks_without_noise(zara1):
    path, episodes = zara1
    navil2 = ckpt.shipped("navil2", "zara1")
    with pytest.raises(NaviganError, match="tunes NaviGAN-R only, not navil2"):
        tune(ckpt.load(navil2), navil2, episodes, ClosedLoopConfig(), save=lambda r: None)
    without_noise = Policy.load(navil2)
    with pytest.raises(NaviganError, match="needs a model with fluctuation noise"):
        visited(without_noise, Policy.load(path), episodes, margin=0.5)


def test_tuning_refuses_other_settings_and_unfinished_trainings(zara1):
    path, episodes = zara1
    record = ckpt.load(path)
    record.closed_loop = {"settings": {"rounds": 9}, "rounds": [], "resume": None}
    with pytest.raises(NaviganError, match="closed-loop tuning with other settings"):
        tune(record, path, episodes, ClosedLoopConfig(), save=lambda r: None)
    record = ckpt.load(path)
    record.finished = None
    with pytest.raises(NaviganError, match="starts from a finished training"):
        tune(record, path, episodes, ClosedLoopConfig(), save=lambda r: None)
