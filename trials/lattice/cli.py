"""The lattice planner's command: plan an SBPL problem (nav3d `.cfg` + `.mprim`) with ARA* and print the answer.

`add_arguments` fills any argparse parser (the `trials lattice` subcommand's) and `run` serves the
parsed arguments; bad input raises `LatticeError` with a one-line message.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from trials.lattice.errors import LatticeError

#: The 1.0 x 0.7 m rectangle of the sample pedestrian problems (a Husky, rounded up).
DEFAULT_FOOTPRINT = "-0.5,-0.35 0.5,-0.35 0.5,0.35 -0.5,0.35"
SUMMARY = "plan an SBPL problem with the lattice planner (ARA*)"
DESCRIPTION = (
    "Plan from the start to the goal of an SBPL nav3d environment with SBPL motion primitives, "
    "by ARA* from --eps down to 1 within --budget seconds. Prints every epsilon reached with its "
    "cost, expansions and elapsed time, then the path (x y theta per pose). Exit status 0 when a "
    "path reaches the goal, 1 when not (the status line says why)."
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The command's arguments and options; `run` is its handler."""
    parser.add_argument("env", type=Path, metavar="ENV.cfg", help="SBPL nav3d environment file")
    parser.add_argument("prims", type=Path, metavar="PRIMS.mprim", help="SBPL motion primitive file")
    robot = parser.add_mutually_exclusive_group()
    robot.add_argument("--footprint", default=DEFAULT_FOOTPRINT, metavar='"x1,y1 x2,y2 ..."',
                       help=f"robot outline in metres, robot frame (default: {DEFAULT_FOOTPRINT})")
    robot.add_argument("--point", action="store_true", help="plan for a point robot (no footprint)")
    parser.add_argument("--eps", type=float, default=3.0, help="initial suboptimality bound (default 3.0)")
    parser.add_argument("--eps-step", type=float, default=0.2, help="eps decrement per iteration (default 0.2)")
    parser.add_argument("--budget", type=float, default=10.0, metavar="SECONDS",
                        help="planning time limit, heuristic included (default 10)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--study", type=Path, default=Path("."), metavar="DIR",
                        help="the folder relative ENV.cfg and PRIMS.mprim paths are read from (default: current folder)")


def parse_footprint(text: str) -> list[tuple[float, float]]:
    """'x1,y1 x2,y2 ...' to points; at least three, as a polygon needs."""
    points = []
    for item in text.split():
        parts = item.split(",")
        try:
            x, y = (float(p) for p in parts)
        except ValueError:
            raise LatticeError(f'--footprint: expected points "x,y" separated by spaces, got "{item}"') from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise LatticeError(f'--footprint: point "{item}" is not finite')
        points.append((x, y))
    if len(points) < 3:
        raise LatticeError(f"--footprint: a polygon needs at least 3 points, got {len(points)} (use --point "
                           "for a point robot)")
    return points


def run(args: argparse.Namespace) -> int:
    """Plan the problem `args` name and print it; 0 when a path reaches the goal, 1 when not.

    Raises:
        LatticeError: a bad option, or a file that cannot be read or does not fit the other.
    """
    # numba loads only here, so that building the parser stays quick
    from trials.lattice.environment import read_cfg
    from trials.lattice.planner import make_planner
    from trials.lattice.primitives import read_mprim

    if not args.eps >= 1 or not math.isfinite(args.eps):
        raise LatticeError(f"--eps: expected a number of at least 1, got {args.eps}")
    if not args.eps_step > 0:
        raise LatticeError(f"--eps-step: expected a positive number, got {args.eps_step}")
    if not args.budget > 0:
        raise LatticeError(f"--budget: expected a positive number of seconds, got {args.budget}")
    polygon = [] if args.point else parse_footprint(args.footprint)
    env = read_cfg(args.study / args.env)  # an absolute path stays as it is
    prims = read_mprim(args.study / args.prims)
    planner = make_planner(env, prims, polygon)
    result = planner.plan(eps=args.eps, eps_step=args.eps_step, budget=args.budget)
    iterations = [{"eps": it.eps, "cost": it.cost, "expansions": it.expansions, "seconds": it.seconds}
                  for it in result.iterations]
    if args.json:
        json.dump({"status": result.status, "message": result.message, "start": list(env.to_state(env.start)),
                   "goal": list(env.to_state(env.goal)), "cost": result.cost if result.states else None,
                   "eps": None if math.isinf(result.eps) else result.eps, "expansions": result.expansions,
                   "iterations": iterations, "heuristic_seconds": result.heuristic_seconds,
                   "seconds": result.seconds, "path": result.poses.round(4).tolist()}, sys.stdout)
        sys.stdout.write("\n")
    else:
        print(f"{args.env.name} + {args.prims.name}: {env.width} x {env.height} cells of {env.cell_size:g} m, "
              f"{env.num_thetas} headings, {prims.per_heading} primitives per heading, "
              f"{'point robot' if not polygon else f'footprint of {len(polygon)} points'}")
        print(f"start {env.to_state(env.start)} -> goal {env.to_state(env.goal)}; "
              f"heuristic {result.heuristic_seconds:.3f} s")
        if iterations:
            print(f"{'eps':>8} {'cost':>10} {'expansions':>11} {'seconds':>9}")
            for it in iterations:
                print(f"{it['eps']:8.3f} {it['cost']:10d} {it['expansions']:11d} {it['seconds']:9.3f}")
        print(f"status: {result.status}: {result.message}")
        if len(result.poses):
            print("path (x y theta):")
            for x, y, theta in result.poses:
                print(f"{x:.4f} {y:.4f} {theta:.4f}")
    return 0 if result.reached_goal else 1
