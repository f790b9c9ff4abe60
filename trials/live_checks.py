"""live_checks.csv, the manipulation checks of live runs and the protocol-deviation log: its columns, one reader, one writer.

After every live run, finished or aborted, `trials run --robot` appends a check: how the run ended, the people its row
asked for and the most tracked near the robot at once (`trials.robot.people_check`), and a flag when the row's
condition was not met or the run ended early (a timeout; an abort: e-stop, stall, protective stop, stale sensors, a dead
worker). The operator decides each flagged run that finished with `trials deviation CODE --stands|--rerun --reason TEXT`,
appended as a decision row; an aborted run is no data and stays pending, so it is decided `rerun` as it is recorded.
The file only grows: a run's state is its latest check and the decisions after it (CONSORT's deviations, with reasons).
Blinded studies record times to the minute, as every public file does.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from analysis.records import LiveCheck
from trials.csv_table import append_rows, parse_rows, read_table, text_cell, utc_cell
from trials.errors import StudyError
from trials.numbers import number_in
from trials.robot.people_check import PeopleCheck
from trials.study import StudyFolder, to_the_minute, utc_now

FILE = "live_checks.csv"
COLUMNS = ("run_code", "recorded_utc", "ending", "asked", "seen", "seen_at_s", "condition", "flag", "decision", "reason")
#: The condition column's words.
MET, NOT_MET = "met", "not met"
STANDS, RERUN = "stands", "rerun"
DECISIONS = (STANDS, RERUN)
#: Endings that are data as they are; any other ending is flagged.
AS_PLANNED = ("goal", "collision")
ABORTED = "aborted"
#: The longest reason or flag kept.
MAX_TEXT = 500


def flag_of(ending: str, detail: str, people: PeopleCheck | None) -> str:
    """Why a live run is flagged ('' when it ended as planned and met its row's condition)."""
    reasons = [] if ending in AS_PLANNED else [f"{ending}: {detail}" if detail else ending]
    if people is not None and not people.met:
        reasons.append(people.describe())
    return "; ".join(reasons)[:MAX_TEXT]


def record_check(folder: StudyFolder, code: str, ending: str, detail: str, people: PeopleCheck | None, blind: bool) -> LiveCheck:
    """Append run `code`'s check; an aborted run is decided `rerun` at once (it stays pending)."""
    flag = flag_of(ending, detail, people)
    check = LiveCheck(code, utc_now(to_the_minute=blind), ending, people.asked if people else None, people.seen if people else None,
                      people.seen_at_s if people else None, people.met if people else None, flag, RERUN if ending == ABORTED else "",
                      "an aborted run is not data: it stays pending and is run again" if ending == ABORTED else "")
    _append(folder, [check], blind)
    return check


def record_decision(folder: StudyFolder, code: str, decision: str, reason: str, blind: bool) -> LiveCheck:
    """Append the operator's decision on flagged run `code`.

    Raises:
        StudyError: an unknown decision, no reason, a run never driven live, one not flagged, or an aborted one (it is rerun).
    """
    if decision not in DECISIONS:
        raise StudyError(f"decision must be one of {', '.join(DECISIONS)}, got {decision!r}")
    reason = reason.strip()
    if not reason:
        raise StudyError("a deviation's decision needs its reason (--reason TEXT)")
    if len(reason) > MAX_TEXT or not reason.isprintable():
        raise StudyError(f"--reason must be one line of at most {MAX_TEXT} characters of text")
    latest = read_checks(folder).get(code)
    if latest is None:
        raise StudyError(f"run {code} has no live check in {folder.path(FILE)}: only runs driven live are decided here")
    if not latest.flag:
        raise StudyError(f"run {code} is not flagged (it ended {latest.ending} and met its row's condition): nothing to decide")
    if latest.ending == ABORTED:
        raise StudyError(f"run {code} was aborted: it is no data and stays pending; `trials run --robot` runs it again")
    decided = replace(latest, recorded_utc=utc_now(to_the_minute=blind), decision=decision, reason=reason)
    _append(folder, [LiveCheck(code, decided.recorded_utc, "", None, None, None, None, "", decision, reason)], blind)
    return decided


def read_check_log(folder: StudyFolder) -> list[LiveCheck]:
    """Every live run's checks in the order they were made, each with the latest decision on it ([] without the file).

    Raises:
        StudyError: a damaged file, naming its line and column.
    """
    path = folder.path(FILE)
    log: list[LiveCheck] = []
    latest: dict[str, int] = {}
    for entry in parse_rows(path, read_table(path, COLUMNS), _entry):
        if entry.ending:
            latest[entry.run_code] = len(log)
            log.append(entry)
        elif entry.run_code in latest:
            at = latest[entry.run_code]
            log[at] = replace(log[at], decision=entry.decision, reason=entry.reason)
    return log


def read_checks(folder: StudyFolder) -> dict[str, LiveCheck]:
    """Each live run's state: its latest check with the latest decision on it, by run code."""
    return {check.run_code: check for check in read_check_log(folder)}


def _append(folder: StudyFolder, entries: list[LiveCheck], blind: bool) -> None:
    path: Path = folder.path(FILE)
    append_rows(path, COLUMNS, ([e.run_code, e.recorded_utc, e.ending, _cell(e.asked), _cell(e.seen),
                                 "" if e.seen_at_s is None else f"{e.seen_at_s:.1f}",
                                 "" if e.condition_met is None else MET if e.condition_met else NOT_MET, e.flag, e.decision, e.reason]
                                for e in entries))
    if blind:
        to_the_minute(path, folder.root)


def _cell(value: int | None) -> str:
    return "" if value is None else str(value)


def _entry(row: dict[str, str]) -> LiveCheck:
    if not row["run_code"]:
        raise ValueError("run_code is empty")
    if row["condition"] not in ("", MET, NOT_MET):
        raise ValueError(f"condition must be empty, {MET!r} or {NOT_MET!r}, got {row['condition']!r}")
    if row["decision"] not in ("", *DECISIONS):
        raise ValueError(f"decision must be empty or one of {', '.join(DECISIONS)}, got {row['decision']!r}")

    def whole(column: str) -> int | None:
        return None if not row[column] else int(number_in(row[column], column, 0, 1000))

    return LiveCheck(row["run_code"], utc_cell(row["recorded_utc"], required=True), row["ending"], whole("asked"), whole("seen"),
                     None if not row["seen_at_s"] else number_in(row["seen_at_s"], "seen_at_s", 0, 86_400),
                     None if not row["condition"] else row["condition"] == MET, text_cell(row["flag"], "flag", MAX_TEXT),
                     row["decision"], text_cell(row["reason"], "reason", MAX_TEXT))
