"""Benchmark of `trials run` on the paper's two plans, each in a fresh temporary study folder.

For the 27-run qualitative plan (`trials design --runs 27 && trials run`) and the 18-run blinded
A/B plan (`trials design --runs 18 --ab && trials run --blind`) it prints the wall time of the
design command and of the whole `trials run` command (a fresh process: start-up, worker start-up,
controller loading and every run included), the statuses, the simulated time, and the machine's
load average before and after (the goal, 27 runs in under 2 minutes on 2 cores, assumes the cores
are free).

    python benchmarks/bench_run.py [--workers 2] [--perception positions|lidar] [--seed 1]
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PLANS = {
    "qualitative, 27 runs (NaviGAN-R)": (["--runs", "27"], []),
    "A/B, 18 runs, blinded (NaviGAN-R and lattice)": (["--runs", "18", "--ab"], ["--blind"]),
}


def trials(*args: str) -> float:
    """Run `trials ARGS` in a fresh process; its wall time in seconds."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "trials.cli", *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2, help="worker processes of trials run (default 2)")
    parser.add_argument("--perception", choices=("positions", "lidar"), default="positions")
    parser.add_argument("--seed", type=int, default=1, help="study seed of both designs")
    args = parser.parse_args()
    print(f"{os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f} before; trials run --workers {args.workers} "
          f"--perception {args.perception}")
    for name, (design_args, run_args) in PLANS.items():
        with tempfile.TemporaryDirectory() as folder:
            design_s = trials("design", *design_args, "--seed", str(args.seed), "--study", folder)
            run_s = trials("run", *run_args, "--workers", str(args.workers), "--perception", args.perception, "--study", folder)
            with (Path(folder) / "outcomes.csv").open(newline="") as handle:
                rows = list(csv.DictReader(handle))
            statuses = {s: sum(r["status"] == s for r in rows) for s in ("goal", "collision", "timeout")}
            simulated = sum(float(r["duration_s"]) for r in rows)
            print(f"{name}: design {design_s:.1f} s, run {run_s:.1f} s wall for {len(rows)} runs "
                  f"({simulated:.0f} s simulated, {simulated / run_s:.1f}x real time); "
                  + ", ".join(f"{n} {s}" for s, n in statuses.items()))
    print(f"load average {os.getloadavg()[0]:.2f} after (other jobs on the machine count here)")


if __name__ == "__main__":
    main()
