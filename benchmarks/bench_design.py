"""Benchmark of `trials design` on the paper's two plans.

Prints, per preset: p, the efficiencies, the D-efficiency relative to the cvxpy bound, how
many of 100 seeded starts reached the best value, and the wall time of the whole
`trials design` command (a fresh process, start-up included; median of 5).

    python benchmarks/bench_design.py
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time

from designs.plan import build_plan
from designs.presets import ab, qualitative
from trials.controllers.registry import NAMES as CONTROLLERS

PRESETS = {"qualitative (--runs 27)": (qualitative(), ["--runs", "27"]), "A/B (--runs 18 --ab)": (ab(CONTROLLERS), ["--runs", "18", "--ab"])}
REPEATS = 5


def command_seconds(args: list[str]) -> list[float]:
    """Wall times of `trials design ARGS` in fresh study folders."""
    times = []
    for i in range(REPEATS):
        with tempfile.TemporaryDirectory() as folder:
            start = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "trials.cli", "design", *args, "--seed", str(i), "--study", folder],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            times.append(time.perf_counter() - start)
    return times


def main() -> None:
    print(f"{'preset':<24}{'p':>3}{'D-eff':>10}{'A-eff':>9}{'G-eff':>9}{'APV':>8}{'bound':>9}{'vs bound':>10}{'hits/100':>10}{'median s':>10}{'max s':>8}")
    for name, (spec, args) in PRESETS.items():
        spec = type(spec)(**{**spec.__dict__, "seed": 2019, "starts": 100})
        plan = build_plan(spec, allocation_seed=0)
        d = plan.diagnostics
        times = command_seconds(args)
        print(
            f"{name:<24}{d.p:>3}{d.d_efficiency:>10.4f}{d.a_efficiency:>9.3f}{d.g_efficiency:>9.3f}"
            f"{d.average_prediction_variance:>8.4f}{plan.bound.d_efficiency:>9.4f}{plan.d_efficiency_vs_bound:>9.2f}%"
            f"{plan.design.hits:>10}{statistics.median(times):>10.3f}{max(times):>8.3f}"
        )
    print(f"(wall time of `trials design` in a fresh process, median of {REPEATS}; goal for the 27-run plan: under 2 s)")


if __name__ == "__main__":
    main()
