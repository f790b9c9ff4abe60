"""Playback speed: episodes per second of batched roll-outs, and the full Table I evaluation's wall time.

Roll-outs: each learned column walks every episode of --split (default univ, the largest scene)
in one batch per step; episodes per second is episodes / wall time of the roll-out (scoring
apart). Full evaluation: `trials playback` over the five splits and every column whose shipped
weights exist, into a fresh folder (goal: under 10 minutes on 2 cores). Columns whose weights
are missing are named and left out.

    python benchmarks/bench_playback.py [--data DIR] [--split univ] [--threads 1] [--skip-full]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import torch

from navigan import checkpoint as ckpt
from navigan.data import SHIPPED_DATA, SPLITS, load_split
from navigan.playback.episodes import load_episodes
from navigan.playback.evaluate import HUMAN, MODELS, Playback, Settings, checkpoint_file
from navigan.playback.protocols import DEFAULT_PROTOCOL
from navigan.playback.rollout import roll_out
from navigan.playback.table import COLUMNS

DATA = Path(os.environ.get("TRIALS_DATA", SHIPPED_DATA))


def available(models: tuple[str, ...], splits: tuple[str, ...]) -> tuple[list[str], list[str]]:
    """The columns whose checkpoints exist for every split, and those that lack some."""
    have, lack = [], []
    for m in models:
        ok = all((p := checkpoint_file(m, s, ckpt.WEIGHTS_DIR)) is None or p.is_file() for s in splits)
        (have if ok else lack).append(m)
    return have, lack


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="ETH/UCY folder (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--split", default="univ", help="split of the roll-out timing (default univ)")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    parser.add_argument("--skip-full", action="store_true", help="time the roll-outs only")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"torch threads {args.threads}, {os.cpu_count()} CPU cores")

    episodes = load_episodes(load_split(args.data, args.split).test, DEFAULT_PROTOCOL)
    have, _ = available(MODELS, (args.split,))
    print(f"\nroll-outs on {args.split}: {len(episodes)} episodes, one batch per step")
    for model in have:
        if model == HUMAN:
            continue
        path = checkpoint_file(model, args.split, ckpt.WEIGHTS_DIR)
        policy = Settings().policy(model, ckpt.load(path), path)
        start = time.perf_counter()
        rollout = roll_out(policy, episodes)
        seconds = time.perf_counter() - start
        print(f"  {COLUMNS[model]:<10} {seconds:6.2f} s  {len(episodes) / seconds:7.1f} episodes/s  "
              f"({int(rollout.steps.max())} steps)")

    if args.skip_full:
        return
    have, lack = available(MODELS, SPLITS)
    print(f"\nfull evaluation, five splits, columns {', '.join(COLUMNS[m] for m in have)}")
    if lack:
        print(f"  left out (weights missing for some split): {', '.join(COLUMNS[m] for m in lack)}")
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        table = Playback(data=args.data, out=Path(out)).evaluate(list(SPLITS), have, progress=False)[0]
        seconds = time.perf_counter() - start
    episodes_total = int(table.values[have[0]]["episodes"])
    walked = episodes_total * sum(m != HUMAN for m in have)
    print(f"  wall time {seconds:.1f} s ({seconds / 60:.2f} min; goal under 10 min) for {episodes_total} episodes "
          f"x {len(have)} columns; {walked / seconds:.1f} walked episodes/s overall")


if __name__ == "__main__":
    main()
