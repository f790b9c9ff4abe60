"""`trials deviation`: the operator's decision on a flagged live run (the protocol-deviation log, `trials.live_checks`)."""

from __future__ import annotations

import argparse

from trials import option_types as types


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "deviation",
        help="decide a flagged live run: it stands as data, or is rerun (with a reason)",
        description=(
            "List the live runs flagged in live_checks.csv (their row's condition was not met, or they ended early: a timeout, "
            "an abort), or decide one: --stands keeps it as data; --rerun moves its log and outcome row to superseded/ so that "
            "the next `trials run --robot` drives it again. Each decision is kept with its reason and shown on the run sheet "
            "and in the report, counted per arm."
        ),
    )
    parser.add_argument("code", nargs="?", metavar="CODE", help="the run to decide (without it: list the flagged runs)")
    decision = parser.add_mutually_exclusive_group()
    decision.add_argument("--stands", action="store_true", help="the run stands as data")
    decision.add_argument("--rerun", action="store_true", help="the run is driven again; this one is kept in superseded/")
    parser.add_argument("--reason", default="", metavar="TEXT", help="why (required with --stands or --rerun)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from trials.errors import StudyError
    from trials.live_checks import RERUN, STANDS, read_checks, record_decision
    from trials.outcomes import Outcomes
    from trials.runner import study_lock, supersede_runs
    from trials.study import StudyFolder

    folder = StudyFolder(args.study)
    blind = bool(folder.read_design().get("blinding"))
    if args.code is None:
        if args.stands or args.rerun:
            raise StudyError("--stands and --rerun decide one run: give its CODE")
        flagged = [check for check in read_checks(folder).values() if check.flag]
        for check in flagged:
            decided = f"{check.decision}: {check.reason}" if check.decision else "undecided"
            print(f"{check.run_code}  {check.flag}  [{decided}]")
        print(f"{len(flagged)} flagged live run(s), {sum(c.undecided for c in flagged)} undecided")
        return 0
    if not (args.stands or args.rerun):
        raise StudyError(f"decide run {args.code} with --stands or --rerun, and --reason TEXT")
    if args.code not in {row["run_code"] for row in folder.read_plan()}:
        raise StudyError(f"run {args.code} is not in the plan")
    with study_lock(folder):
        decided = record_decision(folder, args.code, RERUN if args.rerun else STANDS, args.reason, blind)
        if args.rerun:
            outcomes = Outcomes(folder, blind)
            if args.code in outcomes.finished:
                where = supersede_runs(folder, outcomes, [args.code], folder.aside_stamp())
                print(f"Run {args.code} will be driven again: its log and outcome row moved to {where}")
    print(f"Run {args.code}: {decided.decision} ({decided.reason}); flagged for: {decided.flag}")
    return 0
