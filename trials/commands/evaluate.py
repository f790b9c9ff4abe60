"""`trials evaluate`: ADE/FDE of a checkpoint (full and dagger) or a baseline on a split's test scene."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from trials import option_types as types
from trials.progress import add_quiet

BASELINES = ("constant-velocity",)
LABELS = {"goal-social-lstm": "Goal-Social-LSTM", "navil2": "NaviL2", "navigan": "NaviGAN", "navigan-r": "NaviGAN-R"}


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "evaluate",
        help="ADE/FDE of a NaviGAN checkpoint or a baseline on a split's test scene",
        description=(
            "Average and final displacement errors (m) over every target of the split's test "
            "recordings: the model's way-points and its intention-only (dagger) output, or a "
            "baseline's prediction. Prints them and writes them as JSON."
        ),
    )
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--checkpoint", metavar="FILE", help="a checkpoint file, or a shipped name such as navigan-r-eth")
    what.add_argument("--baseline", choices=BASELINES, help="a baseline instead of a checkpoint")
    parser.add_argument("--split", help="eth, hotel, univ, zara1 or zara2 (default: the checkpoint's own)")
    parser.add_argument("--seed", type=types.seed, default=0, help="seed of the fluctuation noise (default 0)")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"), help="torch device (default cpu)")
    parser.add_argument("--data", type=Path, metavar="DIR",
                        help="ETH/UCY folder with splits.json (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--json", type=types.output_file, metavar="FILE",
                        help="where to write the result (default: NAME-SPLIT-eval.json in the study folder)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR",
                        help="the study folder the result goes into (default: current folder)")
    add_quiet(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import torch

    from navigan import checkpoint as ckpt
    from navigan.data import ALL_SCENES, Scenes, data_dir, load_split
    from navigan.errors import NaviganError
    from navigan.evaluation import evaluate, evaluate_constant_velocity
    from trials.atomic import write_text
    from trials.progress import Progress

    if args.device == "cuda" and not torch.cuda.is_available():
        raise NaviganError("--device cuda: this torch build sees no CUDA device")
    record: dict = {}
    if args.checkpoint:
        path = ckpt.resolve(args.checkpoint)
        loaded = ckpt.load(path)
        split_name = args.split or loaded.split["name"]
        name, label = path.stem, LABELS[loaded.model.model]
        record.update(checkpoint=str(path), model=loaded.model.model, trained_on=loaded.split["name"],
                      epochs=loaded.epoch, kept_epoch=(loaded.best or {}).get("epoch"))
    else:
        if not args.split:
            raise NaviganError("--baseline needs --split")
        split_name, name, label = args.split, args.baseline, "Constant velocity"
        record.update(baseline=args.baseline)
    if split_name == ALL_SCENES:
        raise NaviganError("the all-scenes split has no test scene; pass --split eth|hotel|univ|zara1|zara2")
    Progress("target", "evaluating", args.quiet).loading(f"Loading the {split_name} test scene")
    split = load_split(data_dir(args.data), split_name)
    scenes = Scenes.from_files(split.test)
    record.update(split=split_name, test_files=split.describe()["test"], targets=scenes.n_targets,
                  skipped_rows=scenes.skipped)
    rows: list[tuple[str, dict]] = []
    if args.checkpoint:
        metrics = evaluate(loaded.build_generator().to(args.device), scenes, seed=args.seed, device=args.device)
        record.update(seed=args.seed, full={"ade": metrics["ade"], "fde": metrics["fde"]})
        rows.append((label, record["full"]))
        if loaded.model.variant.generator == "navigan":
            record["dagger"] = {"ade": metrics["ade_dagger"], "fde": metrics["fde_dagger"]}
            rows.append((label + "†", record["dagger"]))
    else:
        record["full"] = evaluate_constant_velocity(scenes)
        rows.append((label, record["full"]))
    print(f"{name} on the {split_name} test scene ({', '.join(record['test_files'])}; {scenes.n_targets} targets)")
    for row_label, m in rows:
        print(f"  {row_label:<20} ADE {m['ade']:.3f} m   FDE {m['fde']:.3f} m")
    out = args.json or args.study / f"{name}-{split_name}-eval.json"
    write_text(out, json.dumps(record, indent=1) + "\n")
    print(f"wrote {out}")
    return 0
