"""`trials power`: the power of the study's plan (or of plans of other sizes) to show its effects, by
model-based simulation and by whole closed-loop campaigns, in local processes or on a Ray cluster."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_logs.physical import STEP_S
from trials import option_types as types
from trials.commands.run import MAX_PARTICIPANTS
from trials.run_settings import MAX_TIMEOUT_S, PERCEPTIONS

MAX_SIMULATIONS = 100_000
MAX_CAMPAIGNS = 100_000
MAX_WORKERS = 256
MAX_BATCH = 1000


def _shares(text: str) -> tuple[float, float]:
    """Two different shares LOW,HIGH in (0, 1)."""
    share = types.number(0.0, 1.0, above=True, below=True)
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected two shares LOW,HIGH in (0, 1), e.g. 0.67,0.75, got {text!r}")
    low, high = share(parts[0].strip()), share(parts[1].strip())
    if low == high:
        raise argparse.ArgumentTypeError(f"expected two different shares, got {text!r}")
    return low, high


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "power",
        help="estimate the power of the study's plan (model-based and closed-loop simulation)",
        description=(
            "Estimate how likely the study's plan is to show its effects. Model-based: judgments drawn from anticipated "
            "effects on the plan's model terms (logit scale, between-run variance) and a Gaussian outcome, each data set "
            "analysed as `trials report` does. Closed-loop (--campaigns K): K whole simulated campaigns through the real "
            "controllers and simulated participants, each with fresh seeds and its own allocation. --runs designs the "
            "D-optimal plan of each size from the study's spec. Writes power/ (power.md, power.json, power.csv, power.png); "
            "an interrupted run resumes from power.csv."
        ),
    )
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--out", type=types.folder, metavar="DIR", help="where to write (default: STUDY/power)")
    parser.add_argument("--seed", type=types.whole(0, 2**53 - 1), metavar="S",
                        help="the power seed every campaign's and data set's seeds derive from (default: the one in OUT/power.json, else drawn)")
    parser.add_argument("--simulations", type=types.whole(1, MAX_SIMULATIONS), default=400, metavar="N",
                        help="model-based data sets per plan (default 400)")
    parser.add_argument("--campaigns", type=types.whole(1, MAX_CAMPAIGNS), metavar="K", help="closed-loop campaigns per plan (default: none)")
    parser.add_argument("--runs", type=types.listed(types.whole(1, 1000), "run counts"), metavar="LIST",
                        help="plan sizes to compare, e.g. 18,36,54,72: the D-optimal plan of each from the study's spec (default: the study's own plan)")
    parser.add_argument("--target", type=types.number(0.0, 1.0, above=True, below=True), default=0.8, metavar="P",
                        help="the power a plan should reach on the Controller term (else every term; default 0.8)")
    parser.add_argument("--shares", type=_shares, default=(0.5, 0.8), metavar="LOW,HIGH",
                        help="model-based: the shares of yes whose logits span each anticipated effect, as skpr does (default 0.5,0.8)")
    parser.add_argument("--terms", type=types.listed(str, "model terms"), metavar="LIST",
                        help="model-based: only these terms have an effect (default: every term)")
    parser.add_argument("--run-sd", type=types.number(0.0, 10.0), default=0.5, metavar="SD",
                        help="model-based: between-run standard deviation on the logit scale (default 0.5)")
    parser.add_argument("--participants", type=types.whole(1, MAX_PARTICIPANTS), metavar="N",
                        help="judgments per run (default: one per pedestrian of the run)")
    parser.add_argument("--controllers", type=types.listed(str, "controller names"), metavar="LIST",
                        help="closed-loop, blinded study: the controllers behind the arms (default for two arms: NaviGAN-R,Lattice); "
                             "the sealed key is never opened")
    parser.add_argument("--workers", type=types.whole(1, MAX_WORKERS), metavar="N", help="local worker processes (default 1; with --ray local, its CPUs)")
    parser.add_argument("--ray", metavar="ADDRESS", help="run the campaigns on the Ray cluster at HOST:PORT (or `local`); needs the ray extra")
    parser.add_argument("--batch", type=types.whole(1, MAX_BATCH), default=1, metavar="N", help="campaigns per worker task (default 1)")
    parser.add_argument("--perception", choices=PERCEPTIONS, help="closed-loop perception (default: the study's [run] table, else positions)")
    parser.add_argument("--timeout", type=types.number(STEP_S, MAX_TIMEOUT_S), metavar="S",
                        help="closed-loop: a run's time limit (default: the study's [run] table, else 60 s)")
    parser.add_argument("--weights", type=types.input_file, metavar="FILE",
                        help="closed-loop: NaviGAN-R's checkpoint (default: the study's [run] table, else the shipped weights)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from trials.power.study_power import PowerRequest, estimate_power
    from trials.study import POWER, StudyFolder

    folder = StudyFolder(args.study)
    out = args.out if args.out is not None else folder.path(POWER)
    request = PowerRequest(
        seed=args.seed, simulations=args.simulations, campaigns=args.campaigns, sizes=args.runs, target=args.target,
        shares=args.shares, terms=tuple(args.terms) if args.terms else None, run_sd=args.run_sd, participants=args.participants,
        controllers=tuple(args.controllers) if args.controllers else None, workers=args.workers, ray=args.ray, batch=args.batch,
        perception=args.perception, timeout_s=args.timeout, weights=str(args.weights) if args.weights else None,
    )
    outcome = estimate_power(folder, Path(out), request)
    print("\n".join(outcome.lines))
    return 0
