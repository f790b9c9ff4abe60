"""Benchmark of `trials design`: the paper's two plans, then the exchange's cost as the model and
the number of runs grow, beside R's AlgDesign where the issue measured it.

Prints, per preset: p, the efficiencies, the D-efficiency relative to the approximate design's bound, how many of
100 seeded starts reached the best value, and the wall time of the whole `trials design` command
(a fresh process, start-up included; median of 5, with its CPU time, user + sys), and the 27-run plan again
with its design figures drawn (--figures: PNG and SVG), a program that only starts the libraries the 27-run plan needs
(numpy, scipy.special, a cached numba kernel) beside that command, and a spec of 6 continuous factors in a full quadratic
model, 40 runs, with --seed 2019 and the starts its design.json says reached the best, its starts searched on every CPU
this process may use (the default) and on one (--threads 1). The command runs
with Python's bytecode cache on, in a private folder warmed by one run first, as an ordinary install
has it (pip compiles bytecode); this environment's PYTHONDONTWRITEBYTECODE would otherwise make
every import compile its module from source, doubling the start-up. Then, for k continuous factors in a full
quadratic model, the search time of 100 starts (CPU), the iterated local search's kick budget per start (0:
the starts agreed without it), the starts that reached the best design, how far the median start ended
below it, and its D-efficiency; AlgDesign's figures (optFederov, the same candidate grid and starts) were measured
in issue 24, since R cannot be installed beside the project: they are printed as the reference.

    python benchmarks/bench_design.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from designs.diagnostics import diagnose
from designs.exchange import optimal_design
from designs.factors import ContinuousFactor
from designs.model import parse_model
from designs.plan import build_plan
from designs.presets import ab, qualitative
from trials.commands.design import usable_cpus
from trials.controllers.registry import AB_PRESET as CONTROLLERS

PRESETS = {"qualitative (--runs 27)": (qualitative(), ["--runs", "27"]), "A/B (--runs 18 --ab)": (ab(CONTROLLERS), ["--runs", "18", "--ab"])}
REPEATS = 5
#: (factors, runs) -> AlgDesign's seconds and D-efficiency as issue 24 measured them (None: not measured).
ALGDESIGN = {(6, 40): (5.0, 50.13), (6, 80): (13.8, None)}
#: The issue's measurements of the previous Python exchange, for the same problems.
BEFORE = {(6, 40): 145.0, (6, 80): 262.0, (4, 20): 33.6}
#: p from 6 to 28 at 40 runs, then 6 factors from 40 to 200 runs, and the issue's 4-factor case.
SIZES = [(2, 40), (3, 40), (4, 40), (5, 40), (6, 40), (6, 80), (6, 120), (6, 200), (4, 20)]
QUICK = [(2, 40), (4, 20), (6, 40)]
#: The seed of the 6-factor spec's whole command (the scaling table's searches use 2019 as the design seed itself).
SPEC_SEED = 2019
QUADRATIC_SPEC = """[study]
name = "six-factor quadratic"
runs = 40
model = "main + interactions + quadratic"
""" + "".join(f'\n[[factors]]\nname = "X{i}"\ntype = "continuous"\nlow = -1\nhigh = 1\n' for i in range(6))


@dataclass
class CommandRuns:
    """The timed runs of one `trials design` command: wall and CPU (user + sys) seconds, and the starts at the best
    design as its design.json records them."""

    walls: list[float]
    cpus: list[float]
    hits: list[int]


def command_seconds(args: list[str], repeats: int = REPEATS, seed: int | None = None) -> CommandRuns:
    """`trials design ARGS` in fresh study folders, bytecode cached; run i has seed i unless `seed` is given."""
    runs = CommandRuns([], [], [])
    with tempfile.TemporaryDirectory() as cache:
        env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = cache
        for i in range(-1, repeats):  # run -1 writes the bytecode cache and is not timed
            with tempfile.TemporaryDirectory() as folder:
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                start = time.perf_counter()
                subprocess.run(
                    [sys.executable, "-m", "trials.cli", "design", *args, "--seed", str(max(i, 0) if seed is None else seed),
                     "--study", folder],
                    check=True,
                    stdout=subprocess.DEVNULL,
                    env=env,
                )
                wall = time.perf_counter() - start
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                hits = json.loads(Path(folder, "design.json").read_text(encoding="utf-8"))["search"]["hits"]
            if i >= 0:
                runs.walls.append(wall)
                runs.cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
                runs.hits.append(hits)
    return runs


#: A program that pays only the libraries' start-up: numpy, scipy.special and numba's first call of a kernel it has
#: cached, the three the 27-run plan's command cannot do without (numba's first call also imports scipy.linalg),
#: run as `trials` runs: OpenBLAS on one thread, no garbage collection at exit.
LIBRARY_FLOOR = """import gc
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numba
import numpy as np
import scipy.special

@numba.njit(cache=True)
def total(values):
    return values.sum()

