"""`trials score`: record evaluators' 1-2-3 scores of finished runs, by run code (blind: no controller shown)."""

from __future__ import annotations

import argparse
from pathlib import Path

from trials import option_types as types


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "score",
        help="record an evaluator's 1-2-3 score of a run (or import a scores file)",
        description=(
            "Record a human score of a finished run: 1 = collision, 2 = no collision but unnatural "
            "(turning in place, backing up, stopping or hesitating, passing within intimate distance), "
            "3 = natural and comfortable. Scores go to scores.csv; in the report the latest human score "
            "of a run overrides the automatic rubric score, and both are shown."
        ),
    )
    parser.add_argument("run_code", nargs="?", metavar="CODE", help="the run's code from plan.csv")
    parser.add_argument("score", nargs="?", metavar="1|2|3", help="the score")
    parser.add_argument("--by", metavar="NAME", help="the evaluator (default: your login name)")
    parser.add_argument("--note", default="", metavar="TEXT", help="a remark kept with the score")
    parser.add_argument("--import", dest="import_file", type=Path, metavar="FILE",
                        help="add every row of a CSV with columns run_code, score (and optionally scorer, note, recorded_utc)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from trials.errors import StudyError
    from trials.outcomes import check_run_codes, finished_codes
    from trials.scores import append_scores, read_scores, record_score
    from trials.study import SCORES, StudyFolder, utc_now

    folder = StudyFolder(args.study)
    if args.import_file is not None and (args.run_code or args.score):
        raise StudyError("give either CODE and SCORE or --import FILE, not both")
    if args.import_file is None and not (args.run_code and args.score):
        raise StudyError("give a run code and a score 1, 2 or 3 (e.g. `trials score NGAC3 3`), or --import FILE")
    scorer = args.by or _login()
    if args.import_file is None:
        value = record_score(folder, args.run_code, args.score, scorer, args.note).score
        print(f"Recorded score {value} for run {args.run_code} by {scorer}; it overrides the rubric's score in the report.")
        return 0
    plan_codes = [row["run_code"] for row in folder.read_plan()]
    finished = finished_codes(folder)
    now = utc_now()
    if not args.import_file.is_file():
        raise StudyError(f"no scores file at {args.import_file}")
    new = [replace(s, scorer=s.scorer or scorer, recorded_utc=s.recorded_utc or now) for s in read_scores(args.import_file)]
    check_run_codes([s.run_code for s in new], plan_codes, finished, f"{args.import_file.name} has scores")
    known = {(s.run_code, s.score, s.scorer, s.note) for s in read_scores(folder.path(SCORES))}
    fresh = [s for s in new if (s.run_code, s.score, s.scorer, s.note) not in known]
    if fresh:
        append_scores(folder, fresh)
    skipped = f"; {len(new) - len(fresh)} already recorded were skipped" if len(fresh) < len(new) else ""
    print(f"Imported {len(fresh)} score(s) from {args.import_file}{skipped}.")
    return 0


def _login() -> str:
    """The login name, the default evaluator."""
    import getpass

    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return "unnamed"
