"""run_events.csv, the experimenter's record of the field day: when each run started and finished, why
one was aborted, notes and attached logs. Its columns (the fields of `RunEvent`), its one reader and
its one writer (appends), and a run's status from its events.

A run's status is its latest start, finish or abort: pending before any, then running, finished or
aborted; an aborted run may start again. A run with an outcome row and no events (run from the
command line) is finished.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from trials.csv_table import append_rows, parse_rows, read_table, record_columns, record_row, utc_cell
from trials.errors import StudyError
from trials.study import RUN_EVENTS, StudyFolder

START, FINISH, ABORT, NOTE, LOG = "start", "finish", "abort", "note", "log"
EVENTS = (START, FINISH, ABORT, NOTE, LOG)
PENDING, RUNNING, FINISHED, ABORTED = "pending", "running", "finished", "aborted"
#: The status each event that changes it leads to.
STATUS_AFTER = {START: RUNNING, FINISH: FINISHED, ABORT: ABORTED}
#: The statuses from which each such event may come.
ALLOWED_FROM = {START: (PENDING, ABORTED), FINISH: (RUNNING,), ABORT: (RUNNING,)}
#: A note or an abort reason is one line of at most this many characters.
MAX_DETAIL = 500


@dataclass(frozen=True)
class RunEvent:
    """One row of run_events.csv: which run, what happened, its detail (abort reason, note, log path), when."""

    run_code: str
    event: str
    detail: str
    recorded_utc: str


def read_run_events(path: Path) -> list[RunEvent]:
    """The events of a run_events.csv in file order ([] when there is none)."""
    return parse_rows(path, read_table(path, ("run_code", "event")), _event)


def append_run_event(folder: StudyFolder, event: RunEvent) -> None:
    """Add an event to the study's run_events.csv."""
    header = record_columns(RunEvent)
    append_rows(folder.path(RUN_EVENTS), header, [record_row(event, header)])


def statuses(codes: Sequence[str], events: Iterable[RunEvent], finished: Iterable[str]) -> dict[str, str]:
    """Each run's status by its latest start, finish or abort (finished when it has an outcome row and no such event)."""
    latest: dict[str, str] = {}
    for event in events:
        if event.event in STATUS_AFTER:
            latest[event.run_code] = STATUS_AFTER[event.event]
    done = set(finished)
    return {code: latest.get(code, FINISHED if code in done else PENDING) for code in codes}


def check_step(code: str, event: str, status: str, detail: str) -> None:
    """StudyError unless `event` may follow a run in `status` and its detail is one line (a reason for an abort, text for a note)."""
    if event not in EVENTS:
        raise StudyError(f"unknown event {event!r} for run {code} (expected one of {', '.join(EVENTS)})")
    allowed = ALLOWED_FROM.get(event)
    if allowed is not None and status not in allowed:
        raise StudyError(f"run {code} is {status}: it cannot {event} (only a run that is {' or '.join(allowed)} can)")
    if "\n" in detail or "\r" in detail or len(detail) > MAX_DETAIL:
        raise StudyError(f"the {event} text of run {code} must be one line of at most {MAX_DETAIL} characters")
    if event in (ABORT, NOTE) and not detail.strip():
        raise StudyError(f"{'an abort needs a reason' if event == ABORT else 'the note is empty'} (run {code})")


def _event(row: dict[str, str]) -> RunEvent:
    if row["event"] not in EVENTS:
        raise ValueError(f"event must be one of {', '.join(EVENTS)}, got {row['event']!r}")
    return RunEvent(row["run_code"], row["event"], row.get("detail", ""), utc_cell(row.get("recorded_utc", "")))
