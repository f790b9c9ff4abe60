"""The run sheet as the console shows it: every plan row in order with its settings (a blinded factor's
arm label, never a controller), status and what has been recorded for it, and whether the study's key has
been opened (unblinding.json, through its owner). Read from the public study files only; the sealed
key is never opened."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from analysis.records import EXTERNAL_LOG, HUMAN, SIMULATED_RUN, SOFTWARE_ROBOT_RUN, LiveCheck, Outcome
from designs.questionnaire import LikertItem
from designs.spec import LOG_COLUMN, PLAN_COLUMNS, read_spec
from trials.controllers import registry
from trials.live_checks import read_checks
from trials.outcomes import read_outcomes
from trials.responses import read_responses
from trials.run_events import ABORT, ABORTED, FINISH, LOG, NOTE, PENDING, RUNNING, START, RunEvent, read_run_events, statuses
from trials.scenario import CONTROLLER
from trials.scores import read_scores
from trials.study import OUTCOMES, RESPONSES, RUN_EVENTS, SCORES, SPEC, StudyFolder
from trials.study_data import read_unblinding, run_origin


@dataclass(frozen=True)
class StudyKey:
    """The study's name, whether it is blinded, and when its sealed key was opened (`trials report --unblind`)."""

    name: str
    blind: bool
    unblinded_utc: tuple[str, ...] = ()

    @property
    def sealed(self) -> bool:
        """Blinded and never opened: no page compares the arms (that would be an unplanned interim look)."""
        return self.blind and not self.unblinded_utc


def study_key(folder: StudyFolder, design: dict[str, Any] | None = None) -> StudyKey:
    """The study's key state from design.json and unblinding.json (the openings of this design's key)."""
    design = folder.read_design() if design is None else design
    blinding = design.get("blinding") or {}
    opened = read_unblinding(folder, blinding["commitment"]["digest"]) if blinding else ()
    return StudyKey(str(design.get("study", "")), bool(blinding), opened)


def outcome_figures(outcome: Outcome) -> list[tuple[str, str]]:
    """A run's public outcome metrics as its page shows them, (label, value) in outcomes.csv's order."""

    def measure(value: float | None, unit: str, digits: int = 1) -> str:
        return "-" if value is None else f"{value:.{digits}f} {unit}"

    return [("Status", outcome.status), ("Duration", measure(outcome.duration_s, "s")), ("Time to goal", measure(outcome.time_to_goal_s, "s")),
            ("Path length", measure(outcome.path_length_m, "m", 2)), ("Closest gap", measure(outcome.min_distance_m, "m", 2)),
            ("Within 0.5 m", measure(outcome.time_within_0_5m_s, "s")), ("Within 1.2 m", measure(outcome.time_within_1_2m_s, "s")),
            ("Collisions", str(outcome.collisions))]


@dataclass(frozen=True)
class SheetRow:
    """One run on the sheet: order, code, settings by factor, status, its outcome's status (empty until
    its log is played or its live run ends) and how the run was made (`analysis.records`: simulated, driven
    live, external log; empty without an outcome), counts of human scores and judgments, its events and its
    outcome row."""

    order: int
    code: str
    settings: dict[str, str]
    status: str
    outcome: str
    scores: int
    judgments: int
    events: list[RunEvent] = field(default_factory=list)
    origin: str = ""
    result: Outcome | None = None
    #: Its latest live run's manipulation check and deviation decision (`trials.live_checks`); None before one.
    check: LiveCheck | None = None

    @property
    def check_text(self) -> str:
        """The check as the sheet shows it: `ok`, or the flag and the operator's decision (or that none was made)."""
        if self.check is None:
            return ""
        if not self.check.flag:
            return "ok"
        return f"flagged: {self.check.flag} [{self.check.decision or 'undecided'}{': ' + self.check.reason if self.check.decision else ''}]"

    @property
    def figures(self) -> list[tuple[str, str]]:
        """Its outcome's public metrics (none before its outcome row), never its controller."""
        return outcome_figures(self.result) if self.result is not None else []

    @property
    def made(self) -> str:
        """How the run was made, as the sheet marks it: `driven live` or `external log` (nothing for a simulated run)."""
        return "" if self.origin == SIMULATED_RUN else self.origin

    @property
    def software_robot(self) -> bool:
        """Whether the run was driven live on the software robot (`trials robot-sim`): a rehearsal."""
        return self.origin == SOFTWARE_ROBOT_RUN

    @property
    def external(self) -> bool:
        """Whether the run was played from an external robot log: the toolkit did not drive it."""
        return self.origin == EXTERNAL_LOG

    def latest(self, kind: str) -> RunEvent | None:
        """The run's latest event of a kind (start, finish, abort, log)."""
        return next((e for e in reversed(self.events) if e.event == kind), None)

    @property
    def notes(self) -> list[RunEvent]:
        return [e for e in self.events if e.event in (NOTE, ABORT)]

    @property
    def started(self) -> str:
        event = self.latest(START)
        return event.recorded_utc if event else ""

    @property
    def finished(self) -> str:
        event = self.latest(FINISH)
        return event.recorded_utc if event else ""

    @property
    def log(self) -> str:
        event = self.latest(LOG)
        return event.detail if event else ""


