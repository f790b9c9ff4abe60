"""Checkpoints: the best generator weights with everything needed to trust and remake them.

A checkpoint holds the model and training configs (the recipe's settings as resolved), the
recipe file's text, the data split (file names), the seed, the command that made it, per-epoch
validation metrics, and the best weights. While training runs it also holds `state` (latest
weights of both networks, optimisers, noise RNG) so an interrupted run resumes; a finished
training drops it, which keeps shipped files small.
"""

from __future__ import annotations

import os
import re
import secrets
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from navigan.config import ModelConfig, TrainConfig, from_dict, to_dict
from navigan.data import T_PRED
from navigan.errors import NaviganError
from navigan.evasion import Evasion
from navigan.generators import GoalSocialGenerator, NaviganGenerator, build_generator

FORMAT = "navigan-checkpoint/1"

#: Where the shipped weights live, one `<model>-<split>.pt` each.
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"

#: The checkpoint the trial controller loads by default.
DEFAULT_MODEL, DEFAULT_SPLIT = "navigan-r", "all"

#: Training settings older checkpoints record that training no longer has, each with the one
#: value every training now uses (the goal a target's last future position, as the paper).
RETIRED_SETTINGS: dict[str, object] = {"goal_first": T_PRED, "goal_last": T_PRED}


@dataclass
class Checkpoint:
    """A training record (see the module docstring).

    Attributes:
        model, train: the configs, as resolved from the recipe and the command's overrides.
        split: the split's name and data files (relative to the data folder).
        data: window and target counts and NaN/missing rows skipped, per part.
        command: the command line that made it (that trained its generator; evasion networks
            record their own).
        recipe: the recipe's name, file and text (see `navigan.recipes`); None in checkpoints
            made before recipes were files.
        epoch: epochs completed.
        history: one dict of training losses and validation metrics per epoch.
        best: the epoch and validation metrics of the kept weights.
        generator: the kept (best validation loss) generator weights.
        finished: why training stopped ("early stopping", "epoch limit"), None while it runs.
        state: what resuming needs, None once finished.
        closed_loop: the closed-loop tuning that changed the kept weights after training, if any
            (`navigan.closed_loop`: its settings, one entry per round, what resuming needs).
        evasion: the evasion networks trained beside the kept weights, if any
            (`navigan.evasion_training`: the command that trained them, their settings, one entry
            per round, what resuming needs, and once finished the networks' weights).
    """

    model: ModelConfig
    train: TrainConfig
    split: dict[str, Any]
    data: dict[str, Any]
    command: str
    recipe: dict[str, str] | None = None
    epoch: int = 0
    history: list[dict[str, Any]] = field(default_factory=list)
    best: dict[str, Any] | None = None
    generator: dict[str, torch.Tensor] = field(default_factory=dict)
    finished: str | None = None
    state: dict[str, Any] | None = None
    closed_loop: dict[str, Any] | None = None
    evasion: dict[str, Any] | None = None

    def build_generator(self) -> NaviganGenerator | GoalSocialGenerator:
        """The generator with the kept weights, in eval mode."""
        generator = build_generator(self.model)
        generator.load_state_dict(self.generator)
        return generator.eval()

    def build_evasion(self) -> Evasion | None:
        """The finished evasion networks, in eval mode; None if the checkpoint has none."""
        if not self.evasion or self.evasion.get("weights") is None:
            return None
        networks = Evasion(self.evasion["settings"]["width"])
        networks.load_state_dict(self.evasion["weights"])
        return networks.eval()


def weights(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    """A copy of a module's weights, detached, to keep in a checkpoint while the module trains on."""
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def save(checkpoint: Checkpoint, path: str | Path) -> None:
    """Write atomically: a temporary file in the same folder, then a rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {
        "format": FORMAT,
        "model": to_dict(checkpoint.model),
        "train": to_dict(checkpoint.train),
        "split": checkpoint.split,
        "data": checkpoint.data,
        "command": checkpoint.command,
        "recipe": checkpoint.recipe,
        "epoch": checkpoint.epoch,
        "history": checkpoint.history,
        "best": checkpoint.best,
        "generator": checkpoint.generator,
        "finished": checkpoint.finished,
        "state": checkpoint.state,
        "closed_loop": checkpoint.closed_loop,
        "evasion": checkpoint.evasion,
    }
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    try:
        with tmp.open("xb") as f:
            torch.save(record, f)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def load(path: str | Path, map_location: str | torch.device = "cpu") -> Checkpoint:
    """Read a checkpoint.

    Raises:
        NaviganError: missing file, not a NaviGAN checkpoint, or unknown fields.
    """
    path = Path(path)
    if not path.is_file():
        raise NaviganError(f"no checkpoint at {path}")
    try:
        record = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # torch raises many types for a corrupt or foreign file
        # torch wraps what its safe unpickler stopped at in a paragraph on unsafe loading; keep only that.
        unpickler = re.search(r"WeightsUnpickler error:\s*([^\n]+?)(\.\s|\n|$)", str(exc))
        if unpickler:
            reason = f"a weights-only load stops at: {unpickler.group(1)}"
        else:
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise NaviganError(f"{path} is not a readable checkpoint: {reason}") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise NaviganError(f"{path} is not a {FORMAT} file")
    try:
        return Checkpoint(
            model=from_dict(ModelConfig, record["model"]),
            train=_train_config(record["train"], path),
            split=record["split"],
            data=record["data"],
            command=record["command"],
            recipe=record.get("recipe"),
            epoch=record["epoch"],
            history=record["history"],
            best=record["best"],
            generator=record["generator"],
            finished=record["finished"],
            state=record["state"],
            closed_loop=record.get("closed_loop"),
            evasion=record.get("evasion"),
        )
    except KeyError as exc:
        raise NaviganError(f"{path} lacks the field {exc}") from exc


def _train_config(values: dict[str, Any], path: Path) -> TrainConfig:
    """The training config a checkpoint records, less the retired settings at their one value.

    Raises:
        NaviganError: a retired setting holds another value, or a field is unknown.
    """
    current = dict(values)
    for name, value in RETIRED_SETTINGS.items():
        if current.pop(name, value) != value:
            raise NaviganError(f"{path} was trained with {name} = {values[name]}, a setting training no longer has")
    return from_dict(TrainConfig, current)


def shipped(model: str = DEFAULT_MODEL, split: str = DEFAULT_SPLIT) -> Path:
    """The path of the shipped checkpoint of `model` trained on `split`.

    Raises:
        NaviganError: no such shipped checkpoint.
    """
    path = WEIGHTS_DIR / f"{model}-{split}.pt"
    if not path.is_file():
        names = sorted(p.stem for p in WEIGHTS_DIR.glob("*.pt"))
        raise NaviganError(f"no shipped weights {path.name}; shipped: {', '.join(names) or 'none'}")
    return path


def resolve(name_or_path: str | Path) -> Path:
    """A checkpoint path, or the shipped file a name like `navigan-r-eth` stands for."""
    path = Path(name_or_path)
    if path.is_file() or path.suffix == ".pt" or len(path.parts) > 1:
        return path
    candidate = WEIGHTS_DIR / f"{path.name}.pt"
    return candidate if candidate.is_file() else path
