"""Encounter rows: a walker on a (near) collision course with one real agent, training only the social force."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from navigan import encounters
from navigan.config import ModelConfig, TrainConfig
from navigan.data import Sampling, Scenes
from navigan.encounters import encounter_batch
from navigan.generators import Prediction, build_generator
from navigan.losses import encounter_losses
from robot_logs.physical import STEP_S, T_OBS, T_PRED


@pytest.fixture(scope="module")
def batch(eth_ucy_dir):
    scenes = Scenes.from_files([eth_ucy_dir / "val" / "crowds_zara02_val.txt"])
    return scenes.batch(np.arange(0, len(scenes.counts), 3), Sampling((8, 36)), np.random.default_rng(0))


@pytest.fixture(scope="module")
def rows(batch):
    made = encounter_batch(batch, 1.0, (8, 36), np.random.default_rng(1))
    assert made is not None
    return made


def test_each_row_is_one_walker_beside_at_most_one_agent(batch, rows):
    assert (rows.targets.sum(dim=1) == 1).all()
    company = rows.mask.sum(dim=1)
    assert set(company.tolist()) <= {1, 2}
    alone = (company == 1).float().mean().item()
    assert 0.5 * encounters.ALONE < alone < 2 * encounters.ALONE
    assert len(rows.goals) > 0.8 * batch.targets.sum().item()  # nearly every target has an agent to meet


def test_walkers_walk_straight_at_a_steady_pace_toward_goals_beyond_the_meeting(rows):
    b, a = rows.targets.nonzero(as_tuple=True)
    history = rows.obs[b, a]
    moves = history.diff(dim=1)
    torch.testing.assert_close(moves, moves[:, :1].expand_as(moves), atol=1e-4, rtol=0)
    stride = moves[:, 0]
    pace = stride.norm(dim=-1) / STEP_S
    walking = pace > 0
    assert walking.any() and (~walking).any()  # walkers of standing targets stand
    assert (pace[walking] >= encounters.STANDING - 1e-4).all() and (pace <= encounters.MAX_PACE + 1e-4).all()
    ahead = rows.goals - history[:, -1]
    steps_to_goal = ahead[walking].norm(dim=-1) / stride[walking].norm(dim=-1)
    assert (steps_to_goal >= 8 - 1e-3).all() and (steps_to_goal <= 36 + 1e-3).all()
    cross = ahead[walking, 0] * stride[walking, 1] - ahead[walking, 1] * stride[walking, 0]
    assert (cross.abs() / ahead[walking].norm(dim=-1) < 1e-3).all()
    assert (ahead[~walking].norm(dim=-1) > 8 * encounters.STANDING_PACE[0] * STEP_S - 1e-3).all()


def test_the_straight_line_passes_its_agent_within_the_offset(rows):
    b, a = rows.targets.nonzero(as_tuple=True)
    others, present = rows.neighbours()
    company = present.any(dim=-1).any(dim=-1)
    history = rows.obs[b, a]
    line = history[:, -1:] + (history[:, -1] - history[:, -2])[:, None] * torch.arange(1, T_PRED + 1)[None, :, None]
    # (a standing walker's line is its position: the agent passes it)
    gap = torch.where(present, (others - line[:, None]).norm(dim=-1), torch.inf).amin(dim=(1, 2))
    assert (gap[company] <= encounters.PASS_OFFSET + 1e-3).all()
    assert (gap[company] < 0.5).float().mean() > 0.6 * min(1.0, 0.5 / encounters.PASS_OFFSET)  # these need room


def test_encounter_terms_train_only_the_social_force(rows):
    torch.manual_seed(0)
    generator = build_generator(ModelConfig("navigan-r"))
    prediction = generator(rows.obs, rows.mask, rows.goals, targets=rows.targets)
    terms = encounter_losses(prediction, rows, TrainConfig("zara2"))
    assert terms["encounter_resistance"].item() > 0
    (terms["encounter_l2"] + terms["encounter_resistance"]).backward()
    for name, parameter in generator.named_parameters():
        touched = parameter.grad is not None and parameter.grad.abs().sum().item() > 0
        assert touched == (not name.startswith("intention")), name


def test_the_force_term_scores_mostly_changes_so_a_held_side_step_costs_little_more_than_its_start(rows):
    """A side-step of 0.6 m taken at once and held for all 12 steps against the same jump out and back."""
    k = len(rows.goals)
    intention = torch.zeros(k, T_PRED, 2)
    held = torch.zeros(k, T_PRED, 2)
    held[:, :, 1] = 0.6
    bump = torch.zeros(k, T_PRED, 2)
    bump[:, 5, 1] = 0.6
    for size in (0.1, 1.0):
        config = TrainConfig("zara2", force_size=size)
        for force, cost in ((held, 0.36 * (1 + size * T_PRED)), (bump, 0.36 * (2 + size))):
            prediction = Prediction(intention + force, intention, force)
            assert encounter_losses(prediction, rows, config)["encounter_l2"].item() == pytest.approx(cost / T_PRED)


def test_no_rows_when_nobody_is_asked_for(batch):
    assert encounter_batch(batch, 0.0, (8, 36), np.random.default_rng(0)) is None
    assert T_OBS == 8


def test_crowd_rows_keep_the_whole_window_beside_the_walker(batch):
    crowd = encounter_batch(batch, 1.0, (8, 36), np.random.default_rng(1), crowd=1.0)
    pair = encounter_batch(batch, 1.0, (8, 36), np.random.default_rng(1), crowd=0.0)
    torch.testing.assert_close(crowd.obs, pair.obs, equal_nan=True)  # the same walkers, only the company differs
    futures = torch.nan_to_num(batch.future, nan=1e6).flatten(1)
    for k, future in enumerate(torch.nan_to_num(crowd.future, nan=1e6).flatten(1)):
        window = int(torch.nonzero((futures == future).all(dim=1))[0])
        assert torch.equal(crowd.mask[k], batch.mask[window])
        assert (crowd.mask[k] | ~pair.mask[k]).all()
    assert crowd.mask.sum() > 2 * pair.mask.sum()
