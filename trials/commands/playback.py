"""`trials playback`: the paper's long-term playback navigation (Table I) on the ETH/UCY test scenes."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from navigan.playback.protocols import DEFAULT_PROTOCOL, PROTOCOLS
from trials import option_types as types
from trials.option_types import MAX_THREADS
from trials.progress import add_quiet

SPLIT_CHOICES = "eth, hotel, univ, zara1, zara2 or all"
#: Upper ends of the scoring options: beyond them a value is a typing slip.
MAX_SPEED_M_S = 10.0
MAX_SHIELD_M = 10.0
ALL_MODELS = ("goal-social-lstm,navil2,navil2-dagger,navigan,navigan-dagger,navigan-r,navigan-r-dagger,"
              "navigan-r-evasion,navigan-r-shield,human")


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "playback",
        help="long-term playback navigation on ETH/UCY: the paper's Table I",
        description=(
            "Each model walks as a recorded pedestrian of each split's test scene toward where that "
            "pedestrian was 14.4 s later, among the others as recorded; it is scored for social score S, "
            "comfort rate C, arrival rate A and path measures. Writes OUT/table1.md, table1.csv, "
            "episodes.csv, episodes/<split>/<model>.json and figures/ (PNG and SVG). An interrupted run resumes."
        ),
    )
    parser.add_argument("--split", default="all", help=f"{SPLIT_CHOICES} (default all: the five splits)")
    parser.add_argument("--models", default=ALL_MODELS, metavar="LIST",
                        help=f"comma-separated columns (default: all, {ALL_MODELS})")
    parser.add_argument("--checkpoints", type=Path, metavar="DIR",
                        help="folder of MODEL-SPLIT.pt checkpoints (default: the shipped weights)")
    parser.add_argument("--out", type=types.folder, metavar="DIR",
                        help="where results go (default: playback/ in the study folder)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR",
                        help="the study folder the results go into (default: current folder)")
    parser.add_argument("--data", type=Path, metavar="DIR",
                        help="ETH/UCY folder with splits.json (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--gamma", type=types.number(0, 1, above=True), default=0.9,
                        help="discount factor of S, per second at the preferred speed (default 0.9)")
    parser.add_argument("--v-pref", type=types.number(0, MAX_SPEED_M_S, above=True), default=1.0,
                        help="preferred speed in S's discount, m/s (default 1.0)")
    parser.add_argument("--collision", type=types.number(0, 0.2, below=True), default=0.1,
                        help="distance counted as a collision in S, m (default 0.1: pedestrians are points)")
    parser.add_argument("--subgoal-speed", metavar="recorded|M/S",
                        help="hand the networks, trained with goals 4.8 s ahead, a sub-goal that far ahead toward the "
                             "goal at the recorded pedestrian's pace or at M/S; 0: the goal itself (default: the "
                             "protocol's, the recorded pace under strict, the goal itself under paper)")
    parser.add_argument("--shield", type=types.number(0, MAX_SHIELD_M, above=True), default=0.5, metavar="M",
                        help="R+shield column: the distance (m) its first step must keep from everyone's "
                             "constant-velocity forecast over 1.6 s (default 0.5)")
    parser.add_argument("--protocol", choices=PROTOCOLS, default=DEFAULT_PROTOCOL,
                        help="paper: as the paper's text states it (targets with a recorded position 36 steps ahead, "
                             "distances at the recorded frames, the far goal handed to the networks); strict (default): "
                             "every pedestrian present for 20 frames, the closest approach within each step, a "
                             "sub-goal 12 steps ahead at the recorded pace")
    parser.add_argument("--paper", type=Path, metavar="FILE",
                        help="the paper's Table I values to print beside ours, as JSON {\"source\": text, "
                             "\"values\": {\"S\"|\"C\"|\"A\": {column: number or null}}} (default: the shipped "
                             "navigan/playback/paper_table1.json)")
    parser.add_argument("--seed", type=types.seed, default=0, help="seed of the fluctuation noise (default 0)")
    parser.add_argument("--episodes", type=types.whole(1), metavar="N",
                        help="only the first N episodes of each split (a quick look)")
    types.add_dpi(parser)
    parser.add_argument("--threads", type=types.whole(1, MAX_THREADS), default=1,
                        help="CPU threads for torch (default 1: small batches; more threads thrash on a busy machine)")
    add_quiet(parser)
    parser.add_argument("--json", action="store_true", help="print the tables as one JSON object instead of Markdown")
    parser.set_defaults(handler=run)


def subgoal_speed(text: str) -> float | str | None:
    """`recorded`, or a speed in m/s (None for 0: the goal itself).

    Raises:
        NaviganError: anything else.
    """
    from navigan.errors import NaviganError
    from navigan.playback.rollout import RECORDED

    if text == RECORDED:
        return RECORDED
    try:
        speed = float(text)
    except ValueError:
        speed = -1.0
    if not (math.isfinite(speed) and speed >= 0):
        raise NaviganError(f"--subgoal-speed: expected 'recorded' or a speed >= 0 in m/s, got {text!r}")
    return speed or None


def run(args: argparse.Namespace) -> int:
    import json

    import torch

    from navigan import checkpoint as ckpt
    from navigan.data import SPLITS, data_dir
    from navigan.errors import NaviganError
    from navigan.playback.evaluate import PROTOCOL_GOAL, Playback, Settings
    from navigan.playback.paper import PAPER_FILE, load_paper
    from trials.progress import Progress, numbered, piped_lines, show_bars

    speed = PROTOCOL_GOAL if args.subgoal_speed is None else subgoal_speed(args.subgoal_speed)
    out = args.out or args.study / "playback"
    torch.set_num_threads(args.threads)
    splits = list(SPLITS) if args.split == "all" else [args.split]
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    if not models:
        raise NaviganError("--models: name at least one column")
    checkpoints = args.checkpoints or ckpt.WEIGHTS_DIR
    if not checkpoints.is_dir():
        raise NaviganError(f"--checkpoints: {checkpoints} is not a folder")
    Progress("step", "playback", args.quiet).loading(
        f"Loading the {', '.join(splits)} test scenes and the checkpoints of {', '.join(models)}")
    playback = Playback(
        data=data_dir(args.data), out=out, checkpoints=checkpoints,
        settings=Settings.of(args.protocol, args.gamma, args.v_pref, args.collision, args.seed, args.episodes,
                             speed, args.shield),
        paper=args.paper or PAPER_FILE, dpi=args.dpi,
    )
    def walked(n: int, total: int, split: str, column: str) -> None:
        print(numbered(n, total, f"{split} {column}: walked, stored in {out / 'episodes' / split}"), flush=True)

    quiet = args.quiet or args.json
    tables = playback.evaluate(splits, models, progress=show_bars(quiet), on_walked=walked if piped_lines(quiet) else None)
    if args.json:
        print(json.dumps({"out": str(out), "protocol": args.protocol, "tables": [{"scope": t.scope, "values": t.values,
                                                        "intervals": {m: {k: list(v) for k, v in i.items()} for m, i in t.intervals.items()}}
                                                       for t in tables]}))
        return 0
    paper = load_paper(args.paper or PAPER_FILE)
    print(f"Protocol {args.protocol}; all splits pooled:")
    print(tables[0].markdown(paper).rstrip())
    print("\nMean over splits (each weighted equally):")
    print(tables[1].markdown(paper).rstrip())
    counts = ", ".join(f"{t.scope} {int(next(iter(t.values.values()))['episodes'])}" for t in tables[2:])
    print(f"episodes per split: {counts}")
    print(f"wrote {out / 'table1.md'}, table1.csv, episodes.csv, figures/")
    return 0
