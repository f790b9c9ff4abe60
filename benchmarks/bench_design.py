"""Benchmark of `trials design` side by side with R's AlgDesign (optFederov, or optBlock for a blocked plan, 100 starts)
on the same candidate points, when Rscript and AlgDesign are installed.

For each plan: the whole `trials design` command (a fresh process, start-up included, bytecode cached as an ordinary
install has it) and the whole `Rscript` process, each the median of --repeats runs, and each design's D-efficiency, both
computed by this project's `designs.diagnostics.diagnose` on its own model, so the two are measured alike (AlgDesign's
own D uses R's contrasts). Then equal work against equal work: AlgDesign's search time inside R (`system.time` of the
call) beside the search time (CPU, one thread, in this process, kernels compiled) of the fewest of our seeded starts
(1, 2, 4, ..., 100) whose design reaches AlgDesign's D-efficiency, and how many that took.

Without R the table shows this project's figures alone. `--loaded` keeps one core busy with another process throughout.

    python benchmarks/bench_design.py [--quick] [--loaded] [--repeats N]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from designs.constraints import Restrictions, compile_restrictions
from designs.diagnostics import diagnose
from designs.exchange import candidate_set, optimal_design
from designs.factors import CategoricalFactor
from designs.model import Model
from designs.presets import ab, qualitative
from designs.spec import StudySpec, read_spec
from trials.controllers.registry import AB_PRESET

#: The seed of every search here: the design command's `--seed` and R's `set.seed`.
SEED = 2019
#: Starts, ours and AlgDesign's `nRepeats`.
STARTS = 100
#: The start counts tried for the equal-work comparison.
START_STEPS = (1, 2, 4, 8, 16, 32, 64, 100)


@dataclass(frozen=True)
class Case:
    """One plan: how `trials design` is asked for it (a preset's flags, or a spec), and AlgDesign's formula over the
    candidate columns (categorical ones as R factors)."""

    name: str
    args: tuple[str, ...]
    spec_text: str | None
    formula: str

    def spec(self, folder: Path) -> StudySpec:
        if self.spec_text is None:
            return qualitative() if "--ab" not in self.args else ab(AB_PRESET)
        path = folder / "spec.toml"
        path.write_text(self.spec_text, encoding="utf-8")
        return read_spec(path)


def quadratic_spec(factors: int, runs: int, extra: str = "") -> str:
    """`factors` continuous factors X1.. on [-1, 1] in a full quadratic model."""
    head = f'[study]\nname = "quadratic"\nruns = {runs}\nmodel = "main + interactions + quadratic"\n{extra}'
    return head + "".join(f'\n[[factors]]\nname = "X{i + 1}"\ntype = "continuous"\nlow = -1\nhigh = 1\n' for i in range(factors))


CASES = (
    Case("the 27-run plan (--runs 27)", ("--runs", "27"), None, "~ ."),
    Case("the 18-run A/B plan (--runs 18 --ab --power 0)", ("--runs", "18", "--ab", "--power", "0"), None, "~ (.)^2 + I(Pedestrians^2)"),
    Case("6 factors, quadratic (p 28), 40 runs", (), quadratic_spec(6, 40), "~ quad(.)"),
    Case("6 factors, quadratic (p 28), 60 runs", (), quadratic_spec(6, 60), "~ quad(.)"),
    Case("6 factors, quadratic (p 28), 100 runs", (), quadratic_spec(6, 100), "~ quad(.)"),
    Case("8 factors, quadratic (p 45), 60 runs", (), quadratic_spec(8, 60), "~ quad(.)"),
    Case("4 factors, quadratic, X1 + X2 <= 1.5, 3 blocks, 30 runs", (),
         quadratic_spec(4, 30, 'disallowed = ["X1 + X2 > 1.5"]\nblocks = 3\n'), "~ quad(.)"),
)
QUICK = CASES[:3]
#: Pairs of cases whose whole-process times show how time grows with runs, and with terms.
GROWTH = (((CASES[2], CASES[4]), "40 -> 100 runs at p 28"), ((CASES[3], CASES[5]), "p 28 -> 45 at 60 runs"))


@dataclass(frozen=True)
class Problem:
    """A case as both tools see it: our model, restrictions and fixed block column, and the candidate points."""

    spec: StudySpec
    model: Model
    restrictions: Restrictions | None
    candidates: np.ndarray
    block: int | None

    @classmethod
    def of(cls, case: Case, folder: Path) -> Problem:
        spec = case.spec(folder)
        model = spec.build_model()
        restrictions = compile_restrictions(spec.disallowed, spec.constraints, model.factors, "spec")
        block = next((i for i in spec.per_run() if model.factors[i].name == "Block"), None)
        return cls(spec, model, restrictions, candidate_set(model, restrictions), block)

    def d_efficiency(self, settings: np.ndarray) -> float:
        return diagnose(self.model, settings).d_efficiency


def trials_design(case: Case, folder: Path, repeats: int) -> tuple[float, float]:
    """The whole `trials design` command: median wall seconds of `repeats` fresh processes (bytecode cached by an untimed
    first run), and its design's D-efficiency."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    spec = ("--spec", str(folder / "spec.toml")) if case.spec_text is not None else ()
    walls, efficiency = [], float("nan")
    for i in range(-1, repeats):
        study = folder / f"study{i + 1}"
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "trials.cli", "design", *case.args, *spec, "--seed", str(SEED), "--study", str(study),
                        "--quiet"], check=True, stdout=subprocess.DEVNULL, env=env)
        if i >= 0:
            walls.append(time.perf_counter() - start)
        efficiency = json.loads((study / "design.json").read_text(encoding="utf-8"))["diagnostics"]["d_efficiency"]
    return statistics.median(walls), efficiency


