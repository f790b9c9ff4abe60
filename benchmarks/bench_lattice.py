"""Lattice planner speed: SBPL's problems and the trial scenario (median of 5 runs each).

Prints, per problem, the setup time (primitive tables), the time to the first solution and to
epsilon 1 (both counting the 2-D heuristic, as SBPL's clock does), the expansions, and expansions per
second, next to SBPL's figures where the samples README gives them. Then the trial scenario with
2, 4 and 6 pedestrians: the controller's grid and Husky primitives, planned without a budget, and
the controller's whole `plan` call under its 0.25 s budget.

    python benchmarks/bench_lattice.py [--sbpl DIR] [--runs 5]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from robot_logs.physical import STEP_S, T_OBS
from trials.controllers.base import Observation
from trials.controllers.lattice import LatticeController
from trials.lattice.environment import read_cfg
from trials.lattice.planner import LatticePlanner, make_planner
from trials.lattice.primitives import read_mprim

SBPL_DIR = Path(__file__).resolve().parents[1] / "tests" / "data" / "sbpl"
RECTANGLE = [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)]
#: (environment, primitives, footprint, SBPL's expansions first / eps 1, SBPL's seconds first / eps 1)
PROBLEMS = [
    ("env1", "pr2", [], (2679, 3015), None),
    ("ped2_5cm", "unicycle_5cm", RECTANGLE, (19123, 257279), None),
    ("ped4_5cm", "unicycle_5cm", RECTANGLE, (19123, 265832), None),
    ("ped6_5cm", "unicycle_5cm", RECTANGLE, (28420, 266533), (0.160, 1.5)),
    ("ped2_5cm", "unicycle_side_backturn_5cm", RECTANGLE, (223, 65675), None),
    ("ped6_5cm", "unicycle_side_backturn_5cm", RECTANGLE, (265, 52188), None),
    ("ped2_10cm", "pr2_unicycle_10cm", RECTANGLE, (4481, 62345), None),
    ("ped6_10cm", "pr2_unicycle_10cm", RECTANGLE, (4490, 59626), None),
    ("ped2_10cm", "pr2_10cm", RECTANGLE, (2752, 31142), None),
    ("ped6_10cm", "pr2_10cm", RECTANGLE, (2751, 35283), (0.022, 0.3)),
]
HEADER = (f"{'problem':44} {'setup s':>8} {'first s':>8} {'eps1 s':>8} {'exp first':>10} {'exp eps1':>9} "
          f"{'exp/s':>9}   SBPL: exp first / eps1, s first / eps1")


def measure(planner: LatticePlanner, runs: int, **goal) -> dict[str, float]:
    """Median over `runs` full ARA* searches (eps 3 -> 1, step 0.2, no budget) of one planner."""
    planner.plan(budget=600.0, **goal)  # compiled code loaded, caches warm
    rows = []
    for _ in range(runs):
        result = planner.plan(eps=3.0, eps_step=0.2, budget=600.0, **goal)
        first, last = result.iterations[0], result.iterations[-1]
        rows.append((result.heuristic_seconds + first.seconds, result.heuristic_seconds + last.seconds,
                     first.expansions, last.expansions, last.expansions / last.seconds))
    med = [statistics.median(column) for column in zip(*rows)]
    return dict(zip(("first_s", "eps1_s", "exp_first", "exp_eps1", "exp_per_s"), med))


def row(name: str, setup: float, m: dict[str, float], sbpl: str) -> str:
    return (f"{name:44} {setup:8.3f} {m['first_s']:8.3f} {m['eps1_s']:8.3f} {m['exp_first']:10.0f} "
            f"{m['exp_eps1']:9.0f} {m['exp_per_s']:9.0f}   {sbpl}")


def scenario(n_peds: int, seed: int = 0) -> Observation:
    """The trial scenario: robot at the origin heading +x, goal 10 m ahead, pedestrians walking
    parallel (towards the robot) or crossing its line."""
    rng = np.random.default_rng(seed)
    positions, velocities = [], []
    for i in range(n_peds):
        if i % 2:
            positions.append((rng.uniform(4.0, 9.0), rng.uniform(-1.0, 1.0)))
            velocities.append((-rng.uniform(0.8, 1.3), 0.0))
        else:
            side = rng.choice([-1.0, 1.0])
            positions.append((rng.uniform(2.0, 8.0), side * rng.uniform(0.5, 2.5)))
            velocities.append((0.0, -side * rng.uniform(0.8, 1.3)))
    steps = np.arange(-(T_OBS - 1), 1)[:, None] * STEP_S
    history = np.array([np.asarray(p) + steps * np.asarray(v) for p, v in zip(positions, velocities)])
    return Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)),
                       tuple(range(n_peds)), history.reshape(n_peds, T_OBS, 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sbpl", type=Path, default=SBPL_DIR, help="the SBPL samples folder")
    parser.add_argument("--runs", type=int, default=5, help="runs per problem (the median is printed)")
    args = parser.parse_args()

    print(HEADER)
    for env_name, prims_name, footprint, sbpl_exp, sbpl_s in PROBLEMS:
        t0 = time.perf_counter()
        planner = make_planner(read_cfg(args.sbpl / f"{env_name}.cfg"), read_mprim(args.sbpl / f"{prims_name}.mprim"),
                               footprint)
        setup = time.perf_counter() - t0
        sbpl = f"{sbpl_exp[0]} / {sbpl_exp[1]}" + (f", {sbpl_s[0]:.3f} / {sbpl_s[1]:.1f} s" if sbpl_s else "")
        print(row(f"{env_name} + {prims_name}", setup, measure(planner, args.runs), sbpl), flush=True)

    print("\ntrial scenario (0.1 m cells, Husky primitives and footprint, comfort margin 0.2 m)")
    print(HEADER.split("   SBPL")[0] + "   controller plan() s, median / max")
    t0 = time.perf_counter()
    controller = LatticeController()
    setup = time.perf_counter() - t0
    for n_peds in (2, 4, 6):
        observation = scenario(n_peds)
        calls = []
        for _ in range(args.runs):
            controller.reset(0)
            plan = controller.plan(observation)
            calls.append(plan.record["plan_seconds"])
        problem = controller.planner.situation(observation.robot_pose, observation.goal,
                                               observation.pedestrian_history)
        m = measure(problem.planner, args.runs, start=problem.start, goal=problem.target)
        print(row(f"{n_peds} pedestrians", setup, m, f"{statistics.median(calls):.3f} / {max(calls):.3f}"),
              flush=True)


if __name__ == "__main__":
    main()
