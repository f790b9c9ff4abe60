"""The social-aware discriminator: PoolNet at every step of the full path, a D-LSTM, a score."""

from __future__ import annotations

import torch
from torch import nn

from navigan.blocks import PoolNet, mlp
from navigan.config import ModelConfig


def steps(paths: torch.Tensor) -> torch.Tensor:
    """(..., T, 2) positions -> (..., T, 2) moves since the previous step (zero first)."""
    return torch.cat([torch.zeros_like(paths[..., :1, :]), paths.diff(dim=-2)], dim=-2)


class Discriminator(nn.Module):
    """Scores each agent's observed + future path among the other agents' real paths (a logit).

    At every step PoolNet pools over the other agents from their displacement to the agent and
    their own move; the D-LSTM reads [move; pooled] and its last state gives the score.
    """

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.pool = PoolNet(2, config.embed, config.pool)
        self.lstm = nn.LSTM(2 + config.pool, config.hidden, batch_first=True)
        self.score = mlp([config.hidden, config.mlp, 1])

    def forward(self, paths: torch.Tensor, scene: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """(B, A, S, 2) paths to score, (B, A, S, 2) every agent's real path, (B, A) real agents -> (K,) logits.

        Row (b, a) of `paths` is scored against the real paths of the other agents of scene b;
        the logits are those of the real agents, in mask order.
        """
        pooled = self.pool(scene, steps(scene), mask, centres=paths)
        _, (h, _) = self.lstm(torch.cat([steps(paths), pooled], dim=-1)[mask])
        return self.score(h[0]).squeeze(-1)