def r_script(case: Case, problem: Problem, folder: Path) -> Path:
    """The R program of a case: read the candidates, search as AlgDesign does with 100 starts, print its search seconds
    and the chosen candidates (1-based), one line per block."""
    factors = problem.model.factors
    columns = [i for i in range(len(factors)) if i != problem.block]
    table = folder / "candidates.csv"
    points = problem.candidates[:, columns]
    if problem.block is not None:
        points = np.unique(points, axis=0)  # the block column multiplied the points
    if len(points) <= problem.spec.runs:
        # AlgDesign chooses each row of its data at most once: with no more points than runs, each is given ceil(runs / p)
        # times, as often as a D-optimal plan of so few points may repeat one.
        points = np.repeat(points, -(-problem.spec.runs // problem.model.p), axis=0)
    header = ",".join(factors[i].name for i in columns)
    np.savetxt(table, points, delimiter=",", header=header, comments="", fmt="%.17g")
    categorical = [factors[i].name for i in columns if isinstance(factors[i], CategoricalFactor)]
    runs, blocks = problem.spec.runs, problem.spec.blocks
    search = (f"d <- optBlock({case.formula}, withinData = cand, blocksizes = rep({runs // blocks}, {blocks}), nRepeats = {STARTS})"
              if problem.block is not None else f"d <- optFederov({case.formula}, cand, nTrials = {runs}, nRepeats = {STARTS})")
    chosen = ('for (b in d$Blocks) cat(rownames(b), "\\n")' if problem.block is not None else 'cat(d$rows, "\\n")')
    script = folder / "design.R"
    script.write_text(
        "suppressMessages(library(AlgDesign))\n"
        f'cand <- read.csv("{table}")\n'
        + "".join(f'cand${name} <- factor(cand${name})\n' for name in categorical)
        + f"set.seed({SEED})\n"
        f'seconds <- system.time({search})[["elapsed"]]\n'
        'cat(seconds, "\\n")\n'
        f"{chosen}\n",
        encoding="utf-8")
    return script


def algdesign(case: Case, problem: Problem, folder: Path, repeats: int) -> tuple[float, float, float] | None:
    """AlgDesign's whole Rscript process (median wall seconds), its search seconds inside R and its design's D-efficiency
    by our diagnose; None when Rscript or AlgDesign is missing."""
    rscript = shutil.which("Rscript")
    if rscript is None:
        return None
    script = r_script(case, problem, folder)
    walls, searches, out = [], [], ""
    for _ in range(repeats):
        start = time.perf_counter()
        done = subprocess.run([rscript, str(script)], capture_output=True, text=True)
        walls.append(time.perf_counter() - start)
        if done.returncode != 0:
            if "AlgDesign" in done.stderr:
                return None
            raise RuntimeError(done.stderr)
        out = done.stdout
        searches.append(float(out.split()[0]))
    lines = out.strip().splitlines()[1:]
    points = np.loadtxt(folder / "candidates.csv", delimiter=",", skiprows=1, ndmin=2)
    rows = [points[[int(r) - 1 for r in line.split()]] for line in lines]
    if problem.block is not None:
        settings = [np.insert(block, problem.block, b, axis=1) for b, block in enumerate(rows)]
        design = np.vstack(settings)
    else:
        design = rows[0]
    return statistics.median(walls), statistics.median(searches), problem.d_efficiency(design)


def to_reach(problem: Problem, target: float) -> tuple[int, float] | None:
    """The fewest of START_STEPS seeded starts whose design reaches `target` D-efficiency, and the CPU seconds that
    search took on one thread; None when 100 starts do not."""
    for starts in START_STEPS:
        began = time.process_time()
        design = optimal_design(problem.model, problem.spec.runs, seed=SEED, starts=starts, restrictions=problem.restrictions,
                                per_run=problem.spec.per_run())
        seconds = time.process_time() - began
        if problem.d_efficiency(design.settings) >= target - 1e-9:
            return starts, seconds
    return None


@contextlib.contextmanager
def busy_core(loaded: bool) -> Iterator[None]:
    """With `loaded`, another process spinning on one core until the block ends."""
    if not loaded:
        yield
        return
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        spinner.kill()
        spinner.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the two presets and the 40-run quadratic only")
    parser.add_argument("--loaded", action="store_true", help="keep one core busy with another process throughout")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each whole process (median; default 3)")
    args = parser.parse_args()
    # Compile (or load) the exchange's kernels before anything is timed in this process.
    with tempfile.TemporaryDirectory() as folder:
        warm = Problem.of(CASES[2], Path(folder))
        optimal_design(warm.model, warm.spec.runs, seed=0, starts=2)
    print(f"{'plan':<58}{'trials s':>9}{'D-eff':>8}{'R s':>8}{'D-eff':>8}{'ratio':>7}   "
          f"{'R search s':>11}{'ours to reach R':>20}")
    walls: dict[Case, tuple[float, float]] = {}
    with busy_core(args.loaded):
        for case in QUICK if args.quick else CASES:
            with tempfile.TemporaryDirectory() as name:
                folder = Path(name)
                problem = Problem.of(case, folder)
                ours, ours_eff = trials_design(case, folder, args.repeats)
                reference = algdesign(case, problem, folder, args.repeats)
                if reference is None:
                    print(f"{case.name:<58}{ours:>9.2f}{ours_eff:>8.2f}{'(AlgDesign not installed)':>33}")
                    continue
                r_wall, r_search, r_eff = reference
                walls[case] = ours, r_wall
                reach = to_reach(problem, r_eff)
                reached = "not in 100 starts" if reach is None else f"{reach[1]:.2f} s ({reach[0]} starts)"
                print(f"{case.name:<58}{ours:>9.2f}{ours_eff:>8.2f}{r_wall:>8.2f}{r_eff:>8.2f}{ours / r_wall:>7.2f}   "
                      f"{r_search:>11.2f}{reached:>20}")
    for (small, large), what in GROWTH:
        if small in walls and large in walls:
            print(f"growth, {what}: trials x{walls[large][0] / walls[small][0]:.2f}, AlgDesign x{walls[large][1] / walls[small][1]:.2f}")
    print(f"(wall seconds of each whole process, median of {args.repeats}, seed {SEED}, {STARTS} starts each; ratio: trials over R; "
          f"D-efficiencies by this project's diagnose; {'one core kept busy by another process; ' if args.loaded else ''}"
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the end)")


if __name__ == "__main__":
    main()