total(np.ones(3))
gc.freeze()
"""


def library_floor(repeats: int = REPEATS) -> CommandRuns:
    """Wall and CPU seconds of `LIBRARY_FLOOR` in fresh processes, bytecode and kernel cached by a first run."""
    runs = CommandRuns([], [], [])
    with tempfile.TemporaryDirectory() as folder:
        script = Path(folder, "library_floor.py")
        script.write_text(LIBRARY_FLOOR, encoding="utf-8")
        env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = folder
        for i in range(-1, repeats):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([sys.executable, str(script)], check=True, env=env)
            wall = time.perf_counter() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            if i >= 0:
                runs.walls.append(wall)
                runs.cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return runs


def presets() -> None:
    print(f"{'preset':<24}{'p':>3}{'D-eff':>10}{'A-eff':>9}{'G-eff':>9}{'APV':>8}{'bound':>9}{'vs bound':>10}{'hits/100':>10}"
          f"{'median s':>10}{'max s':>8}{'CPU s':>7}")
    for name, (spec, args) in PRESETS.items():
        plan = build_plan(replace(spec, seed=2019, starts=100), allocation_seed=0)
        d = plan.diagnostics
        runs = command_seconds(args)
        times, cpus = runs.walls, runs.cpus
        print(
            f"{name:<24}{d.p:>3}{d.d_efficiency:>10.4f}{d.a_efficiency:>9.3f}{d.g_efficiency:>9.3f}"
            f"{d.average_prediction_variance:>8.4f}{plan.bound.d_efficiency:>9.4f}{plan.d_efficiency_vs_bound:>9.2f}%"
            f"{plan.design.hits:>10}{statistics.median(times):>10.3f}{max(times):>8.3f}{statistics.median(cpus):>7.3f}"
        )
    print(f"(wall and CPU time of `trials design` in a fresh process, median of {REPEATS}, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; goal for the 27-run plan: under 0.8 s; "
          "AlgDesign 0.19 s, the previous release 1.2 s)")
    floor, plan = library_floor(), command_seconds(["--runs", "27"])
    print(f"library start-up alone (numpy, scipy.special, numba's first cached call): {statistics.median(floor.walls):.3f} s "
          f"({statistics.median(floor.cpus):.3f} s CPU); the 27-run command measured beside it {statistics.median(plan.walls):.3f} s "
          f"({statistics.median(plan.cpus):.3f} s CPU)")
    figures = command_seconds(["--runs", "27", "--figures"], repeats=3)
    print(f"qualitative (--runs 27 --figures): {statistics.median(figures.walls):.3f} s "
          f"({statistics.median(figures.cpus):.3f} s CPU), the two design figures drawn as PNG and SVG")
    with tempfile.TemporaryDirectory() as folder:
        spec = f"{folder}/spec.toml"
        with open(spec, "w", encoding="utf-8") as handle:
            handle.write(QUADRATIC_SPEC)
        quadratic = command_seconds(["--spec", spec], repeats=1, seed=SPEC_SEED)
        one_thread = command_seconds(["--spec", spec, "--threads", "1"], repeats=1, seed=SPEC_SEED)
    print(f"6 continuous factors, full quadratic, 40 runs, 100 starts: `trials design --spec --seed {SPEC_SEED}` "
          f"{quadratic.walls[0]:.1f} s ({quadratic.cpus[0]:.1f} s CPU, starts on the {usable_cpus()} CPUs this process may use), "
          f"{quadratic.hits[0]} of 100 starts at the best; with --threads 1 {one_thread.walls[0]:.1f} s "
          "(goal: at most 10 s, 50 of 100; AlgDesign 5.0 s, the previous release 145 s)")


def scaling(sizes: list[tuple[int, int]]) -> None:
    print()
    print(f"{'factors':>7}{'p':>4}{'runs':>6}{'search s':>10}{'kicks':>7}{'hits/100':>10}{'within 1 %':>11}"
          f"{'median %':>10}{'D-eff':>9}   {'AlgDesign s, D-eff':>20}{'before s':>10}")
    for k, runs in sizes:
        model = parse_model("main + interactions + quadratic", tuple(ContinuousFactor(f"X{i}", -1, 1) for i in range(k)))
        start = time.process_time()
        design = optimal_design(model, runs, seed=2019, starts=100)
        seconds = time.process_time() - start
        reference = ALGDESIGN.get((k, runs))
        shown = "" if reference is None else f"{reference[0]:.1f}, " + ("-" if reference[1] is None else f"{reference[1]:.2f}")
        before = BEFORE.get((k, runs))
        relative = np.exp((design.start_values - design.value) / model.p)  # each start's D-efficiency over the best's
        near = int(np.sum(relative >= 0.99))
        print(f"{k:>7}{model.p:>4}{runs:>6}{seconds:>10.2f}{design.kicks:>7}{design.hits:>10}{near:>11}"
              f"{100 * np.median(relative):>10.2f}{diagnose(model, design.settings).d_efficiency:>9.2f}"
              f"   {shown:>20}{'' if before is None else f'{before:.1f}':>10}")
    print("(CPU time of the search of 100 starts in this process, numba's kernels compiled and cached; hits: starts at the best "
          "design's log det within 1e-6, within 1 %: starts whose D-efficiency is within 1 % of the best; median %: the median start's D-efficiency "
          "as a percentage of the best's; AlgDesign's figures are the issue's)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the presets and three sizes only")
    args = parser.parse_args()
    # Load the compiled kernels, the iterated local search's too (these starts disagree).
    optimal_design(parse_model("main + interactions + quadratic", tuple(ContinuousFactor(f"X{i}", -1, 1) for i in range(4))), 20,
                   seed=0, starts=4)
    presets()
    scaling(QUICK if args.quick else SIZES)


if __name__ == "__main__":
    main()
