"""Every write the console makes, one at a time, each through the module that owns its file: run events
(`trials.run_events`), uploaded logs (`trials.attached_logs`), a logged run's MCAP and outcome row as
`trials run --from-log` makes them (`trials.runner`; a corrected log as `trials run --rerun CODE --from-log`
replaces one, the earlier run moved to superseded/), scores (`trials.scores`) and judgments
(`trials.responses`). Each owner writes atomically, so a server killed mid-request leaves every file whole.
A live run is written by the `trials run --robot` it starts (`trials.console.live`); the console records its
start and how it ended.

Playing a log takes a while (loading the controllers, tracking the people), so it goes on in a thread of its own
under the study's run lock, one log at a time, while the pages and the other forms stay open; its run's page
follows it (`Console.playing`).

Errors are StudyError (or another user error) with one line saying what was wrong; nothing is written then.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from pathlib import Path

from analysis.records import HUMAN, HumanScore, Response
from trials.attached_logs import MAGIC, save_upload
from trials.console.live import LiveRuns, robot_uri
from trials.console.sheet import RunSheet, SheetRow, run_sheet
from trials.errors import USER_ERRORS, StudyError
from trials.log_trial import ReplayOptions
from trials.responses import read_responses, record_response
from trials.robot.settings import RobotSettings, read_robot_settings
from trials.robot.staging import StagedScene, staged_scene
from trials.run_events import ABORT, FINISH, FINISHED, LOG, MAX_DETAIL, NOTE, RUNNING, START, RunEvent, append_run_event, check_step
from trials.runner import RunOptions, StudyRun, run_study, utc_stamp
from trials.scores import read_scores, record_score
from trials.study import LOGS, PLAN, RESPONSES, RUN_EVENTS, SCORES, SPEC, StudyFolder, to_the_minute, utc_now

#: The suffix an earlier upload of a run is held under while a corrected log replaces it.
HELD = ".earlier"


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


@dataclass
class Playing:
    """A robot log being checked, tracked and played for a run in the background (`Console.attach_log`): the run, the
    log as run_events.csv names it, since when (UTC), whether it replaces the run's earlier log, and how it ended
    (`outcome`: the new outcome's status; `error`: why there is none)."""

    code: str
    log: str
    since_utc: str
    replacing: bool
    outcome: str = ""
    error: str = ""

    @property
    def running(self) -> bool:
        return not (self.outcome or self.error)


class Console:
    """The study folder behind `trials serve`; one lock serializes every write. `robot` (`trials serve --robot`)
    drives the runs live on that robot, as study.toml's [robot] table does."""

    def __init__(self, folder: StudyFolder, robot: str | None = None) -> None:
        self.folder = folder
        self._lock = threading.Lock()
        self._playing: dict[str, Playing] = {}
        self.live = LiveRuns(folder, robot_uri(folder, robot), self._live_ended)

    def sheet(self) -> RunSheet:
        return run_sheet(self.folder)

    def staging(self, code: str) -> StagedScene | None:
        """Where run `code`'s robot and walkers go (`trials.robot.staging`); None when the study is not driven live.

        Raises:
            StudyError: the study stages its rows on a start mark not measured yet, or its [robot] table is bad.
        """
        if self.live.uri is None:
            return None
        return staged_scene(self.folder, read_robot_settings(self.folder.path(SPEC)) or RobotSettings(), code)

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
            if (busy := self.playing_now()) is not None:
                raise StudyError(f"run {busy.code}'s log is being played; wait until its page shows the outcome before starting a live run")
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

    def attach_log(self, code: str, request: LogRequest, replace: bool = False) -> Playing:
        """Start playing a finished run's robot log as `trials run --from-log LOG --only CODE` does (checked, tracked,
        played through the run's controller in a worker process, written as runs/<code>.mcap and its outcome row), in
        the background; its page follows it (`playing`). An upload is kept as logs/<code>.bag or .mcap first. With
        `replace`, a corrected log replaces that of a run played from an attached log, as `trials run --rerun CODE
        --from-log LOG` does: the earlier run log, outcome row and upload move to superseded/<time>/.

        Raises:
            StudyError: another log is being played, the run is not finished, already has its outcome (without
                `replace`) or was not played from a log (with it), no log or two were given, or the upload is no robot log.
        """
        with self._lock:
            sheet, row = self.run(code)
            if (busy := self.playing_now()) is not None:
                raise StudyError(f"run {busy.code}'s log is being checked and played; one log at a time: wait until its page shows the outcome")
            if self.live.running is not None:
                raise StudyError(f"run {self.live.running} is being driven live; attach the log once it has ended")
            if replace and not row.external:
                raise StudyError(f"run {code} was not played from an attached robot log, so it has no log to correct")
            if row.outcome and not replace:
                raise StudyError(f"run {code} already has its outcome ({row.outcome}); its page's \"attach a corrected log\" replaces its log")
            if row.status != FINISHED:
                raise StudyError(f"run {code} is {row.status}: finish it before attaching its log")
            if bool(request.upload_name) == bool(request.path.strip()):
                raise StudyError(f"attach run {code}'s log either as an upload or by its path on this machine, not both or neither")
            earlier = self._uploads(code) if replace else []
            if request.upload_name:
                held = [self._hold(path) for path in earlier]
                try:
                    path = save_upload(self.folder, code, request.upload_name, request.upload)
                except BaseException:
                    self._restore(held)
                    raise
            else:
                path = Path(request.path.strip()).expanduser()
                path = path if path.is_absolute() else self.folder.root / path
                if not path.exists():
                    raise StudyError(f"no robot log at {path} on this machine")
                if any(path.resolve() == upload.resolve() for upload in earlier):
                    raise StudyError(f"{path} is run {code}'s earlier log, the one being corrected; give the corrected log")
                held = [self._hold(upload) for upload in earlier]
            shown = path.relative_to(self.folder.root) if path.is_relative_to(self.folder.root) else path
            job = Playing(code, str(shown), utc_now(), replace)
            self._playing[code] = job
        saved = path if request.upload_name else None
        threading.Thread(target=self._play, args=(job, path, saved, held, request), name=f"log-of-{code}", daemon=True).start()
        return job

    def playing(self, code: str) -> Playing | None:
        """The latest log played for run `code` from this console (going on, or how it ended), if any."""
        return self._playing.get(code)

    def playing_now(self) -> Playing | None:
        """The log being played now, if any (one at a time)."""
        return next((job for job in self._playing.values() if job.running), None)

    def _play(self, job: Playing, path: Path, saved: Path | None, held: list[tuple[Path, Path]], request: LogRequest) -> None:
        """Play the log (in its own thread), then record how that went."""
        superseded: Path | None = None
        outcome = error = ""
        try:
            study = StudyRun.open(self.folder, False, from_log=True)
            options = RunOptions(replay=ReplayOptions(path, request.goal, request.start_s, request.duration_s))
            failures: list[str] = []
            only, rerun = ([], [job.code]) if job.replacing else ([job.code], [])
            summary = run_study(study, 1, only, rerun, options, lambda count: None, lambda run: None,
                                lambda failed, message: failures.append(message))
            superseded = summary.superseded
            outcome = summary.finished[0].outcome.status if summary.finished and not failures else ""
            error = "" if outcome else failures[0] if failures else "no run was made"
        except USER_ERRORS as exc:
            error = str(exc)
        except Exception as exc:  # a crash in this thread would otherwise leave its run's page waiting for ever
            error = f"{type(exc).__name__}: {exc}"
        with self._lock:
            try:
                self._settle(job, bool(outcome), superseded, saved, held)
            finally:
                job.outcome, job.error = (outcome, "") if outcome else ("", f"run {job.code}: its log could not be played: {error}")

    def _settle(self, job: Playing, played: bool, superseded: Path | None, saved: Path | None, held: list[tuple[Path, Path]]) -> None:
        """After playing: the earlier uploads go with the run they made (superseded/<time>/logs/), or back where they were
        when the earlier run was kept; run_events.csv notes a correction and names the log played."""
        if job.replacing and superseded is None:
            if saved is not None:
                saved.unlink(missing_ok=True)
            self._restore(held)
            return
        for original, holding in held:
            target = superseded / LOGS / original.name if superseded is not None else original
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(holding, target)
        sheet = self.sheet()
        if superseded is not None:
            where = superseded.relative_to(self.folder.root)
            self._append(sheet, RunEvent(job.code, NOTE, f"log corrected: the earlier run log, outcome row and upload are kept in {where}/",
                                         utc_stamp(sheet.blind)))
        if played:
            self._append(sheet, RunEvent(job.code, LOG, job.log, utc_stamp(sheet.blind)))

    def _uploads(self, code: str) -> list[Path]:
        """Run `code`'s uploaded logs in logs/."""
        return [path for suffix in MAGIC if (path := self.folder.path(LOGS) / f"{code}{suffix}").exists()]

    def _hold(self, path: Path) -> tuple[Path, Path]:
        """Move an earlier upload out of the way of its correction (logs/<code>.bag.earlier); (where it was, where it is)."""
        holding = path.with_name(path.name + HELD)
        os.replace(path, holding)
        return path, holding

    @staticmethod
    def _restore(held: list[tuple[Path, Path]]) -> None:
        for original, holding in held:
            os.replace(holding, original)

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
        """Record a participant's judgment (and questionnaire answers) as `trials respond` does, of a run once its finish is
        recorded (before its log is played too); a second answer by the same participant to the same run is refused."""
        with self._lock:
            sheet, row = self.run(code)
            if row.status != FINISHED:
                raise StudyError(f"run {code} has not finished yet: its questionnaire opens once the robot has finished the run")
            if self.answered(code, participant):
                raise StudyError(f"participant {participant} has already answered for run {code}; nothing was added")
            finished = [other.code for other in sheet.rows if other.status == FINISHED]
            response, _ = record_response(self.folder, code, participant, answer, ratings, sheet.questionnaire, finished)
            self._minute(sheet)
            return response

    def answered(self, code: str, participant: str) -> bool:
        """Whether the participant has answered for run `code`."""
        return any(r.run_code == code and r.participant == participant and r.source == HUMAN for r in read_responses(self.folder.path(RESPONSES)))

    def _minute(self, sheet: RunSheet) -> None:
        """A blinded study's public files keep their times to the minute, as `trials run` leaves them."""
        if sheet.blind:
            to_the_minute(*(p for p in (self.folder.path(RUN_EVENTS), self.folder.path(RESPONSES)) if p.exists()), self.folder.root)
