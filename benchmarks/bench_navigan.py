"""NaviGAN speed: planning latency of the shipped NaviGAN-R and the time of one training epoch.

Planning: one target among 6 other agents, a 12-step plan, one CPU thread; median and p99 over
--calls calls (goal: median under 5 ms), with the controller's all-scenes weights (PoolNet) and
the eth split's (PairPoolNet). Training: one NaviGAN-R epoch (discriminator and
generator steps) over the eth split's training scenes, for each --batch (target agents per
batch; 32 is the paper's, 256 the shipped weights'), on --threads CPU threads (goal: under 10 s),
with the paper's recipe and the playback's (PairPoolNet and encounter rows; navigan/recipes).

    python benchmarks/bench_navigan.py [--data DIR] [--calls 1000] [--batch 32 256] [--threads 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np
import torch

from navigan import recipes
from navigan.config import ModelConfig, TrainConfig
from navigan.data import SHIPPED_DATA, Scenes, load_split
from navigan.planner import Planner
from navigan.training import Networks, run_epoch

DATA = Path(os.environ.get("TRIALS_DATA", SHIPPED_DATA))


def planning_latency(weights: str, calls: int) -> tuple[float, float]:
    """Median and p99 (ms) of `Planner.plan` with shipped `weights`, 6 other agents, one thread."""
    torch.set_num_threads(1)
    planner = Planner(weights)
    rng = np.random.default_rng(0)
    t = np.arange(8)[:, None]
    history = np.array([0.0, 0.0]) + t * np.array([0.45, 0.0])
    others = rng.uniform(1, 6, size=(6, 1, 2)) + t[None] * rng.normal(0, 0.4, size=(6, 1, 2))
    goal = np.array([8.5, 0.5])
    for _ in range(50):
        planner.plan(history, others, goal)
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        planner.plan(history, others, goal)
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3), float(np.percentile(times, 99) * 1e3)


def epoch_seconds(scenes: Scenes, model: ModelConfig, config: TrainConfig, threads: int) -> float:
    """Wall time of one training epoch over `scenes`."""
    torch.set_num_threads(threads)
    nets = Networks.build(model, config, torch.device("cpu"))
    start = time.perf_counter()
    run_epoch(nets, scenes, model, config, epoch=0, device=torch.device("cpu"), progress=False)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="ETH/UCY folder (default: $TRIALS_DATA, else the copy shipped with navigan)")
    parser.add_argument("--calls", type=int, default=1000, help="planning calls to time (default 1000)")
    parser.add_argument("--batch", type=int, nargs="+", default=[32, 256], help="batch sizes to time an epoch at")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for the epoch (default 1)")
    args = parser.parse_args()

    for weights in ("navigan-r-all", "navigan-r-eth"):
        median, p99 = planning_latency(weights, args.calls)
        print(f"planning ({weights}, 1 target, 6 others, 12 steps, 1 thread): "
              f"median {median:.2f} ms, p99 {p99:.2f} ms  [goal: < 5 ms]")
    scenes = Scenes.from_files(load_split(args.data, "eth").train)
    configs = {name: recipes.load(name).configs("eth") for name in ("paper", "playback")}
    for batch in args.batch:
        for name, (model, config) in configs.items():
            seconds = epoch_seconds(scenes, model, dataclasses.replace(config, batch=batch), args.threads)
            print(f"training epoch (NaviGAN-R, {name} recipe, eth split, {scenes.n_targets} targets, batch {batch}, "
                  f"{args.threads} thread{'s' if args.threads > 1 else ''}): {seconds:.1f} s  [goal: < 10 s]")


if __name__ == "__main__":
    main()
