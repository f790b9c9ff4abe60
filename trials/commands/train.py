"""`trials train`: train a NaviGAN-family model by a recipe on an ETH/UCY leave-one-scene-out split."""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from trials import option_types as types
from trials.option_types import MAX_THREADS
from trials.progress import add_quiet

if TYPE_CHECKING:
    from navigan.checkpoint import Checkpoint
    from navigan.config import ClosedLoopConfig, EvasionConfig

#: Training settings the command may override, each a whole number (None: the recipe's).
OVERRIDES = ("epochs", "patience", "seed")


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "train",
        help="train a NaviGAN-family model on ETH/UCY",
        description=(
            "Train a model by a recipe on a split's training recordings, keeping the weights of the best "
            "validation loss. A recipe (navigan/recipes/NAME.toml, or a file of your own) names the model and "
            "its training settings; settings it leaves out keep the defaults of navigan/config.py, the paper's. "
            "The checkpoint (weights, resolved settings, the recipe's text, split files, this command, per-epoch "
            "validation metrics) is saved after every epoch; run the same command again to resume an "
            "interrupted training. --closed-loop then tunes the finished NaviGAN-R on the states it visits "
            "walking playback episodes of the split's training recordings (navigan/closed_loop.py; settings "
            "from the recipe's [closed_loop] table, on the CPU), saved after every round and resumable the same way. "
            "--evasion then trains NaviGAN-R's evasion networks beside the finished generator on the states it visits "
            "walking the same episodes (navigan/evasion_training.py; settings from the recipe's [evasion] table, "
            "on the CPU), saved and resumable the same way; `trials playback --models navigan-r-evasion` walks them."
        ),
    )
    parser.add_argument("--recipe", required=True, metavar="NAME|FILE",
                        help="a shipped recipe's name (a file in navigan/recipes, such as robot or playback) "
                             "or a .toml file of your own")
    parser.add_argument("--split", required=True, help="eth, hotel, univ, zara1, zara2, or all (every scene)")
    parser.add_argument("--epochs", type=int, help="most epochs (default: the recipe's)")
    parser.add_argument("--patience", type=int,
                        help="stop after this many epochs without a better validation loss (default: the recipe's)")
    parser.add_argument("--seed", type=types.seed,
                        help="seed of weights, batch order and noise (default: the recipe's)")
    parser.add_argument("--closed-loop", action="store_true",
                        help="after training (or on a finished checkpoint at --out), tune it in closed loop")
    parser.add_argument("--closed-loop-seed", type=types.seed, metavar="SEED",
                        help="seed of the closed-loop tuning's walks and batch order (default: the recipe's)")
    parser.add_argument("--evasion", action="store_true",
                        help="after training (and any closed-loop tuning), train the evasion networks")
    parser.add_argument("--evasion-seed", type=types.seed, metavar="SEED",
                        help="seed of the evasion training's walks, weights and batch order (default: the recipe's)")
    parser.add_argument("--retrain-evasion", action="store_true",
                        help="with --evasion: discard the finished evasion networks the checkpoint at --out holds "
                             "(such as the shipped ones) and train them again")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"), help="torch device (default cpu)")
    parser.add_argument("--threads", type=types.whole(1, MAX_THREADS), help="CPU threads for torch (default: torch's choice)")
    parser.add_argument("--data", type=Path, metavar="DIR",
                        help="ETH/UCY folder with splits.json (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--out", type=types.output_file, metavar="FILE", help="checkpoint file (default: MODEL-SPLIT.pt in the study folder)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR",
                        help="the study folder the checkpoint goes into (default: current folder)")
    add_quiet(parser)
    parser.set_defaults(handler=run)


def command_line(args: argparse.Namespace, out: Path) -> str:
    """The command that reproduces this training with the same recipe (the data folder aside, which is machine-specific)."""
    overrides = [f"--{name} {getattr(args, name)}" for name in OVERRIDES if getattr(args, name) is not None]
    if args.closed_loop:
        overrides.append("--closed-loop")
        if args.closed_loop_seed is not None:
            overrides.append(f"--closed-loop-seed {args.closed_loop_seed}")
    if args.evasion:
        overrides.append("--evasion")
        if args.evasion_seed is not None:
            overrides.append(f"--evasion-seed {args.evasion_seed}")
        if args.retrain_evasion:
            overrides.append("--retrain-evasion")
    return " ".join([f"trials train --recipe {args.recipe} --split {args.split}", *overrides, f"--out {out.name}"])


