"""NaviGAN-R's evasion networks: a learned choice of the plan's first step among the shield's moves.

The generator's plans come closer to people than it learned to keep in the states its own steps
lead to, and a continuous output cannot learn the shield's discrete detours (docs/results.md,
moonshot). Two small networks beside the generator choose instead, with no forecast computed
while walking:

- the head (`EvasionHead`) gives, for the plan's first step and each move of the ring (standing,
  and 5 speeds x 24 headings), the log-odds that it falls short of the margin from someone when
  held for the shield's horizon; the plan is kept unless its step more likely falls short than not;
- the shortfall network (`ShortfallNet`) predicts each move's shortfall in metres, and the walked
  move minimises its distance from the planned step plus `navigan.shield.PENALTY` times that.

Both see what the generator's pooling sees: the planned step, the walker's last move, and for each
of the NEAR nearest others within REACH their position relative to the walker and their last move.
One MLP scores each person and the scores are max-pooled over the people present (a move falls
short if it does so for anyone). They are taught by the shield's test (`navigan.evasion_training`).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from navigan.blocks import mlp
from navigan.shield import HEADINGS, PENALTY, SPEEDS, clearance, forecast
from robot_logs.physical import STEP_S

#: The nearest others each network sees, and how far away (m) one may be.
NEAR, REACH = 10, 6.0
#: Features of the walker (planned step, last move) and of each other person (relative position,
#: last move, present).
OWN, PERSON = 4, 5
#: The distinct moves (m per step): standing, then speed-major over the shield's headings.
RING = np.concatenate([np.zeros((1, 2)), (SPEEDS[1:, None, None] * np.stack(
    [np.cos(HEADINGS), np.sin(HEADINGS)], axis=-1)[None]).reshape(-1, 2)]).astype(np.float32) * np.float32(STEP_S)
#: Each network's outputs: the planned step (column 0), then the ring.
CHOICES = 1 + len(RING)
#: A pair score's stand-in where nobody is (log-odds: never short).
ABSENT = -20.0


def features(histories: np.ndarray, others: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """(B, OWN + NEAR * PERSON) what the networks see.

    Args:
        histories: (B, T, 2) the walkers' last positions (T >= 2).
        others: (B, N, T, 2) the others' last positions, NaN where unknown.
        steps: (B, 2) the planned first steps.
    """
    count = len(histories)
    position = histories[:, -1]
    last, before = others[:, :, -1], others[:, :, -2]
    move = np.where(np.isnan(before), 0.0, last - before)
    relative = last - position[:, None]
    distance = np.linalg.norm(relative, axis=-1)
    distance = np.where(np.isnan(distance) | (distance > REACH), np.inf, distance)
    order = np.argsort(distance, axis=1, kind="stable")[:, :NEAR]
    near = np.isfinite(np.take_along_axis(distance, order, axis=1))[..., None]
    people = np.zeros((count, NEAR, PERSON), dtype=np.float32)
    k = order.shape[1]
    people[:, :k, 0:2] = np.where(near, np.take_along_axis(relative, order[..., None], axis=1), 0.0)
    people[:, :k, 2:4] = np.where(near, np.take_along_axis(move, order[..., None], axis=1), 0.0)
    people[:, :k, 4] = near[..., 0]
    own = np.concatenate([steps, histories[:, -1] - histories[:, -2]], axis=1)
    return np.concatenate([own, people.reshape(count, -1)], axis=1).astype(np.float32)


def turned(x: np.ndarray, turns: int, mirror: bool) -> tuple[np.ndarray, np.ndarray]:
    """Features turned by `turns` of the ring's heading step (mirrored in y first if `mirror`), and
    the permutation `perm` of the choices that goes with it: choice c of `x` is choice perm[c] of
    the turned features. The ring maps onto itself, which makes this an exact augmentation."""
    count = len(x)
    angle = turns * (HEADINGS[1] - HEADINGS[0])
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    transform = (rotation @ np.diag([1.0, -1.0 if mirror else 1.0])).astype(np.float32)
    people = x[:, OWN:].reshape(count, NEAR, PERSON).copy()
    vectors = np.concatenate([x[:, :OWN].reshape(count, 2, 2), people[:, :, :4].reshape(count, 2 * NEAR, 2)], axis=1)
    vectors = vectors @ transform.T
    people[:, :, :4] = vectors[:, 2:].reshape(count, NEAR, 4)
    out = np.concatenate([vectors[:, :2].reshape(count, OWN), people.reshape(count, -1)], axis=1)
    headings = len(HEADINGS)
    heading = ((-np.arange(headings) if mirror else np.arange(headings)) + turns) % headings
    perm = np.concatenate([[0, 1], (2 + np.arange(len(SPEEDS) - 1)[:, None] * headings + heading[None]).reshape(-1)])
    return out.astype(np.float32), perm


def candidates(steps: np.ndarray) -> np.ndarray:
    """(B, CHOICES, 2) the planned step followed by the ring."""
    return np.concatenate([steps[:, None], np.broadcast_to(RING, (len(steps),) + RING.shape)], axis=1)


def person_shortfalls(x: np.ndarray, margin: float, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """(B, NEAR, CHOICES) each person's own shortfall (m) under `margin` for every choice, from the
    features alone (the person keeps their last move, `navigan.shield`), and (B, NEAR) who is present."""
    count = len(x)
    people = x[:, OWN:].reshape(count * NEAR, PERSON)
    relative, move = people[:, 0:2], people[:, 2:4]
    track = np.stack([relative - move, relative], axis=1)[:, None]  # (B*NEAR, 1, 2, 2): before and now
    moves = np.repeat(candidates(x[:, :2]), NEAR, axis=0)
    gap = clearance(np.zeros((count * NEAR, 2)), moves, forecast(track, horizon))
    short = np.clip(margin - gap, 0.0, None).reshape(count, NEAR, CHOICES)
    present = people[:, 4].reshape(count, NEAR) > 0
    return np.where(present[..., None], short, 0.0).astype(np.float32), present


class _PairScore(nn.Module):
    """One MLP over each (walker, person) pair -> (B, NEAR, CHOICES), and who is present."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.pair = mlp([OWN + PERSON - 1, width, width, CHOICES])

    def pairs(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        count = len(x)
        people = x[:, OWN:].reshape(count, NEAR, PERSON)
        both = torch.cat([x[:, None, :OWN].expand(count, NEAR, OWN), people[:, :, :4]], dim=-1)
        return self.pair(both), people[:, :, 4] > 0


class EvasionHead(_PairScore):
    """(B, CHOICES) log-odds that each choice, held for the horizon, falls short of the margin."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        scores, present = self.pairs(x)
        return torch.where(present[..., None], scores, torch.full_like(scores, ABSENT)).amax(dim=1)


class ShortfallNet(_PairScore):
    """(B, CHOICES) each choice's predicted shortfall (m): the largest of the people's."""

    #: Shifts the softplus so that an untrained net starts near zero shortfall.
    OFFSET = 3.0

    def person(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, NEAR, CHOICES) each person's predicted shortfall, and who is present."""
        scores, present = self.pairs(x)
        return nn.functional.softplus(scores - self.OFFSET), present

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        shortfall, present = self.person(x)
        return torch.where(present[..., None], shortfall, torch.zeros_like(shortfall)).amax(dim=1)


class Evasion(nn.Module):
    """The head and the shortfall network, and the step they choose."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.head = EvasionHead(width)
        self.shortfall = ShortfallNet(width)

    @torch.inference_mode()
    def steps(self, histories: np.ndarray, others: np.ndarray, planned: np.ndarray) -> np.ndarray:
        """(B, 2) the walked next positions: the planned ones unless the head calls their step short,
        else the move of the ring that costs least (see the module docstring)."""
        position = histories[:, -1]
        step = planned - position
        x = torch.from_numpy(features(histories, others, step))
        short = self.head(x)[:, 0].numpy() >= 0.0  # probability >= 0.5
        if not short.any():
            return planned
        detour = (torch.from_numpy(RING) - torch.from_numpy(step[short, None])).norm(dim=-1)
        cost = detour + PENALTY * self.shortfall(x[short])[:, 1:]
        walked = planned.copy()
        walked[short] = position[short] + RING[cost.argmin(dim=1).numpy()]
        return walked
