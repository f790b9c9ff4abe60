"""Every write the console makes, one at a time, each through the module that owns its file: run events
(`trials.run_events`), uploaded logs (`trials.attached_logs`), a logged run's MCAP and outcome row as
`trials run --from-log` makes them (`trials.runner`), scores (`trials.scores`) and judgments
(`trials.responses`). Each owner writes atomically, so a server killed mid-request leaves every file whole.
A live run is written by the `trials run --robot` it starts (`trials.console.live`); the console records its
start and how it ended.

Errors are StudyError (or another user error) with one line saying what was wrong; nothing is written then.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

from analysis.records import HUMAN, HumanScore, Response
from trials.attached_logs import save_upload
from trials.console.live import LiveRuns, robot_uri
from trials.console.sheet import RunSheet, SheetRow, run_sheet
from trials.errors import StudyError
from trials.log_trial import ReplayOptions
from trials.responses import read_responses, record_response
from trials.run_events import ABORT, FINISH, FINISHED, LOG, MAX_DETAIL, RUNNING, START, RunEvent, append_run_event, check_step
from trials.runner import RunDone, RunOptions, StudyRun, run_study, utc_stamp
from trials.scores import read_scores, record_score
from trials.study import PLAN, RESPONSES, RUN_EVENTS, SCORES, StudyFolder, to_the_minute


class UnknownRun(StudyError):
    """A run code that the plan does not have (its page: not found)."""


@dataclass(frozen=True)
class LogRequest:
    """A robot log to attach: an uploaded file (its name and bytes) or a path on this machine (absolute,
    or relative to the study folder), with the part of it to play and the goal (`trials run --from-log`'s options)."""

    upload_name: str = ""
    upload: bytes = b""
    path: str = ""
    goal: tuple[float, float] | None = None
    start_s: float = 0.0
    duration_s: float | None = None


class Console:
    """The study folder behind `trials serve`; one lock serializes every write. `robot` (`trials serve --robot`)
    drives the runs live on that robot, as study.toml's [robot] table does."""

    def __init__(self, folder: StudyFolder, robot: str | None = None) -> None:
        self.folder = folder
        self._lock = threading.Lock()
        self.live = LiveRuns(folder, robot_uri(folder, robot), self._live_ended)

    def sheet(self) -> RunSheet:
        return run_sheet(self.folder)

    def run(self, code: str) -> tuple[RunSheet, SheetRow]:
        """The sheet and run `code`'s row; UnknownRun when the plan has no such run."""
        sheet = self.sheet()
        row = sheet.row(code)
        if row is None:
            raise UnknownRun(f"run {code!r} is not in {PLAN}")
        return sheet, row

    def record_event(self, code: str, event: str, detail: str = "") -> RunEvent:
        """Start, finish or abort run `code`, or add a note to it (times to the minute in a blinded study). In a study
        driven live, Start is `start_live`, and a run being driven live ends by itself or by E-STOP."""
        with self._lock:
            sheet, row = self.run(code)
            check_step(code, event, row.status, detail)
            if event == START and self.live.uri is not None:
                raise StudyError(f"this study's runs are driven live on {self.live.uri}: the run page's Start starts run {code} on the robot")
            if event in (FINISH, ABORT) and self.live.running == code:
                raise StudyError(f"run {code} is being driven live: it ends by itself, or press E-STOP to stop it now")
            return self._append(sheet, RunEvent(code, event, detail.strip(), utc_stamp(sheet.blind)))

    def start_live(self, code: str) -> RunEvent:
        """Start driving run `code` live (`trials run --robot URI --only CODE` in the background) and record its start;
        refused when the study is not driven live, the run cannot start, or another live run is going."""
        with self._lock:
            sheet, row = self.run(code)
            uri = self.live.robot()
            check_step(code, START, row.status, "")
            self.live.start(code)
            try:
                return self._append(sheet, RunEvent(code, START, f"driven live on {uri}", utc_stamp(sheet.blind)))
            except BaseException:
                self.live.estop()
                raise

    def _live_ended(self, code: str, finished: bool, reason: str) -> None:
        """Record how a live run ended: finished (its outcome row is there) or aborted, and why (one line)."""
        with self._lock:
            sheet, row = self.run(code)
            if row.status == RUNNING:
                detail = " ".join(reason.split())[:MAX_DETAIL] or "stopped"
                self._append(sheet, RunEvent(code, FINISH, "", utc_stamp(sheet.blind)) if finished else
                             RunEvent(code, ABORT, detail, utc_stamp(sheet.blind)))

    def _append(self, sheet: RunSheet, record: RunEvent) -> RunEvent:
        append_run_event(self.folder, record)
        self._minute(sheet)
        return record

    def attach_log(self, code: str, request: LogRequest) -> RunDone:
        """Play a finished run's robot log as `trials run --from-log LOG --only CODE` does: checked, tracked,
        played through the run's controller in a worker process, written as runs/<code>.mcap and its
        outcome row. An upload is kept as logs/<code>.bag or .mcap first."""
        with self._lock:
            sheet, row = self.run(code)
            if row.outcome:
                raise StudyError(f"run {code} already has its outcome ({row.outcome}); `trials run --rerun {code} --from-log LOG` replaces it")
            if row.status != FINISHED:
                raise StudyError(f"run {code} is {row.status}: finish it before attaching its log")
            if bool(request.upload_name) == bool(request.path.strip()):
                raise StudyError(f"attach run {code}'s log either as an upload or by its path on this machine, not both or neither")
            if request.upload_name:
                path = save_upload(self.folder, code, request.upload_name, request.upload)
            else:
                path = Path(request.path.strip()).expanduser()
                path = path if path.is_absolute() else self.folder.root / path
            study = StudyRun.open(self.folder, False, from_log=True)
            options = RunOptions(replay=ReplayOptions(path, request.goal, request.start_s, request.duration_s))
            failures: list[str] = []
            summary = run_study(study, 1, [code], [], options, lambda count: None, lambda run: None,
                                lambda failed, message: failures.append(message))
            if failures or not summary.finished:
                raise StudyError(f"run {code}: its log could not be played: {failures[0] if failures else 'no run was made'}")
            shown = path.relative_to(self.folder.root) if path.is_relative_to(self.folder.root) else path
            self._append(sheet, RunEvent(code, LOG, str(shown), utc_stamp(sheet.blind)))
            return summary.finished[0]

    def score(self, code: str, score: str, scorer: str, note: str) -> HumanScore:
        """Record an evaluator's score as `trials score` does; the same score by the same scorer again is refused."""
        with self._lock:
            self.run(code)
            scorer, note = scorer.strip(), note.strip()
            if not scorer or not scorer.isprintable() or not note.isprintable():
                raise StudyError(f"the score of run {code} needs the scorer's name, and name and note must be one line each")
            if any((s.run_code, str(s.score), s.scorer, s.note) == (code, score.strip(), scorer, note) for s in read_scores(self.folder.path(SCORES))):
                raise StudyError(f"{scorer} has already recorded score {score.strip()} for run {code}; nothing was added")
            return record_score(self.folder, code, score, scorer, note)

    def respond(self, code: str, participant: str, answer: str, ratings: dict[str, str]) -> Response:
        """Record a participant's judgment (and questionnaire answers) as `trials respond` does; a second
        answer by the same participant to the same run is refused."""
        with self._lock:
            sheet, _ = self.run(code)
            if self.answered(code, participant):
                raise StudyError(f"participant {participant} has already answered for run {code}; nothing was added")
            response, _ = record_response(self.folder, code, participant, answer, ratings, sheet.questionnaire)
            self._minute(sheet)
            return response

    def answered(self, code: str, participant: str) -> bool:
        """Whether the participant has answered for run `code`."""
        return any(r.run_code == code and r.participant == participant and r.source == HUMAN for r in read_responses(self.folder.path(RESPONSES)))

    def _minute(self, sheet: RunSheet) -> None:
        """A blinded study's public files keep their times to the minute, as `trials run` leaves them."""
        if sheet.blind:
            to_the_minute(*(p for p in (self.folder.path(RUN_EVENTS), self.folder.path(RESPONSES)) if p.exists()), self.folder.root)
