"""Coverage of the primary result's interval for the average difference, by simulation.

Data sets like the paper's 18-run A/B plan: 9 runs per arm drawn at random, each run judged by 2, 4 or 6 people
(six runs each), a run effect N(0, SD^2) on the logit scale, and each arm's chance of yes expit(logit(share) + run
effect). The estimand is the average difference over the data set's 18 runs of their chances under the two arms,
so with a run SD above 0 the effect differs from run to run on the share scale (no constant shift). Each data set's
interval (`analysis.randomization`, studentized test inverted, 2,000 allocations drawn as `trials power` draws them
unless --exact) is checked for holding it. Printed per setting: the coverage with its Wilson 95 % Monte Carlo
interval, the mean width, and how often the interval and the planned test disagree about 0.

    python benchmarks/bench_interval.py [--simulations 1000] [--seed 1] [--exact]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy.special import expit, logit

from analysis.intervals import wilson
from analysis.randomization import MAX_ALLOCATIONS, randomization_test
from trials.power.verdicts import POWER_DRAWS

#: (share of yes in the first arm, in the second, run SD on the logit scale).
SETTINGS = ((0.5, 0.5, 0.5), (0.7, 0.5, 0.5), (0.9, 0.5, 0.5), (0.9, 0.75, 1.0), (0.95, 0.6, 1.0))
JUDGES = np.repeat([2, 4, 6], 6)


def one(rng: np.random.Generator, first: float, second: float, sd: float, exact: bool) -> tuple[bool, float, bool]:
    """(covered, width, interval and test disagree) for one simulated data set."""
    effect = rng.normal(0.0, sd, len(JUDGES))
    chance_first, chance_second = expit(logit(first) + effect), expit(logit(second) + effect)
    arm = np.zeros(len(JUDGES), dtype=bool)
    arm[rng.choice(len(JUDGES), len(JUDGES) // 2, replace=False)] = True
    shares = rng.binomial(JUDGES, np.where(arm, chance_first, chance_second)) / JUDGES
    truth = float(np.mean(chance_first - chance_second))
    test = randomization_test(shares, arm, level=0.95, max_allocations=MAX_ALLOCATIONS if exact else 0, draws=POWER_DRAWS,
                              seed=int(rng.integers(2**31)))
    if np.isnan(test.low):
        return False, float("nan"), False
    return test.low <= truth <= test.high, test.high - test.low, not test.agrees


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulations", type=int, default=1000, help="data sets per setting (default 1000)")
    parser.add_argument("--seed", type=int, default=1, help="the seed of every draw (default 1)")
    parser.add_argument("--exact", action="store_true", help="enumerate all 48,620 allocations, as a report does (slower)")
    args = parser.parse_args()
    reference = "all 48,620 allocations" if args.exact else f"{POWER_DRAWS:,} allocations drawn"
    print(f"{os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f}; {args.simulations} data sets per setting, seed {args.seed}, "
          f"reference set: {reference}")
    print("| shares (first, second) | run SD | coverage (Wilson 95 %) | mean width | interval and test disagree | seconds |")
    print("| --- | ---: | --- | ---: | ---: | ---: |")
    for index, (first, second, sd) in enumerate(SETTINGS):
        rng = np.random.default_rng([args.seed, index])
        start = time.perf_counter()
        results = [one(rng, first, second, sd, args.exact) for _ in range(args.simulations)]
        covered = sum(r[0] for r in results)
        band = wilson(covered, len(results))
        widths = [r[1] for r in results if not np.isnan(r[1])]
        print(f"| {first:g}, {second:g} | {sd:g} | {covered / len(results):.3f} ({band.low:.3f}-{band.high:.3f}) | "
              f"{np.mean(widths):.3f} | {sum(r[2] for r in results)} | {time.perf_counter() - start:.0f} |")


if __name__ == "__main__":
    main()
