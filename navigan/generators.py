"""The generators: NaviGAN's intention-force + social-force generator, and Goal-Social-LSTM.

Both take whole scenes as padded tensors: positions in each scene's world frame, a mask of real
agents and a mask of the targets to plan for. Each target is planned in its own target-centric
frame (origin at its first observed position); outputs are returned in the scene's frame, one
row per target in `targets.nonzero()` order (batch-major).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from navigan.blocks import Encoder, IntentionDecoder, PairPoolNet, PoolNet, SocialForceDecoder
from navigan.config import ModelConfig
from robot_logs.physical import T_PRED


@dataclass(frozen=True)
class Prediction:
    """A generator's output for K targets, in the scene frame.

    Attributes:
        waypoints: (K, T_PRED, 2) y_hat = y_tilde + f.
        intention: (K, T_PRED, 2) y_tilde, the intention-only (dagger) output.
        forces: (K, T_PRED, 2) the social forces f (zero for Goal-Social-LSTM).
    """

    waypoints: torch.Tensor
    intention: torch.Tensor
    forces: torch.Tensor


class _SceneGenerator(nn.Module):
    """What both generators share: encode every agent with E_s and pool around each target."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        self.social_encoder = Encoder(config.hidden)
        self.pool: PoolNet | PairPoolNet = (
            PairPoolNet(config.hidden, config.embed, config.mlp, config.pool) if config.pair_pool
            else PoolNet(config.hidden, config.embed, config.pool)
        )

    def social_context(
        self, obs: torch.Tensor, mask: torch.Tensor, rows: tuple[torch.Tensor, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(K, H) each target's own E_s state h_i and (K, P) its pooled neighbourhood V_i."""
        hidden = obs.new_zeros(*mask.shape, self.config.hidden)
        hidden[mask] = self.social_encoder(obs[mask])
        if isinstance(self.pool, PairPoolNet):
            return hidden[rows], self.pool(obs[:, :, -1], obs[:, :, -1] - obs[:, :, -2], hidden, mask, rows)
        pooled = self.pool(obs[:, :, -1:], hidden.unsqueeze(2), mask)[:, :, 0]
        return hidden[rows], pooled[rows]


class NaviganGenerator(_SceneGenerator):
    """The intention-force generator (E_i, I-LSTM) plus the social-force generator (E_s, PoolNet, SF-LSTM)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__(config)
        self.intention_encoder = Encoder(config.hidden)
        self.intention_decoder = IntentionDecoder(config.hidden, config.goal, config.mlp)
        self.force_decoder = SocialForceDecoder(config.hidden + config.pool + config.noise, config.mlp)

    def forward(
        self,
        obs: torch.Tensor,
        mask: torch.Tensor,
        goals: torch.Tensor,
        targets: torch.Tensor | None = None,
        noise: torch.Tensor | None = None,
    ) -> Prediction:
        """Plan every target.

        Args:
            obs: (B, A, T_OBS, 2) observed positions; mask: (B, A) real agents.
            goals: (K, 2) one goal per target; targets: (B, A) agents to plan for (default: mask).
            noise: (K, noise) the fluctuation z (default: zero).
        """
        rows = (mask if targets is None else targets).nonzero(as_tuple=True)
        own = obs[rows]
        origin = own[:, 0]
        intention = self.intention_decoder(
            self.intention_encoder(own), goals - origin, own[:, -1] - origin, T_PRED
        ) + origin.unsqueeze(1)
        h, pooled = self.social_context(obs, mask, rows)
        if noise is None:
            noise = obs.new_zeros(len(origin), self.config.noise)
        forces = self.force_decoder(torch.cat([h, pooled, noise], dim=-1), T_PRED)
        return Prediction(intention + forces, intention, forces)


class GoalSocialGenerator(_SceneGenerator):
    """Goal-Social-LSTM: one encoder, PoolNet, and a decoder started from [h_i; V_i; embedded goal]."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__(config)
        self.decoder = IntentionDecoder(config.hidden + config.pool, config.goal, config.mlp)

    def forward(
        self,
        obs: torch.Tensor,
        mask: torch.Tensor,
        goals: torch.Tensor,
        targets: torch.Tensor | None = None,
        noise: torch.Tensor | None = None,
    ) -> Prediction:
        """Plan every target (same arguments as NaviganGenerator; the noise is ignored)."""
        rows = (mask if targets is None else targets).nonzero(as_tuple=True)
        own = obs[rows]
        origin = own[:, 0]
        h, pooled = self.social_context(obs, mask, rows)
        path = self.decoder(
            torch.cat([h, pooled], dim=-1), goals - origin, own[:, -1] - origin, T_PRED
        ) + origin.unsqueeze(1)
        return Prediction(path, path, torch.zeros_like(path))


def build_generator(config: ModelConfig) -> NaviganGenerator | GoalSocialGenerator:
    """The generator a model config names."""
    if config.variant.generator == "goal-social-lstm":
        return GoalSocialGenerator(config)
    return NaviganGenerator(config)
