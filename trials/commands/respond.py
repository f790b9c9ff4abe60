"""`trials respond`: record participants' judgments (socially compliant yes / no) by run code, or simulate them."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from trials import option_types as types
from trials.commands.run import MAX_PARTICIPANTS

if TYPE_CHECKING:
    from trials.study import StudyFolder


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "respond",
        help="record a participant's judgment of a run (or import them, or simulate them)",
        description=(
            "Record whether a participant judged a finished run socially compliant (yes / no) in "
            "responses.csv. --import adds a CSV of judgments; --simulate judges every finished run that "
            "has no judgments with the simulated-participant model (from each run's log), recorded as "
            "source=simulated with the seed. A participant's later judgment of a run replaces the earlier one."
        ),
    )
    parser.add_argument("run_code", nargs="?", metavar="CODE", help="the run's code from plan.csv")
    parser.add_argument("participant", nargs="?", metavar="PARTICIPANT", help="the participant's name or id")
    parser.add_argument("answer", nargs="?", metavar="yes|no", help="judged socially compliant?")
    action = parser.add_mutually_exclusive_group()
    action.add_argument("--import", dest="import_file", type=Path, metavar="FILE",
                        help="add every row of a CSV with columns run_code, participant, compliant (and optionally source, recorded_utc, seed)")
    action.add_argument("--simulate", action="store_true", help="simulate judgments of every finished run that has none")
    parser.add_argument("--participants", type=types.whole(1, MAX_PARTICIPANTS), metavar="N",
                        help="with --simulate: judgments per run (default: one per pedestrian of the run)")
    parser.add_argument("--seed", type=types.seed, metavar="S", help="with --simulate: the seed (default: drawn and recorded)")
    parser.add_argument("--allow-simulated", action="store_true",
                        help="with --simulate or --import: enter simulated judgments even in a field study (runs driven live "
                        "or played from robot logs)")
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from trials.errors import StudyError
    from trials.field_study import refuse_simulation
    from trials.outcomes import finished_codes
    from trials.study import StudyFolder

    folder = StudyFolder(args.study)
    positional = [args.run_code, args.participant, args.answer]
    if (args.import_file is not None or args.simulate) and any(positional):
        raise StudyError("give either CODE PARTICIPANT yes|no, or --import FILE, or --simulate; not several")
    if (args.participants is not None or args.seed is not None) and not args.simulate:
        raise StudyError("--participants and --seed go with --simulate")
    if args.allow_simulated and not (args.simulate or args.import_file is not None):
        raise StudyError("--allow-simulated goes with --simulate or --import")
    plan_codes = [row["run_code"] for row in folder.read_plan()]
    finished = finished_codes(folder)
    if args.simulate:
        if not args.allow_simulated:
            refuse_simulation(folder, bool(folder.read_design().get("blinding")), "simulate participants' judgments")
        return _simulate(folder, finished, args.participants, args.seed)
    if args.import_file is not None:
        return _import(folder, args.import_file, plan_codes, finished, args.allow_simulated)
    if not all(positional):
        raise StudyError("give a run code, a participant and yes or no (e.g. `trials respond NGAC3 P07 yes`), --import FILE or --simulate")
    return _record_one(folder, args.run_code, args.participant, args.answer)


def _record_one(folder: StudyFolder, code: str, participant: str, answer: str) -> int:
    from trials.responses import record_response

    response, earlier = record_response(folder, code, participant, answer)
    judged = "socially compliant" if response.compliant else "not socially compliant"
    print(f"Recorded: {participant} judged run {code} {judged}" + ("; this replaces their earlier judgment." if earlier else "."))
    return 0


def _import(folder: StudyFolder, path: Path, plan_codes: list[str], finished: list[str], allow_simulated: bool) -> int:
    from dataclasses import replace

    from analysis.records import SIMULATED
    from trials.errors import StudyError
    from trials.field_study import refuse_simulation
    from trials.outcomes import check_run_codes
    from trials.responses import append_responses, read_responses
    from trials.study import RESPONSES, utc_now

    if not path.is_file():
        raise StudyError(f"no responses file at {path}")
    now = utc_now()
    new = [replace(r, recorded_utc=r.recorded_utc or now) for r in read_responses(path)]
    check_run_codes([r.run_code for r in new], plan_codes, finished, f"{path.name} has judgments")
    simulated = [line for line, r in enumerate(new, start=2) if r.source == SIMULATED]
    if simulated and not allow_simulated:
        refuse_simulation(folder, bool(folder.read_design().get("blinding")),
                          f"import {len(simulated)} simulated judgment(s) from {path} (source simulated, first on line {simulated[0]})")
    known = {(r.run_code, r.participant, r.compliant, r.source) for r in read_responses(folder.path(RESPONSES))}
    fresh = [r for r in new if (r.run_code, r.participant, r.compliant, r.source) not in known]
    if fresh:
        append_responses(folder, fresh)
    skipped = f"; {len(new) - len(fresh)} already recorded were skipped" if len(fresh) < len(new) else ""
    print(f"Imported {len(fresh)} judgment(s) from {path}{skipped}.")
    return 0


def _simulate(folder: StudyFolder, finished: list[str], participants: int | None, seed: int | None) -> int:
    import secrets

    from trials.errors import StudyError
    from trials.simulated_participants import simulate_runs
    from trials.study import OUTCOMES, RESPONSES

    if not finished:
        raise StudyError(f"no finished runs in {OUTCOMES} to simulate judgments of: run `trials run` first")
    seed = secrets.randbits(31) if seed is None else seed
    responses, skipped = simulate_runs(folder, finished, seed, participants)
    runs = len({r.run_code for r in responses})
    print(f"Simulated {len(responses)} judgment(s) of {runs} run(s) with seed {seed} (source=simulated in {RESPONSES}).")
    if len(responses) == 0 and not skipped:
        print("Every finished run already has judgments.")
    for entry in skipped:
        print(f"skipped {entry}")
    return 0
