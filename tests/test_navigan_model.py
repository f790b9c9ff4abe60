"""The network blocks, generators, discriminator and losses on hand-made scenes."""

from __future__ import annotations

import pytest
import torch

from navigan.blocks import PairPoolNet, PoolNet
from navigan.config import ModelConfig
from navigan.discriminator import Discriminator
from navigan.evaluation import constant_velocity
from navigan.generators import GoalSocialGenerator, NaviganGenerator, build_generator
from navigan.losses import ade, fde, resistance_loss
from robot_logs.physical import T_OBS, T_PRED


def scene(batch: int = 2, agents: int = 4, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Random walkers: (B, A, T_OBS, 2) observed positions and a mask with one padded row."""
    g = torch.Generator().manual_seed(seed)
    start = torch.rand(batch, agents, 1, 2, generator=g) * 8
    velocity = torch.randn(batch, agents, 1, 2, generator=g) * 0.5
    obs = start + velocity * torch.arange(T_OBS).view(1, 1, T_OBS, 1)
    mask = torch.ones(batch, agents, dtype=torch.bool)
    mask[-1, -1] = False
    return obs, mask


def generator(model: str, seed: int = 0, pair_pool: bool = False) -> NaviganGenerator | GoalSocialGenerator:
    torch.manual_seed(seed)
    return build_generator(ModelConfig(model, pair_pool=pair_pool)).eval()


@pytest.mark.parametrize("model", ["goal-social-lstm", "navigan-r"])
def test_prediction_shapes_and_decomposition(model):
    obs, mask = scene()
    goals = obs[mask][:, -1] + 3.0
    noise = torch.randn(int(mask.sum()), 8)
    out = generator(model)(obs, mask, goals, noise=noise)
    k = int(mask.sum())
    for tensor in (out.waypoints, out.intention, out.forces):
        assert tensor.shape == (k, T_PRED, 2)
    torch.testing.assert_close(out.waypoints, out.intention + out.forces)
    if model == "goal-social-lstm":
        assert torch.count_nonzero(out.forces) == 0


@pytest.mark.parametrize("model", ["goal-social-lstm", "navigan"])
def test_goal_reaches_the_decoder(model):
    obs, mask = scene()
    net = generator(model)
    goals = obs[mask][:, -1] + torch.tensor([3.0, 0.0])
    moved = goals.clone()
    moved[0] += torch.tensor([0.0, 2.0])
    a, b = net(obs, mask, goals), net(obs, mask, moved)
    assert (a.intention[0] - b.intention[0]).abs().max() > 1e-3
    torch.testing.assert_close(a.intention[1:], b.intention[1:])  # the other targets' goals did not move


@pytest.mark.parametrize("pair_pool", [False, True])
def test_targets_are_planned_in_their_own_frame(pair_pool):
    obs, mask = scene()
    net = generator("navigan-r", pair_pool=pair_pool)
    goals = obs[mask][:, -1] + 2.0
    shift = torch.tensor([100.0, -40.0])
    a, b = net(obs, mask, goals), net(obs + shift, mask, goals + shift)
    torch.testing.assert_close(b.waypoints, a.waypoints + shift, atol=1e-4, rtol=0)


def pool_reference(pool: PoolNet, positions, features, mask, centres):
    """V_i by the definition: NN_embed([NN_pos(x_j - x_i); f_j]) for every other agent j, max."""
    b_n, a_n, s_n, _ = positions.shape
    out = torch.zeros(b_n, a_n, s_n, pool.nn_embed[0].out_features)
    for b in range(b_n):
        for i in range(a_n):
            for s in range(s_n):
                rows = [
                    pool.nn_embed(torch.cat([pool.nn_pos(positions[b, j, s] - centres[b, i, s]), features[b, j, s]]))
                    for j in range(a_n)
                    if j != i and mask[b, j]
                ]
                if rows:
                    out[b, i, s] = torch.stack(rows).max(dim=0).values
    return out


def test_pooling_matches_its_definition_and_ignores_agent_order():
    torch.manual_seed(1)
    pool = PoolNet(features=5, embed=16, out=32)
    positions, features = torch.randn(3, 6, 4, 2), torch.randn(3, 6, 4, 5)
    centres = torch.randn(3, 6, 4, 2)
    mask = torch.rand(3, 6) > 0.3
    mask[0] = False
    mask[0, 2] = True  # a scene with one agent: nothing to pool
    with torch.no_grad():
        fast = pool(positions, features, mask, centres=centres)
        torch.testing.assert_close(fast, pool_reference(pool, positions, features, mask, centres))
        assert torch.count_nonzero(fast[0, 2]) == 0
        order = torch.randperm(6)
        shuffled = pool(positions[:, order], features[:, order], mask[:, order], centres=centres[:, order])
        torch.testing.assert_close(shuffled, fast[:, order])


def test_pair_pooling_matches_its_definition_and_pools_nothing_when_alone():
    torch.manual_seed(2)
    pool = PairPoolNet(features=5, embed=16, hidden=24, out=32)
    positions, moves, features = torch.randn(3, 6, 2) * 4, torch.randn(3, 6, 2), torch.randn(3, 6, 5)
    mask = torch.rand(3, 6) > 0.3
    mask[0] = False
    mask[0, 2] = True  # one agent alone
    mask[1, :2] = True
    positions[~mask] = torch.nan  # absent agents carry no position
    rows = mask.nonzero(as_tuple=True)
    with torch.no_grad():
        fast = pool(positions, moves, features, mask, rows)
    for k, (b, i) in enumerate(zip(*rows)):
        pairs = []
        for j in range(6):
            if j == i or not mask[b, j]:
                continue
            ahead = [positions[b, j] - positions[b, i] + k * (moves[b, j] - moves[b, i])
                     for k in range(PairPoolNet.LOOKAHEAD + 1)]
            geometry = torch.cat([torch.cat([r, r.norm().view(1)]) for r in ahead])
            pairs.append(pool.nn_pair(torch.cat([pool.nn_pos(geometry), features[b, j]])))
        expected = torch.stack(pairs).max(dim=0).values if pairs else torch.zeros(32)
        torch.testing.assert_close(fast[k], expected.detach())
    assert torch.count_nonzero(fast[0]) == 0


def test_pair_pooling_gradient_is_finite_beside_absent_agents():
    obs, mask = scene(batch=2, agents=5)
    obs[~mask] = torch.nan
    net = generator("navigan-r", pair_pool=True).train()
    out = net(obs, mask, obs[mask][:, -1] + 2.0)
    out.waypoints.sum().backward()
    grads = [p.grad for p in net.parameters() if p.grad is not None]
    assert grads and all(torch.isfinite(g).all() for g in grads)
    assert net.pool.nn_pos.weight.grad.abs().sum() > 0


@pytest.mark.parametrize("pair_pool", [False, True])
def test_plan_ignores_the_order_of_the_other_agents(pair_pool):
    obs, mask = scene(batch=1, agents=6)
    net = generator("navigan-r", pair_pool=pair_pool)
    targets = torch.zeros_like(mask)
    targets[0, 0] = True
    goal = obs[0, :1, -1] + 2.0
    order = torch.tensor([0, 4, 2, 5, 1, 3])
    a = net(obs, mask, goal, targets=targets)
    b = net(obs[:, order], mask[:, order], goal, targets=targets)
    torch.testing.assert_close(a.waypoints, b.waypoints)


def test_discriminator_scores_each_real_agent():
    obs, mask = scene()
    full = torch.cat([obs, obs[:, :, -1:] + torch.rand(2, 4, T_PRED, 2)], dim=2)
    logits = Discriminator(ModelConfig("navigan"))(full, full, mask)
    assert logits.shape == (int(mask.sum()),)


def test_resistance_is_zero_beyond_d_safe_and_positive_inside():
    waypoints = torch.zeros(1, T_PRED, 2)
    others = torch.zeros(1, 2, T_PRED, 2)
    others[0, :, :, 0] = 0.6  # both agents 0.6 m away at every step
    present = torch.ones(1, 2, T_PRED, dtype=torch.bool)
    assert resistance_loss(waypoints, others, present, d_safe=0.5).item() == 0.0
    others[0, 0, 3, 0] = 0.3  # one agent comes 0.3 m close at one step: intrusion 0.2 m
    assert resistance_loss(waypoints, others, present, d_safe=0.5).item() == pytest.approx(0.2)
    others[0, 1, 5, 0] = 0.4  # a second intrusion of 0.1 m: norm of (0.2, 0.1)
    assert resistance_loss(waypoints, others, present, d_safe=0.5).item() == pytest.approx(0.05**0.5)
    present[0, 1, 5] = False  # an agent not seen at that step pushes nothing then
    assert resistance_loss(waypoints, others, present, d_safe=0.5).item() == pytest.approx(0.2)
    assert resistance_loss(waypoints, others, torch.zeros_like(present), d_safe=0.5).item() == 0.0
    others[0, 1, 5, 0] = 0.4
    present[0, 1, 5] = True
    assert resistance_loss(waypoints, others, present, d_safe=0.5, steps=5).item() == pytest.approx(0.2)  # step 6 left out
    assert resistance_loss(waypoints, others, present, d_safe=0.5, steps=3).item() == 0.0  # so is step 4


def test_resistance_beyond_truth_asks_no_more_room_than_the_person_kept():
    waypoints = torch.zeros(1, T_PRED, 2)
    others = torch.full((1, 1, T_PRED, 2), 0.3)
    others[..., 1] = 0.0  # a friend walking 0.3 m beside the target all the way
    present = torch.ones(1, 1, T_PRED, dtype=torch.bool)
    truth = torch.zeros(1, T_PRED, 2)
    assert resistance_loss(waypoints, others, present, truth=truth).item() == 0.0
    closer = torch.full((1, T_PRED, 2), 0.0)
    closer[0, 4, 0] = 0.1  # the plan comes 0.2 m close where the person kept 0.3 m: 0.1 m intrusion
    assert resistance_loss(closer, others, present, truth=truth).item() == pytest.approx(0.1)
    assert resistance_loss(waypoints, others, present).item() == pytest.approx(0.2 * T_PRED**0.5)


def test_resistance_gradient_is_finite_when_touching_or_clear():
    waypoints = torch.zeros(1, T_PRED, 2, requires_grad=True)
    others = torch.zeros(1, 1, T_PRED, 2)  # on top of the target: distance 0
    present = torch.ones(1, 1, T_PRED, dtype=torch.bool)
    resistance_loss(waypoints, others, present).backward()
    assert torch.isfinite(waypoints.grad).all()
    clear = torch.zeros(1, T_PRED, 2, requires_grad=True)
    resistance_loss(clear, others + 5.0, present).backward()
    assert torch.count_nonzero(clear.grad) == 0


def test_displacement_errors_and_constant_velocity():
    obs = torch.stack([torch.arange(T_OBS, dtype=torch.float32) * 0.5, torch.zeros(T_OBS)], dim=-1)[None]
    prediction = constant_velocity(obs)
    torch.testing.assert_close(prediction[0, :, 0], 3.5 + 0.5 * torch.arange(1, T_PRED + 1, dtype=torch.float32))
    truth = prediction + torch.tensor([0.0, 1.0])
    truth[0, -1, 1] = 3.0
    assert ade(prediction, truth).item() == pytest.approx((11 * 1.0 + 3.0) / 12)
    assert fde(prediction, truth).item() == pytest.approx(3.0)
