"""Training losses and the ADE/FDE metrics (positions in metres, K targets, T steps)."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from navigan.config import TrainConfig, Variant
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


def fde_loss(intention: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """L_fde: mean distance from the intention's last state to the target's last future position
    (the goal, when the goal is T_PRED steps ahead as in the paper)."""
    return (intention[:, -1] - truth[:, -1]).norm(dim=-1).mean()


def _safe_norm(x: torch.Tensor, dim: int) -> torch.Tensor:
    """Euclidean norm with a zero (not NaN) gradient at zero."""
    squared = x.pow(2).sum(dim=dim)
    positive = squared > 0
    return torch.where(positive, squared.clamp_min(1e-12).sqrt(), torch.zeros_like(squared))


def resistance_loss(
    waypoints: torch.Tensor,
    others: torch.Tensor,
    present: torch.Tensor,
    d_safe: float = 0.5,
    truth: torch.Tensor | None = None,
    steps: int | None = None,
) -> torch.Tensor:
    """L_resist = || max(d_safe - d_o, 0) ||, averaged over targets.

    Args:
        waypoints: (K, T, 2) the planned positions.
        others: (K, A, T, 2) the other agents' positions at the same steps.
        present: (K, A, T) where those are known positions of agents other than the target.
        d_safe: the distance below which an agent pushes back (m).
        truth: (K, T, 2) the recorded future; if given, an agent pushes back only from closer than
            the recorded person came to it (and than d_safe), so the loss never asks for more room
            than people kept, e.g. from the friend they walk beside.
        steps: count only the plan's first `steps` way-points (default: all).
    """
    if steps is not None:
        waypoints, others, present = waypoints[:, :steps], others[:, :, :steps], present[:, :, :steps]
        truth = None if truth is None else truth[:, :steps]
    distance = _safe_norm(others - waypoints.unsqueeze(1), dim=-1)
    limit = torch.full_like(distance, d_safe)
    if truth is not None:
        limit = torch.minimum(limit, (others - truth.unsqueeze(1)).norm(dim=-1))
    intrusion = torch.where(present, (limit - distance).clamp_min(0), 0.0)
    return _safe_norm(intrusion.flatten(1), dim=-1).mean()


def generator_adversarial_loss(fake_logits: torch.Tensor) -> torch.Tensor:
    """The generator's GAN loss: make the discriminator call its paths real."""
    return F.binary_cross_entropy_with_logits(fake_logits, torch.ones_like(fake_logits))


def discriminator_loss(real_logits: torch.Tensor, fake_logits: torch.Tensor) -> torch.Tensor:
    """The discriminator's GAN loss: real paths to 1, generated ones to 0."""
    return F.binary_cross_entropy_with_logits(
        real_logits, torch.ones_like(real_logits)
    ) + F.binary_cross_entropy_with_logits(fake_logits, torch.zeros_like(fake_logits))


def near_rate(waypoints: torch.Tensor, others: torch.Tensor, present: torch.Tensor, distance: float) -> torch.Tensor:
    """(K,) the fraction of each target's way-points closer than `distance` to another agent
    (arguments as for `resistance_loss`)."""
    gap = (others - waypoints.unsqueeze(1)).norm(dim=-1)
    return (present & (gap < distance)).any(dim=1).float().mean(dim=-1)


def supervised_losses(
    prediction: Prediction, batch: SceneBatch, variant: Variant, config: TrainConfig
) -> dict[str, torch.Tensor]:
    """The non-adversarial terms a model trains on: l2, and fde / resistance where its variant has them.

    The resistance loss scores the way-points y_hat; unless `config.resist_intention`, its
    gradient reaches only the social force (the way-points with the intention held fixed), the
    part of the model that sees the other agents.
    """
    terms = {"l2": l2_loss(prediction.waypoints, batch.truth)}
    if variant.fde:
        terms["fde"] = fde_loss(prediction.intention, batch.truth)
    if variant.resistance:
        waypoints = prediction.waypoints
        if not config.resist_intention:
            waypoints = prediction.intention.detach() + prediction.forces
        truth = batch.truth if config.resist_beyond_truth else None
        terms["resistance"] = resistance_loss(
            waypoints, *batch.neighbours(), d_safe=config.d_safe, truth=truth, steps=config.resist_steps
        )
    return terms


def encounter_losses(prediction: Prediction, batch: SceneBatch, config: TrainConfig) -> dict[str, torch.Tensor]:
    """The terms of encounter rows (see `navigan.encounters`), which train the social force only:
    the force's squared step-to-step changes (from zero before the plan) plus `config.force_size`
    times its squared size, and the resistance loss.

    Scoring mostly the changes asks for a side-step that begins at once and is held until the agent
    is passed, a path a robot's follower can drive; scoring only the size would ask for the least
    displacement, a jump aside at the meeting step. The size term brings the force back to zero
    once the agent is passed, and keeps it there for a walker left alone; a larger one asks for
    the least room that keeps d_safe, which matters in a crowd, where a planner that re-plans every
    step from where its force took it otherwise drifts away from its goal.
    """
    forces = prediction.forces
    waypoints = prediction.intention.detach() + forces
    changes = torch.diff(forces, dim=1, prepend=torch.zeros_like(forces[:, :1]))
    return {
        "encounter_l2": (changes.pow(2) + config.force_size * forces.pow(2)).sum(dim=-1).mean(),
        "encounter_resistance": resistance_loss(
            waypoints, *batch.neighbours(), d_safe=config.d_safe, steps=config.resist_steps
        ),
    }


def weighted_sum(terms: dict[str, torch.Tensor], config: TrainConfig) -> torch.Tensor:
    """Sum of loss terms, each times its weight `w_<name>` in the training config (an
    `encounter_<name>` term weighs as `<name>`)."""
    return sum(getattr(config, f"w_{name.removeprefix('encounter_')}") * value for name, value in terms.items())