@dataclass(frozen=True)
class RunSheet:
    """The study's name, whether it is blinded (and its arm factor and labels), factor columns, questionnaire items, rows
    and whether its key has been opened."""

    name: str
    blind: bool
    arm_factor: str | None
    arms: list[str]
    factors: list[str]
    questionnaire: tuple[LikertItem, ...]
    rows: list[SheetRow]
    key: StudyKey

    @property
    def checked(self) -> bool:
        """Whether any run was checked live (the sheet then has a Check column)."""
        return any(row.check is not None for row in self.rows)

    @property
    def sealed(self) -> bool:
        """Blinded and never unblinded: its pages compare no arms."""
        return self.key.sealed

    @property
    def codes(self) -> list[str]:
        return [row.code for row in self.rows]

    @property
    def next_code(self) -> str | None:
        """The first run in plan order that is not finished (running ones first)."""
        running = [row.code for row in self.rows if row.status == RUNNING]
        waiting = [row.code for row in self.rows if row.status in (PENDING, ABORTED)]
        return (running or waiting or [None])[0]

    def row(self, code: str) -> SheetRow | None:
        return next((row for row in self.rows if row.code == code), None)


def run_sheet(folder: StudyFolder) -> RunSheet:
    """The run sheet from plan.csv, design.json, study.toml, outcomes.csv, run_events.csv, scores.csv, responses.csv and
    live_checks.csv."""
    design = folder.read_design()
    plan = folder.read_plan()
    spec = read_spec(folder.path(SPEC))
    blinding = design.get("blinding") or {}
    outcomes = {o.run_code: o for o in read_outcomes(folder.path(OUTCOMES))}
    events = read_run_events(folder.path(RUN_EVENTS))
    checks = read_checks(folder)
    scores = Counter(s.run_code for s in read_scores(folder.path(SCORES)))
    judgments = Counter(r.run_code for r in read_responses(folder.path(RESPONSES)) if r.source == HUMAN)
    codes = [row["run_code"] for row in plan]
    status = statuses(codes, events, outcomes)
    factors = [name for name in plan[0] if name not in (*PLAN_COLUMNS, LOG_COLUMN)] if plan else []
    rows = []
    for row in plan:
        code = row["run_code"]
        outcome = outcomes.get(code)
        rows.append(SheetRow(int(row["order"]), code, {name: row[name] for name in factors}, status[code], outcome.status if outcome else "",
                             scores[code], judgments[code], [e for e in events if e.run_code == code], run_origin(outcome) if outcome else "", outcome,
                             checks.get(code)))
    arm_factor = blinding.get("factor") or (CONTROLLER if CONTROLLER in factors else None)
    arms = list(blinding.get("arms") or dict.fromkeys(row[arm_factor] for row in plan) if arm_factor else [registry.DEFAULT])
    return RunSheet(spec.name, bool(blinding), arm_factor, arms, factors, spec.questionnaire, rows, study_key(folder, design))
