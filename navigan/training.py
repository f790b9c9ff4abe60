"""Training a model of the family: seeded, whole-scene batches, early stopping, resumable.

Each batch: the generator plans every target; for GAN models the discriminator is updated on
real against generated paths, then the generator on its weighted losses (L2, FDE, resistance,
adversarial as the recipe says). After each epoch the validation loss (the non-adversarial
objective with a fixed noise seed) decides which weights are kept, and the checkpoint is saved.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch
from tqdm.auto import tqdm

from navigan import checkpoint as ckpt
from navigan.config import ModelConfig, TrainConfig
from navigan.data import SceneBatch, Scenes
from navigan.discriminator import Discriminator
from navigan.errors import NaviganError
from navigan.evaluation import evaluate
from navigan.generators import GoalSocialGenerator, NaviganGenerator, build_generator
from navigan.losses import discriminator_loss, generator_adversarial_loss, supervised_losses, weighted_sum


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
            discriminator = Discriminator(model).to(device) if model.recipe.adversarial else None
        return cls(
            generator=generator,
            discriminator=discriminator,
            g_optimizer=torch.optim.Adam(generator.parameters(), lr=train.lr),
            d_optimizer=torch.optim.Adam(discriminator.parameters(), lr=train.lr) if discriminator else None,
            noise=torch.Generator(device=device).manual_seed(train.seed),
        )

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


def train_batch(nets: Networks, batch: SceneBatch, model: ModelConfig, config: TrainConfig) -> dict[str, float]:
    """One optimisation step of the discriminator (GAN models) and the generator; the losses."""
    recipe = model.recipe
    goals = batch.goals
    noise = (
        torch.randn(len(goals), model.noise, generator=nets.noise, device=goals.device)
        if recipe.fluctuation
        else None
    )
    prediction = nets.generator(batch.obs, batch.mask, goals, noise=noise)
    terms = supervised_losses(prediction, batch, recipe, config.d_safe)
    logged: dict[str, float] = {}
    if nets.discriminator is not None and nets.d_optimizer is not None:
        scene = torch.cat([batch.obs, batch.future], dim=2)
        fake = torch.zeros_like(scene)
        fake[batch.mask] = torch.cat([batch.obs[batch.mask], prediction.waypoints], dim=1)
        logits = nets.discriminator(
            torch.cat([scene, fake.detach()]), torch.cat([scene, scene]), torch.cat([batch.mask, batch.mask])
        )
        d_loss = discriminator_loss(*logits.chunk(2))
        nets.d_optimizer.zero_grad(set_to_none=True)
        d_loss.backward()
        torch.nn.utils.clip_grad_norm_(nets.discriminator.parameters(), config.clip)
        nets.d_optimizer.step()
        logged["d"] = d_loss.item()
        nets.discriminator.requires_grad_(False)
        terms["adversarial"] = generator_adversarial_loss(nets.discriminator(fake, scene, batch.mask))
        nets.discriminator.requires_grad_(True)
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
    """One pass over the training scenes in the epoch's seeded order; mean losses."""
    nets.generator.train()
    batches = scenes.batches(config.batch, seed=(config.seed, epoch))
    totals: dict[str, float] = {}
    bar = tqdm(batches, desc=f"epoch {epoch + 1}", leave=False, disable=not progress, unit="batch")
    for i, windows in enumerate(bar, start=1):
        losses = train_batch(nets, scenes.batch(windows).to(device), model, config)
        for k, v in losses.items():
            totals[k] = totals.get(k, 0.0) + v
        bar.set_postfix({k: f"{v / i:.3f}" for k, v in totals.items()}, refresh=False)
    return {k: v / len(batches) for k, v in totals.items()}


def start(
    out: Path, model: ModelConfig, config: TrainConfig, split: dict[str, Any], data: dict[str, Any], command: str
) -> ckpt.Checkpoint:
    """The checkpoint to continue: the one at `out` if it matches this training, else a new one.

    Raises:
        NaviganError: `out` holds a different training (model, split or settings other than
            epochs and patience), which would be overwritten.
    """
    if not out.exists():
        return ckpt.Checkpoint(model=model, train=config, split=split, data=data, command=command)
    found = ckpt.load(out)
    same = {"epochs": config.epochs, "patience": config.patience}
    if found.model != model or found.split != split or replace(found.train, **same) != config:
        raise NaviganError(
            f"{out} holds another training ({found.model.model} on {found.split['name']}, "
            f"{found.train}); choose another --out or delete it"
        )
    found.train = config
    return found


def train(
    model: ModelConfig,
    config: TrainConfig,
    train_scenes: Scenes,
    val_scenes: Scenes,
    split: dict[str, Any],
    out: str | Path,
    command: str = "",
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
    record = start(out, model, config, split, data, command)
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
