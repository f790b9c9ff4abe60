"""Training losses and the ADE/FDE metrics (positions in metres, K targets, T steps)."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from navigan.config import Recipe, TrainConfig
from navigan.data import SceneBatch
from navigan.generators import Prediction


def displacement(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """(K, T, 2) each -> (K, T) Euclidean error at each step."""
    return (pred - truth).norm(dim=-1)


def ade(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """(K,) average displacement error over the steps."""
    return displacement(pred, truth).mean(dim=-1)


def fde(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """(K,) final displacement error."""
    return displacement(pred[:, -1:], truth[:, -1:])[:, 0]


def l2_loss(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Mean squared position error over targets and steps."""
    return (pred - truth).pow(2).sum(dim=-1).mean()


def fde_loss(intention: torch.Tensor, goals: torch.Tensor) -> torch.Tensor:
    """L_fde: mean distance from the intention's last state to the goal."""
    return (intention[:, -1] - goals).norm(dim=-1).mean()


def _safe_norm(x: torch.Tensor, dim: int) -> torch.Tensor:
    """Euclidean norm with a zero (not NaN) gradient at zero."""
    squared = x.pow(2).sum(dim=dim)
    positive = squared > 0
    return torch.where(positive, squared.clamp_min(1e-12).sqrt(), torch.zeros_like(squared))


def resistance_loss(
    waypoints: torch.Tensor, others: torch.Tensor, present: torch.Tensor, d_safe: float = 0.5
) -> torch.Tensor:
    """L_resist = || max(d_safe - d_o, 0) ||, averaged over targets.

    Args:
        waypoints: (K, T, 2) the planned positions.
        others: (K, A, T, 2) the other agents' positions at the same steps.
        present: (K, A) which of those agents are real and not the target itself.
        d_safe: the distance below which an agent pushes back (m).
    """
    distance = _safe_norm(others - waypoints.unsqueeze(1), dim=-1)
    intrusion = (d_safe - distance).clamp_min(0) * present.unsqueeze(-1)
    return _safe_norm(intrusion.flatten(1), dim=-1).mean()


def generator_adversarial_loss(fake_logits: torch.Tensor) -> torch.Tensor:
    """The generator's GAN loss: make the discriminator call its paths real."""
    return F.binary_cross_entropy_with_logits(fake_logits, torch.ones_like(fake_logits))


def discriminator_loss(real_logits: torch.Tensor, fake_logits: torch.Tensor) -> torch.Tensor:
    """The discriminator's GAN loss: real paths to 1, generated ones to 0."""
    return F.binary_cross_entropy_with_logits(
        real_logits, torch.ones_like(real_logits)
    ) + F.binary_cross_entropy_with_logits(fake_logits, torch.zeros_like(fake_logits))


def supervised_losses(
    prediction: Prediction, batch: SceneBatch, recipe: Recipe, d_safe: float
) -> dict[str, torch.Tensor]:
    """The non-adversarial terms a model trains on: l2, and fde / resistance where its recipe has them."""
    terms = {"l2": l2_loss(prediction.waypoints, batch.truth)}
    if recipe.fde:
        terms["fde"] = fde_loss(prediction.intention, batch.goals)
    if recipe.resistance:
        terms["resistance"] = resistance_loss(prediction.waypoints, *batch.neighbours(), d_safe=d_safe)
    return terms


def weighted_sum(terms: dict[str, torch.Tensor], config: TrainConfig) -> torch.Tensor:
    """Sum of loss terms (l2 among them), each times its weight `w_<name>` in the training config."""
    total = terms["l2"] * config.w_l2
    for name, value in terms.items():
        if name != "l2":
            total = total + getattr(config, f"w_{name}") * value
    return total
