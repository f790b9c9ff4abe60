"""ADE/FDE of a generator (full and dagger outputs) and of the constant-velocity baseline."""

from __future__ import annotations

import numpy as np
import torch

from navigan.config import TrainConfig
from navigan.data import Sampling, Scenes
from navigan.encounters import encounter_batch
from navigan.generators import GoalSocialGenerator, NaviganGenerator
from navigan.losses import ade, encounter_losses, fde, near_rate, supervised_losses, weighted_sum
from robot_logs.physical import T_PRED

#: Targets per evaluation batch (no gradients, so bigger than training's).
EVAL_BATCH = 1024


#: Way-points closer than this to another agent count in the `near` figure (m): playback's discomfort distance.
NEAR_M = 0.2


@torch.no_grad()
def evaluate(
    generator: NaviganGenerator | GoalSocialGenerator,
    scenes: Scenes,
    seed: int,
    device: str | torch.device = "cpu",
    train: TrainConfig | None = None,
) -> dict[str, float]:
    """Mean ADE and FDE (m) over all targets of `scenes`, for the waypoints and the intention (dagger),
    and `near`, the fraction of way-points closer than NEAR_M to another agent present then.

    One noise sample per target from `seed` (as SGAN-1V-1 draws one sample) where the model
    samples noise. Goals are the last future positions. With `train` also the validation `loss`:
    the weighted non-adversarial objective of the model's variant, averaged over targets, plus that
    of encounter rows drawn from `seed` where the training has them.
    """
    variant = generator.config.variant
    was_training = generator.training
    generator.eval()
    noise_rng = torch.Generator(device=device).manual_seed(seed)
    sampling = Sampling()
    encounter_rng = None
    if train is not None and train.encounters and variant.resistance:
        encounter_rng = np.random.default_rng([seed, 1])
    sums = {"ade": 0.0, "fde": 0.0, "ade_dagger": 0.0, "fde_dagger": 0.0, "near": 0.0, "loss": 0.0}
    for windows in scenes.batches(EVAL_BATCH):
        batch = scenes.batch(windows, sampling)
        if encounter_rng is not None:
            rows = encounter_batch(batch, train.encounters, sampling.goal_steps, encounter_rng, train.encounter_crowd)
            if rows is not None:
                rows = rows.to(device)
                walked = generator(rows.obs, rows.mask, rows.goals, targets=rows.targets)
                sums["loss"] += weighted_sum(encounter_losses(walked, rows, train), train).item() * len(batch.goals)
        batch = batch.to(device)
        goals, truth = batch.goals, batch.truth
        noise = None
        if variant.fluctuation:
            noise = torch.randn(len(goals), generator.config.noise, generator=noise_rng, device=device)
        prediction = generator(batch.obs, batch.mask, goals, targets=batch.targets, noise=noise)
        sums["ade"] += ade(prediction.waypoints, truth).sum().item()
        sums["fde"] += fde(prediction.waypoints, truth).sum().item()
        sums["ade_dagger"] += ade(prediction.intention, truth).sum().item()
        sums["fde_dagger"] += fde(prediction.intention, truth).sum().item()
        sums["near"] += near_rate(prediction.waypoints, *batch.neighbours(), NEAR_M).sum().item()
        if train is not None:
            terms = supervised_losses(prediction, batch, variant, train)
            sums["loss"] += weighted_sum(terms, train).item() * len(goals)
    generator.train(was_training)
    metrics = {k: v / scenes.n_targets for k, v in sums.items()}
    if train is None:
        del metrics["loss"]
    return metrics


def constant_velocity(obs: torch.Tensor) -> torch.Tensor:
    """(K, T_OBS, 2) -> (K, T_PRED, 2): the last observed step repeated."""
    velocity = obs[:, -1] - obs[:, -2]
    steps = torch.arange(1, T_PRED + 1, dtype=obs.dtype, device=obs.device)
    return obs[:, -1:] + steps[None, :, None] * velocity[:, None]


def evaluate_constant_velocity(scenes: Scenes) -> dict[str, float]:
    """Mean ADE and FDE (m) of the constant-velocity prediction over all targets of `scenes`."""
    total_ade = total_fde = 0.0
    for windows in scenes.batches(EVAL_BATCH):
        batch = scenes.batch(windows)
        prediction = constant_velocity(batch.obs[batch.targets])
        total_ade += ade(prediction, batch.truth).sum().item()
        total_fde += fde(prediction, batch.truth).sum().item()
    return {"ade": total_ade / scenes.n_targets, "fde": total_fde / scenes.n_targets}