def run(args: argparse.Namespace) -> int:
    import torch

    from navigan import checkpoint as ckpt
    from navigan import recipes
    from navigan.config import TrainConfig
    from navigan.data import ALL_SCENES, Scenes, data_dir, load_split
    from navigan.errors import NaviganError
    from navigan.training import train
    from trials.progress import Progress, numbered, piped_lines, show_bars

    for name in OVERRIDES:
        value = getattr(args, name)
        expected = None if value is None else recipes.problem(TrainConfig, name, value)
        if expected is not None:
            raise NaviganError(f"--{name}: expected {expected}, got {value}")
    if args.closed_loop_seed is not None and not args.closed_loop:
        raise NaviganError("--closed-loop-seed: only with --closed-loop")
    for option in ("evasion_seed", "retrain_evasion"):
        if getattr(args, option) not in (None, False) and not args.evasion:
            raise NaviganError(f"--{option.replace('_', '-')}: only with --evasion")
    recipe = recipes.load(args.recipe)
    model, config = recipe.configs(args.split, **{name: getattr(args, name) for name in OVERRIDES})
    if args.closed_loop and not (model.variant.resistance and model.variant.fluctuation):
        raise NaviganError(f"--closed-loop: tunes NaviGAN-R only; recipe {args.recipe} trains {model.model}")
    if args.closed_loop and args.split == ALL_SCENES:
        raise NaviganError(f"--closed-loop: needs a split with a held-out test scene, not {ALL_SCENES}")
    if args.closed_loop and args.device != "cpu":
        raise NaviganError(f"--closed-loop: tunes on the CPU only; train with --device {args.device} first, "
                           "then add --closed-loop without it")
    if args.evasion and not (model.variant.resistance and model.variant.fluctuation):
        raise NaviganError(f"--evasion: trains NaviGAN-R's evasion networks only; recipe {args.recipe} trains {model.model}")
    if args.evasion and args.device != "cpu":
        raise NaviganError(f"--evasion: trains on the CPU only; train with --device {args.device} first, "
                           "then add --evasion without it")
    if args.device == "cuda" and not torch.cuda.is_available():
        raise NaviganError("--device cuda: this torch build sees no CUDA device")
    if args.threads:
        torch.set_num_threads(args.threads)
    Progress("epoch", "training", args.quiet).loading(f"Loading the {args.split} split's recordings for {model.model}")
    split = load_split(data_dir(args.data), args.split)
    out = args.out or args.study / f"{model.model}-{args.split}.pt"
    train_scenes, val_scenes = Scenes.from_files(split.train), Scenes.from_files(split.val)
    for scenes in (train_scenes, val_scenes):
        for name, count in scenes.skipped.items():
            if count:
                sys.stderr.write(f"{name}: skipped {count} rows with NaN or missing values\n")
    def trained(checkpoint: ckpt.Checkpoint) -> None:
        val = checkpoint.history[-1]["val"]
        print(numbered(checkpoint.epoch, config.epochs, f"epoch {checkpoint.epoch}: validation loss {val['loss']:.4f}, "
                       f"ADE {val['ade']:.3f} m; best epoch {checkpoint.best['epoch'] if checkpoint.best else '-'}"), flush=True)

    record = train(
        model, config, train_scenes, val_scenes, split.describe(), out,
        command=command_line(args, out), recipe=recipe.record(), device=args.device, progress=show_bars(args.quiet),
        on_epoch=trained if piped_lines(args.quiet) else None,
    )
    if args.closed_loop:
        record = tune_closed_loop(args, record, recipe.tuning(args.closed_loop_seed), split.train, out)
    if args.evasion:
        config = recipe.evasion_training(args.evasion_seed)
        if args.retrain_evasion and record.evasion and (record.evasion["weights"] is not None
                                                        or record.evasion["settings"] != asdict(config)):
            record.evasion = None  # an unfinished training with these settings is resumed, not restarted
        record = train_evasion_networks(args, record, config, split.train, out)
    best = record.best or {"epoch": 0, "val": {}}
    status = record.finished or "unfinished"
    val = best["val"]
    print(
        f"{out}: {status} after {record.epoch} epochs; kept epoch {best['epoch']} "
        f"(validation loss {val.get('loss', float('nan')):.4f}, ADE {val.get('ade', float('nan')):.3f} m, "
        f"FDE {val.get('fde', float('nan')):.3f} m)"
        + (f"; tuned in closed loop over {len(record.closed_loop['rounds'])} rounds" if record.closed_loop else "")
        + (f"; evasion networks trained over {len(record.evasion['rounds'])} walks" if record.evasion else "")
    )
    return 0


def tune_closed_loop(args: argparse.Namespace, record: Checkpoint, config: ClosedLoopConfig, files: tuple[Path, ...],
                     out: Path) -> Checkpoint:
    """Tune a finished checkpoint in closed loop on playback episodes of the training recordings, one
    line per round."""
    from navigan import checkpoint as ckpt
    from navigan.closed_loop import tune
    from navigan.playback.episodes import load_episodes
    from navigan.playback.protocols import DEFAULT_PROTOCOL
    from trials.progress import Progress

    Progress("round", "tuning", args.quiet).loading(f"Walking {args.split}'s training recordings in closed loop")
    episodes = load_episodes(files, DEFAULT_PROTOCOL)

    def tuned(round_: int, entry: dict[str, Any]) -> None:
        terms = ", ".join(f"{k} {v:.4f}" for k, v in entry["train"].items())
        print(f"closed-loop round {round_}/{config.rounds}: walked {entry['states']} states, "
              f"trained on {entry['states_total']}, {terms}", flush=True)

    return tune(record, out, episodes, config, save=lambda r: ckpt.save(r, out), on_round=None if args.quiet else tuned)


def train_evasion_networks(args: argparse.Namespace, record: Checkpoint, config: EvasionConfig, files: tuple[Path, ...],
                           out: Path) -> Checkpoint:
    """Train the evasion networks beside a finished checkpoint on playback episodes of the training
    recordings, one line per walk."""
    from navigan import checkpoint as ckpt
    from navigan.evasion_training import train_evasion
    from navigan.playback.episodes import load_episodes
    from navigan.playback.protocols import DEFAULT_PROTOCOL
    from trials.progress import Progress

    Progress("walk", "evasion", args.quiet).loading(f"Walking {args.split}'s training recordings for the evasion networks")
    episodes = load_episodes(files, DEFAULT_PROTOCOL)

    def trained(round_: int, entry: dict[str, Any]) -> None:
        print(f"evasion walk {round_}/{config.rounds}: walked {entry['states']} states "
              f"({entry['planned_short']:.3f} of the planned steps short), head trained on {entry['states_total']}",
              flush=True)

    return train_evasion(record, out, episodes, config, save=lambda r: ckpt.save(r, out),
                         on_round=None if args.quiet else trained, command=command_line(args, out))
