"""Training a model of the family: seeded, whole-scene batches, early stopping, resumable.

Each batch (goals drawn and scenes turned as the config's sampling says): the generator plans
every target; for GAN models the discriminator is updated on real against generated paths, then
the generator on its weighted losses (L2, FDE, resistance, adversarial as the model's variant says, and the
encounter rows' terms where the config asks for them). After each epoch the validation loss (the
non-adversarial objective with fixed goals and noise from the seed) decides which weights are
kept, and the checkpoint is saved.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from navigan import checkpoint as ckpt
from navigan.config import ModelConfig, TrainConfig
from navigan.data import SceneBatch, Scenes
from navigan.discriminator import Discriminator
from navigan.encounters import encounter_batch
from navigan.errors import NaviganError
from navigan.evaluation import evaluate
from navigan.generators import GoalSocialGenerator, NaviganGenerator, Prediction, build_generator
from navigan.losses import (
    discriminator_loss,
    encounter_losses,
    generator_adversarial_loss,
    supervised_losses,
    weighted_sum,
)


@dataclass
class Networks:
    """The networks being trained, their optimisers and the fluctuation-noise RNG."""

    generator: NaviganGenerator | GoalSocialGenerator
    discriminator: Discriminator | None
    g_optimizer: torch.optim.Optimizer
    d_optimizer: torch.optim.Optimizer | None
    noise: torch.Generator

    @classmethod
    def build(cls, model: ModelConfig, train: TrainConfig, device: torch.device) -> Networks:
        """Fresh networks, initialised from the training seed."""
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(train.seed)
            generator = build_generator(model).to(device)
            discriminator = Discriminator(model).to(device) if model.variant.adversarial else None
        return cls(
            generator=generator,
            discriminator=discriminator,
            g_optimizer=torch.optim.Adam(generator.parameters(), lr=train.lr),
            d_optimizer=torch.optim.Adam(discriminator.parameters(), lr=train.lr) if discriminator else None,
            noise=torch.Generator(device=device).manual_seed(train.seed),
        )

    def plan(self, batch: SceneBatch, model: ModelConfig) -> Prediction:
        """The generator's plan for a batch's targets, with fluctuation noise where the model samples it."""
        noise = None
        if model.variant.fluctuation:
            noise = torch.randn(len(batch.goals), model.noise, generator=self.noise, device=batch.goals.device)
        return self.generator(batch.obs, batch.mask, batch.goals, targets=batch.targets, noise=noise)

    def state(self) -> dict[str, Any]:
        """Everything resuming needs."""
        return {
            "generator": self.generator.state_dict(),
            "discriminator": self.discriminator.state_dict() if self.discriminator else None,
            "g_optimizer": self.g_optimizer.state_dict(),
            "d_optimizer": self.d_optimizer.state_dict() if self.d_optimizer else None,
            "noise": self.noise.get_state(),
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Continue from what `state` returned."""
        self.generator.load_state_dict(state["generator"])
        self.g_optimizer.load_state_dict(state["g_optimizer"])
        if self.discriminator is not None and self.d_optimizer is not None:
            self.discriminator.load_state_dict(state["discriminator"])
            self.d_optimizer.load_state_dict(state["d_optimizer"])
        self.noise.set_state(state["noise"])


def train_batch(
    nets: Networks, batch: SceneBatch, model: ModelConfig, config: TrainConfig, encounters: SceneBatch | None = None
) -> dict[str, float]:
    """One optimisation step of the discriminator (GAN models) and the generator; the losses.

    The discriminator sees the targets only: their whole paths are known, the context agents'
    futures may not be. Encounter rows (if any) add their terms to the generator's loss.
    """
    variant = model.variant
    prediction = nets.plan(batch, model)
    terms = supervised_losses(prediction, batch, variant, config)
    logged: dict[str, float] = {}
    if nets.discriminator is not None and nets.d_optimizer is not None:
        scene = torch.cat([batch.obs, batch.future], dim=2)
        fake = torch.zeros_like(scene)
        targets = batch.targets
        fake[targets] = torch.cat([batch.obs[targets], prediction.waypoints], dim=1)
        logits = nets.discriminator(
            torch.cat([scene, fake.detach()]), torch.cat([scene, scene]), torch.cat([targets, targets])
        )
        d_loss = discriminator_loss(*logits.chunk(2))
        nets.d_optimizer.zero_grad(set_to_none=True)
        d_loss.backward()
        torch.nn.utils.clip_grad_norm_(nets.discriminator.parameters(), config.clip)
        nets.d_optimizer.step()
        logged["d"] = d_loss.item()
        nets.discriminator.requires_grad_(False)
        terms["adversarial"] = generator_adversarial_loss(nets.discriminator(fake, scene, targets))
        nets.discriminator.requires_grad_(True)
    if encounters is not None:
        terms |= encounter_losses(nets.plan(encounters, model), encounters, config)
    total = weighted_sum(terms, config)
    nets.g_optimizer.zero_grad(set_to_none=True)
    total.backward()
    torch.nn.utils.clip_grad_norm_(nets.generator.parameters(), config.clip)
    nets.g_optimizer.step()
    return {"loss": total.item(), **{k: v.item() for k, v in terms.items()}, **logged}


