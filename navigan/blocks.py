"""NaviGAN's network blocks (paper section III), each a small module the generators compose.

Shapes: K target rows, A agent columns (padded), T time steps, H hidden size. The LSTMs read
2-D inputs (positions, forces) directly: a linear embedding in front of an LSTM's own input
weights would add nothing they cannot express.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def mlp(sizes: list[int]) -> nn.Sequential:
    """Linear layers with a ReLU between each two."""
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers[:-1])


class Encoder(nn.Module):
    """An LSTM over an agent's observed positions, each agent centred at its first one (E_i, E_s)."""

    def __init__(self, hidden: int) -> None:
        super().__init__()
        self.lstm = nn.LSTM(2, hidden, batch_first=True)

    def forward(self, positions: torch.Tensor) -> torch.Tensor:
        """(K, T, 2) positions -> (K, H) the last hidden state h^{T_obs}."""
        _, (h, _) = self.lstm(positions - positions[:, :1])
        return h[0]


class PoolNet(nn.Module):
    """V_i = max over the other agents j of NN_embed([NN_pos(x_j - x_i); features_j]).

    NN_pos is linear and NN_embed one linear layer and a ReLU, so the pair term splits into
    a part of j minus a part of i, and as ReLU(. - c) is monotone the max over j commutes with
    it: V_i = ReLU(max_{j != i} a_j - c_i). The max over the others is the largest a_j, or the
    second largest where the largest is i's own, so pooling costs O(A) per scene, not O(A^2),
    and is exact; the max makes V_i independent of the agents' order, and a target with no
    other agent pools to 0.
    """

    def __init__(self, features: int, embed: int, out: int) -> None:
        super().__init__()
        self.nn_pos = nn.Linear(2, embed)
        self.nn_embed = nn.Sequential(nn.Linear(embed + features, out), nn.ReLU())

    def forward(
        self, positions: torch.Tensor, features: torch.Tensor, mask: torch.Tensor, centres: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Pool over each scene's other agents, at every step.

        Args:
            positions: (B, A, S, 2) the agents' positions at S steps.
            features: (B, A, S, F) their features (hidden states or moves).
            mask: (B, A) the real agents.
            centres: (B, A, S, 2) where each agent-as-target stands, if not at `positions`
                (the discriminator scores generated paths against the real ones).

        Returns:
            (B, A, S, out) V_i for every agent i.
        """
        layer = self.nn_embed[0]
        embed = self.nn_pos.out_features
        w_pos, w_features = layer.weight[:, :embed], layer.weight[:, embed:]
        position_map = w_pos @ self.nn_pos.weight
        bias = w_pos @ self.nn_pos.bias + layer.bias
        per_agent = F.linear(positions, position_map) + F.linear(features, w_features, bias)
        per_agent = per_agent.masked_fill(~mask[:, :, None, None], -torch.inf)
        if per_agent.shape[1] < 2:
            per_agent = torch.cat([per_agent, torch.full_like(per_agent, -torch.inf)], dim=1)
        top, index = per_agent.topk(2, dim=1)
        own = torch.arange(mask.shape[1], device=mask.device)[None, :, None, None]
        others_max = torch.where(index[:, :1] == own, top[:, 1:], top[:, :1])
        centre = positions if centres is None else centres
        return self.nn_embed[1](others_max - F.linear(centre, position_map))


class PairPoolNet(nn.Module):
    """V_i = max over the other agents j of NN_pair([NN_pos(r_ij(k), |r_ij(k)| for k = 0..LOOKAHEAD); h_j]).

    r_ij(k) = (x_j - x_i) + k (v_j - v_i) is where j will be relative to i after k more steps if
    both keep their last move. This is Social GAN's pooling (a hidden layer per pair before the
    max) fed with the relative positions a constant-velocity look-ahead predicts: the nonlinearity
    lets a channel respond to an agent on a collision course, which PoolNet's linear max cannot (it
    reports the farthest agent in some direction, in a crowd always someone far away). It costs
    O(A) per target, O(A^2) per scene, so it pools once, at the last observed step. Its outputs
    are >= 0, so a target alone pools to 0.
    """

    #: Steps of the constant-velocity look-ahead.
    LOOKAHEAD = 4

    def __init__(self, features: int, embed: int, hidden: int, out: int) -> None:
        super().__init__()
        self.nn_pos = nn.Linear(3 * (self.LOOKAHEAD + 1), embed)
        self.nn_pair = nn.Sequential(nn.Linear(embed + features, hidden), nn.ReLU(), nn.Linear(hidden, out), nn.ReLU())

    def forward(
        self, positions: torch.Tensor, moves: torch.Tensor, features: torch.Tensor, mask: torch.Tensor,
        rows: tuple[torch.Tensor, torch.Tensor],
    ) -> torch.Tensor:
        """(B, A, 2) positions, last moves, (B, A, F) features, (B, A) real agents -> (K, out) V_i of the
        K targets `rows` (scene, agent)."""
        scene, agent = rows
        absent = ~mask.unsqueeze(-1)
        positions, moves = positions.masked_fill(absent, 0.0), moves.masked_fill(absent, 0.0)
        offset = positions[scene] - positions[scene, agent].unsqueeze(1)
        closing = moves[scene] - moves[scene, agent].unsqueeze(1)
        ahead = torch.arange(self.LOOKAHEAD + 1, dtype=offset.dtype, device=offset.device).view(1, 1, -1, 1)
        future = offset.unsqueeze(2) + ahead * closing.unsqueeze(2)
        pair = torch.cat([future, future.norm(dim=-1, keepdim=True)], dim=-1).flatten(2)
        pooled = self.nn_pair(torch.cat([self.nn_pos(pair), features[scene]], dim=-1))
        others = mask[scene].clone()
        others[torch.arange(len(agent), device=agent.device), agent] = False
        return pooled.masked_fill(~others.unsqueeze(-1), 0.0).amax(dim=1)


class IntentionDecoder(nn.Module):
    """I-LSTM: initial state [context; embedded goal], first input x^{T_obs}; NN_spatial steps the state.

    The intention state is a position: each step NN_spatial maps the decoder's hidden state to the
    move from the previous state, and the new state is the next step's input.
    """

    def __init__(self, context: int, goal: int, hidden: int) -> None:
        super().__init__()
        self.goal_embed = nn.Linear(2, goal)
        self.cell = nn.LSTMCell(2, context + goal)
        self.nn_spatial = mlp([context + goal, hidden, 2])

    def forward(self, context: torch.Tensor, goal: torch.Tensor, last: torch.Tensor, steps: int) -> torch.Tensor:
        """(K, C) context, (K, 2) goal, (K, 2) last observed position -> (K, steps, 2) intention."""
        h = torch.cat([context, self.goal_embed(goal)], dim=-1)
        c = torch.zeros_like(h)
        state = last
        out = []
        for _ in range(steps):
            h, c = self.cell(state, (h, c))
            state = state + self.nn_spatial(h)
            out.append(state)
        return torch.stack(out, dim=1)


class SocialForceDecoder(nn.Module):
    """SF-LSTM: initial state [h_i; V_i; z], zero cell, first input a zero force; NN_social emits f^t."""

    def __init__(self, state: int, hidden: int) -> None:
        super().__init__()
        self.cell = nn.LSTMCell(2, state)
        self.nn_social = mlp([state, hidden, 2])

    def forward(self, initial: torch.Tensor, steps: int) -> torch.Tensor:
        """(K, S) initial hidden state -> (K, steps, 2) social forces."""
        h, c = initial, torch.zeros_like(initial)
        force = initial.new_zeros(initial.shape[0], 2)
        out = []
        for _ in range(steps):
            h, c = self.cell(force, (h, c))
            force = self.nn_social(h)
            out.append(force)
        return torch.stack(out, dim=1)
