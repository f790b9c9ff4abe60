"""Benchmark of `trials power`'s closed-loop campaigns on the paper's 18-run blinded A/B plan.

It runs the same campaigns (one power seed) with 1 and 2 local worker processes and on a local Ray
instance of 2 CPUs, and prints for each the wall time (worker start-up included), the start-up
(until the first batch came back, less one batch's time) and the steady rate in campaigns per
second; then Ray's overhead as a ratio to 2 local processes, both measured and projected to 1,000
campaigns, and the projected wall time of 1,000 campaigns on 2 and on 64 cores (start-up plus
1,000 campaigns at one worker's rate times the cores, assuming campaigns scale with cores, as
independent campaigns do until the cores run out). The machine's load is printed beside them.

    python benchmarks/bench_power.py [--campaigns 8] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from trials.power.closed_loop import campaign_seed
from trials.power.execution import LOCAL, Where, batches, run_batches
from trials.power.plans import own_plan
from trials.runner import RunOptions
from trials.study import StudyFolder

CONTROLLERS = ("NaviGAN-R", "Lattice")


def measure(where: Where, campaigns: int, study: StudyFolder, seed: int) -> tuple[float, float, float]:
    """(wall s, start-up s, campaigns per second after the first batch) of `campaigns` campaigns."""
    plan = own_plan(study)
    work = batches([(0, c, campaign_seed(seed, plan, c)) for c in range(campaigns)], 1)
    arrivals: list[float] = []
    start = time.perf_counter()
    run_batches(work, ([plan], CONTROLLERS, RunOptions(), None), where, lambda results: arrivals.append(time.perf_counter()))
    wall = time.perf_counter() - start
    rate = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0]) if len(arrivals) > 1 else len(arrivals) / wall
    return wall, max(arrivals[0] - start - 1.0 / rate * where.workers, 0.0), rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=8, help="campaigns per setting (default 8)")
    parser.add_argument("--seed", type=int, default=1, help="the power seed (default 1)")
    args = parser.parse_args()
    print(f"{os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f} before; {args.campaigns} campaigns of the 18-run A/B plan each")
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([sys.executable, "-m", "trials.cli", "design", "--ab", "--runs", "18", "--seed", "3", "--study", folder],
                       check=True, stdout=subprocess.DEVNULL)
        study = StudyFolder(Path(folder))
        figures = {}
        for name, where in (("1 local worker", Where(1)), ("2 local workers", Where(2)), ("Ray local, 2 CPUs", Where(2, LOCAL))):
            wall, startup, rate = measure(where, args.campaigns, study, args.seed)
            figures[name] = (wall, startup, rate)
            print(f"{name}: {wall:.1f} s wall, start-up {startup:.1f} s, {rate:.2f} campaigns/s ({args.campaigns / wall:.2f} including start-up)")
    local_wall, local_start, local_rate = figures["2 local workers"]
    ray_wall, ray_start, ray_rate = figures["Ray local, 2 CPUs"]
    projected_local = local_start + 1000 / local_rate
    projected_ray = ray_start + 1000 / ray_rate
    print(f"Ray overhead against 2 local processes: {ray_wall / local_wall - 1:+.1%} measured ({args.campaigns} campaigns), "
          f"{projected_ray / projected_local - 1:+.1%} projected at 1,000 campaigns")
    _, one_start, one_rate = figures["1 local worker"]
    for cores in (2, 64):
        seconds = one_start + 1000 / (one_rate * cores)
        print(f"1,000 campaigns on {cores} cores: about {seconds / 60:.1f} min")
    print(f"load average {os.getloadavg()[0]:.2f} after (other jobs on the machine count here)")


if __name__ == "__main__":
    main()
