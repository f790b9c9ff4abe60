"""`trials status`: a study's state at a glance, from its public files only (never the sealed key)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from trials import option_types as types

if TYPE_CHECKING:
    from trials.study_status import StudyStatus


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "status",
        help="a study's state: runs finished, pending, aborted and failed, judgments, scores, report, blinding",
        description=(
            "Show the runs planned, finished (by how they ended), pending, aborted (interrupted, a partial log left) "
            "and failed, per arm label in a blinded study (per controller in an open one); the judgments and scores "
            "collected; whether the report is older than the data; whether the study has been unblinded; the run "
            "settings; and whether runs/.lock is held or was left stale by a killed `trials run`. Reads only "
            "public files: the sealed key is never opened."
        ),
    )
    parser.add_argument("--study", type=types.folder, default=types.folder("."), metavar="DIR", help="the study folder (default: current folder)")
    parser.add_argument("--json", action="store_true", help="print the status as one JSON object")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import json

    from trials.study import StudyFolder
    from trials.study_status import study_status

    status = study_status(StudyFolder(args.study))
    if args.json:
        print(json.dumps(status.record()))
    else:
        print("\n".join(status_lines(status)))
    return 0


def redo(status: StudyStatus) -> str:
    """How an unfinished run of this study is run again: live on its robot, from the robot's log in a field study
    without one, else simulated."""
    if status.robot:
        return f"`trials run --robot {status.robot}` drives them again"
    if status.field:
        return "attach their logs in `trials serve`, or play them with `trials run --from-log LOG --only CODE`"
    return "the next `trials run` redoes them"


def status_lines(status: StudyStatus) -> list[str]:
    """The text of `trials status`."""
    from trials.study import DESIGN, RUN_LOCK, SPEC

    kind = "blinded" if status.blinded else "open"
    lines = [f"{status.name} ({kind} study) in {status.root}",
             f"runs: {status.finished} of {status.planned} finished"]
    word = "arm" if status.blinded else (status.arm_factor or "").lower()
    for arm, counts in status.arms.items():
        ended = ", ".join(f"{n} {s}" for s, n in counts.finished.items())
        rest = ", ".join(f"{getattr(counts, what)} {what}" for what in ("pending", "running", "aborted", "failed")
                         if getattr(counts, what) or what == "pending")
        label = f"{word} {arm}" if status.arm_factor else "all runs"
        lines.append(f"  {label}: {counts.planned} planned; finished {ended}; {rest}")
    for code, reason in status.failed.items():
        lines.append(f"  failed {code}: {reason}")
    if status.aborted:
        lines.append(f"  aborted (a partial log left): {', '.join(status.aborted)}; {redo(status)}")
    lines.append(f"judgments: {status.responses['human']} human, {status.responses['simulated']} simulated, "
                 f"of {status.judged_runs} runs; scores: {status.scores}, of {status.scored_runs} runs")
    lines.append(f"run settings ([run] of {SPEC}): {status.settings.describe()}")
    if status.robot is not None:
        lines.append(f"robot ([robot] of {SPEC}): {status.robot}; `trials run --robot {status.robot}` drives the pending runs")
    if status.checked:
        lines.append(f"  live checks: {status.checked} run(s); "
                     + (f"flagged without a decision: {', '.join(status.undecided)} (`trials deviation CODE --stands|--rerun --reason TEXT`)"
                        if status.undecided else "no flagged run awaits a decision"))
    if status.live is not None:
        live = status.live
        lines.append(f"  last live run {live.get('run_code', '?')}: {live.get('state', '?')} since {live.get('since_utc', '?')}"
                     + (f" ({live['detail']})" if live.get("detail") else ""))
    if len(status.recorded_settings) > 1:
        from trials.run_settings import recorded_text

        mixed = "; ".join(f"{n} runs with {recorded_text(key)}" for key, n in status.recorded_settings.items())
        lines.append(f"  finished runs were made with different settings: {mixed}")
    report = {"none": "none yet (`trials report`)", "current": "up to date with the data",
              "older than the data": "older than the data: run `trials report` again"}[status.report]
    lines.append(f"report: {report}")
    if status.blinded:
        opened = f"yes, on {', '.join(status.unblinded_utc)}" if status.unblinded_utc else "no (the sealed key is closed)"
        lines.append(f"unblinded: {opened}")
    if not status.design_digest:
        lines.append(f"note: {DESIGN} has no digest of its own content (an earlier release wrote it), so a hand edit of it "
                     "would go unnoticed")
    lock = status.lock
    if lock.held:
        lines.append(f"lock: a `trials run` is running on the study (pid {lock.pid})")
    elif lock.stale:
        lines.append(f"lock: {RUN_LOCK} is stale (pid {lock.pid}, a `trials run` that no longer runs: killed, or of an earlier "
                     "release); the next `trials run` takes it over")
    return lines
