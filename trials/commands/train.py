"""`trials train`: train a NaviGAN-family model on an ETH/UCY leave-one-scene-out split."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

MODELS = ("goal-social-lstm", "navil2", "navigan", "navigan-r")


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "train",
        help="train a NaviGAN-family model on ETH/UCY",
        description=(
            "Train a model on a split's training recordings, keeping the weights of the best "
            "validation loss. The checkpoint (weights, configs, split files, seed, this command, "
            "per-epoch validation metrics) is saved after every epoch; run the same command again "
            "to resume an interrupted training."
        ),
    )
    parser.add_argument("--model", required=True, choices=MODELS, help="which model of the family")
    parser.add_argument("--split", required=True, help="eth, hotel, univ, zara1, zara2, or all (every scene)")
    parser.add_argument("--epochs", type=int, default=500, help="most epochs (default 500, as the paper)")
    parser.add_argument("--patience", type=int,
                        help="stop after this many epochs without a better validation loss (default: never)")
    parser.add_argument("--batch", type=int, default=32,
                        help="target agents per batch, whole scenes (default 32, as the paper)")
    parser.add_argument("--lr", type=float, default=1e-3, help="Adam learning rate (default 1e-3)")
    parser.add_argument("--hidden", type=int, default=32, help="LSTM hidden size (default 32, as the paper)")
    parser.add_argument("--pair-pool", action="store_true",
                        help="pool neighbours with PairPoolNet (a hidden layer per pair, as Social GAN, fed a "
                             "constant-velocity look-ahead) instead of the paper's PoolNet")
    parser.add_argument("--seed", type=int, default=0, help="seed of weights, batch order and noise (default 0)")
    parser.add_argument("--goal-steps", default="12", metavar="FIRST[-LAST]",
                        help="a target's goal lies a uniform number of steps in FIRST-LAST after its last observed "
                             "one (default 12, the paper's: its last future position)")
    parser.add_argument("--augment", action="store_true", help="turn each training scene by a random angle, "
                        "mirror half of them")
    parser.add_argument("--w-resistance", type=float, default=1.0, help="weight of the resistance loss (default 1)")
    parser.add_argument("--d-safe", type=float, default=0.5, metavar="M",
                        help="the resistance loss's safe distance from other agents (default 0.5 m, as the paper)")
    parser.add_argument("--resist-forces-only", action="store_true",
                        help="the resistance loss trains only the social-force generator")
    parser.add_argument("--resist-beyond-truth", action="store_true",
                        help="the resistance loss asks for no more room than the recorded person kept")
    parser.add_argument("--encounters", type=float, default=0.0, metavar="RATE",
                        help="synthetic collision-course rows per target for the resistance loss (default 0)")
    parser.add_argument("--resist-steps", type=int, metavar="N",
                        help="the resistance loss scores only the plan's first N way-points (default: all 12)")
    parser.add_argument("--encounter-crowd", type=float, default=0.0, metavar="FRACTION",
                        help="fraction of encounter rows that keep their window's whole crowd (default 0)")
    parser.add_argument("--force-size", type=float, default=0.1, metavar="W",
                        help="weight of the social force's size beside its changes in encounter rows (default 0.1)")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"), help="torch device (default cpu)")
    parser.add_argument("--threads", type=int, help="CPU threads for torch (default: torch's choice)")
    parser.add_argument("--data", type=Path, metavar="DIR",
                        help="ETH/UCY folder with splits.json (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--out", type=Path, metavar="FILE", help="checkpoint file (default: MODEL-SPLIT.pt here)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(handler=run)


def command_line(args: argparse.Namespace, out: Path) -> str:
    """The command that reproduces this training (the data folder aside, which is machine-specific)."""
    parts = [
        f"trials train --model {args.model} --split {args.split} --epochs {args.epochs}",
        f"--patience {args.patience}" if args.patience is not None else "",
        f"--hidden {args.hidden}" if args.hidden != 32 else "",
        "--pair-pool" if args.pair_pool else "",
        f"--batch {args.batch} --lr {args.lr:g} --seed {args.seed}",
        f"--goal-steps {args.goal_steps}" if args.goal_steps != "12" else "",
        "--augment" if args.augment else "",
        f"--w-resistance {args.w_resistance:g}" if args.w_resistance != 1.0 else "",
        f"--d-safe {args.d_safe:g}" if args.d_safe != 0.5 else "",
        "--resist-forces-only" if args.resist_forces_only else "",
        "--resist-beyond-truth" if args.resist_beyond_truth else "",
        f"--resist-steps {args.resist_steps}" if args.resist_steps is not None else "",
        f"--encounters {args.encounters:g}" if args.encounters else "",
        f"--encounter-crowd {args.encounter_crowd:g}" if args.encounter_crowd else "",
        f"--force-size {args.force_size:g}" if args.force_size != 0.1 else "",
        f"--out {out.name}",
    ]
    return " ".join(p for p in parts if p)


def goal_steps(text: str) -> tuple[int, int]:
    """`FIRST` or `FIRST-LAST` as two whole numbers.

    Raises:
        NaviganError: anything else.
    """
    from navigan.errors import NaviganError

    first, _, last = text.partition("-")
    try:
        return int(first), int(last or first)
    except ValueError:
        raise NaviganError(f"--goal-steps: expected FIRST or FIRST-LAST whole numbers of steps, got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    import torch

    from navigan.config import ModelConfig, TrainConfig
    from navigan.data import Scenes, data_dir, load_split
    from navigan.errors import NaviganError
    from navigan.training import train

    for name in ("epochs", "batch", "patience", "threads", "hidden", "resist_steps"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise NaviganError(f"--{name.replace('_', '-')}: expected a positive whole number, got {value}")
    if not args.lr > 0:
        raise NaviganError(f"--lr: expected a positive number, got {args.lr}")
    if not args.d_safe > 0:
        raise NaviganError(f"--d-safe: expected a positive distance in metres, got {args.d_safe}")
    if not 0 <= args.encounter_crowd <= 1:
        raise NaviganError(f"--encounter-crowd: expected a fraction in [0, 1], got {args.encounter_crowd}")
    for name in ("w_resistance", "encounters", "force_size"):
        if not getattr(args, name) >= 0:
            raise NaviganError(f"--{name.replace('_', '-')}: expected a number >= 0, got {getattr(args, name)}")
    first, last = goal_steps(args.goal_steps)
    if args.device == "cuda" and not torch.cuda.is_available():
        raise NaviganError("--device cuda: this torch build sees no CUDA device")
    if args.threads:
        torch.set_num_threads(args.threads)
    split = load_split(data_dir(args.data), args.split)
    out = args.out or Path(f"{args.model}-{args.split}.pt")
    train_scenes, val_scenes = Scenes.from_files(split.train), Scenes.from_files(split.val)
    for scenes in (train_scenes, val_scenes):
        for name, count in scenes.skipped.items():
            if count:
                sys.stderr.write(f"{name}: skipped {count} rows with NaN or missing values\n")
    config = TrainConfig(
        split=args.split, epochs=args.epochs, patience=args.patience, batch=args.batch, lr=args.lr, seed=args.seed,
        w_resistance=args.w_resistance, d_safe=args.d_safe, goal_first=first, goal_last=last, augment=args.augment,
        resist_intention=not args.resist_forces_only, resist_beyond_truth=args.resist_beyond_truth,
        resist_steps=args.resist_steps, encounters=args.encounters, encounter_crowd=args.encounter_crowd,
        force_size=args.force_size,
    )
    record = train(
        ModelConfig(args.model, hidden=args.hidden, pair_pool=args.pair_pool), config, train_scenes, val_scenes, split.describe(), out,
        command=command_line(args, out), device=args.device, progress=not args.quiet,
    )
    best = record.best or {"epoch": 0, "val": {}}
    status = record.finished or "unfinished"
    val = best["val"]
    print(
        f"{out}: {status} after {record.epoch} epochs; kept epoch {best['epoch']} "
        f"(validation loss {val.get('loss', float('nan')):.4f}, ADE {val.get('ade', float('nan')):.3f} m, "
        f"FDE {val.get('fde', float('nan')):.3f} m)"
    )
    return 0