def run_epoch(
    nets: Networks,
    scenes: Scenes,
    model: ModelConfig,
    config: TrainConfig,
    epoch: int,
    device: torch.device,
    progress: bool = True,
) -> dict[str, float]:
    """One pass over the training scenes in the epoch's seeded order, goals and turns; mean losses."""
    nets.generator.train()
    batches = scenes.batches(config.batch, seed=(config.seed, epoch))
    sampling, rng = config.sampling, np.random.default_rng([config.seed, epoch, 1])
    totals: dict[str, float] = {}
    bar = tqdm(batches, desc=f"epoch {epoch + 1}", leave=False, disable=not progress, unit="batch")
    for i, windows in enumerate(bar, start=1):
        batch = scenes.batch(windows, sampling, rng)
        extra = None
        if config.encounters and model.variant.resistance:
            extra = encounter_batch(batch, config.encounters, sampling.goal_steps, rng, config.encounter_crowd)
        losses = train_batch(nets, batch.to(device), model, config, extra and extra.to(device))
        for k, v in losses.items():
            totals[k] = totals.get(k, 0.0) + v
        bar.set_postfix({k: f"{v / i:.3f}" for k, v in totals.items()}, refresh=False)
    return {k: v / len(batches) for k, v in totals.items()}


def start(
    out: Path,
    model: ModelConfig,
    config: TrainConfig,
    split: dict[str, Any],
    data: dict[str, Any],
    command: str,
    recipe: dict[str, str] | None,
) -> ckpt.Checkpoint:
    """The checkpoint to continue: the one at `out` if it matches this training, else a new one.

    Raises:
        NaviganError: `out` holds a different training (model, split or settings other than
            epochs and patience), which would be overwritten.
    """
    if not out.exists():
        return ckpt.Checkpoint(model=model, train=config, split=split, data=data, command=command, recipe=recipe)
    found = ckpt.load(out)
    same = {"epochs": config.epochs, "patience": config.patience}
    if found.model != model or found.split != split or replace(found.train, **same) != config:
        raise NaviganError(
            f"{out} holds another training ({found.model.model} on {found.split['name']}, "
            f"{found.train}); choose another --out or delete it"
        )
    # The limits may differ: the command and recipe that finish the training are the ones to record;
    # a command that finds it finished with the same limits trains nothing and leaves the record as it is.
    if not found.finished or found.train != config:
        found.train, found.command, found.recipe = config, command, recipe
    return found


def train(
    model: ModelConfig,
    config: TrainConfig,
    train_scenes: Scenes,
    val_scenes: Scenes,
    split: dict[str, Any],
    out: str | Path,
    command: str = "",
    recipe: dict[str, str] | None = None,
    device: str = "cpu",
    progress: bool = True,
    on_epoch: Callable[[ckpt.Checkpoint], None] | None = None,
) -> ckpt.Checkpoint:
    """Train (or resume) until the epoch limit or early stopping; the checkpoint is saved every epoch.

    Args:
        model, config: what to train and how.
        train_scenes, val_scenes: the data (see `navigan.data.Scenes`).
        split: the split's record (name and files) stored with the weights.
        out: the checkpoint file; an unfinished one for the same training is resumed.
        command: the command line, recorded.
        recipe: the recipe's record (`navigan.recipes.TrainingRecipe.record`), recorded.
        device: torch device.
        progress: show tqdm bars.
        on_epoch: called with the checkpoint after each saved epoch.
    """
    out = Path(out)
    dev = torch.device(device)
    data = {
        part: {"windows": len(s.counts), "targets": s.n_targets, "skipped_rows": s.skipped}
        for part, s in (("train", train_scenes), ("val", val_scenes))
    }
    record = start(out, model, config, split, data, command, recipe)
    if record.finished:
        return record
    nets = Networks.build(model, config, dev)
    if record.state is not None:
        nets.restore(record.state)
    bad_epochs = record.state["bad_epochs"] if record.state else 0
    epochs = tqdm(
        range(record.epoch, config.epochs), initial=record.epoch, total=config.epochs,
        desc=f"{model.model} {split['name']}", disable=not progress, unit="epoch",
    )
    for epoch in epochs:
        began = time.perf_counter()
        losses = run_epoch(nets, train_scenes, model, config, epoch, dev, progress)
        seconds = time.perf_counter() - began
        metrics = evaluate(nets.generator, val_scenes, seed=config.seed, device=dev, train=config)
        record.history.append({"epoch": epoch + 1, "seconds": round(seconds, 2), "train": losses, "val": metrics})
        if record.best is None or metrics["loss"] < record.best["val"]["loss"]:
            record.best = {"epoch": epoch + 1, "val": metrics}
            record.generator = {k: v.detach().cpu().clone() for k, v in nets.generator.state_dict().items()}
            bad_epochs = 0
        else:
            bad_epochs += 1
        record.epoch = epoch + 1
        if config.patience is not None and bad_epochs >= config.patience:
            record.finished = "early stopping"
        elif record.epoch >= config.epochs:
            record.finished = "epoch limit"
        record.state = None if record.finished else {**nets.state(), "bad_epochs": bad_epochs}
        ckpt.save(record, out)
        epochs.set_postfix(val_loss=f"{metrics['loss']:.3f}", ade=f"{metrics['ade']:.3f}", best=record.best["epoch"])
        if on_epoch is not None:
            on_epoch(record)
        if record.finished:
            break
    if not record.finished and record.epoch >= config.epochs:
        record.finished, record.state = "epoch limit", None
        ckpt.save(record, out)
    return record
