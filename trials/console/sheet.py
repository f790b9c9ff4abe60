"""The run sheet as the console shows it: every plan row in order with its settings (a blinded factor's
arm label, never a controller), status and what has been recorded for it. Read from the public study
files only; the sealed key is never opened."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from analysis.records import EXTERNAL_LOG, HUMAN, SIMULATED_RUN
from designs.questionnaire import LikertItem
from designs.spec import LOG_COLUMN, PLAN_COLUMNS, read_spec
from trials.controllers import registry
from trials.outcomes import read_outcomes
from trials.responses import read_responses
from trials.run_events import ABORT, ABORTED, FINISH, LOG, NOTE, PENDING, RUNNING, START, RunEvent, read_run_events, statuses
from trials.scenario import CONTROLLER
from trials.scores import read_scores
from trials.study import OUTCOMES, RESPONSES, RUN_EVENTS, SCORES, SPEC, StudyFolder
from trials.study_data import run_origin


@dataclass(frozen=True)
class SheetRow:
    """One run on the sheet: order, code, settings by factor, status, its outcome's status (empty until
    its log is played or its live run ends) and how the run was made (`analysis.records`: simulated, driven
    live, external log; empty without an outcome), counts of human scores and judgments, and its events."""

    order: int
    code: str
    settings: dict[str, str]
    status: str
    outcome: str
    scores: int
    judgments: int
    events: list[RunEvent] = field(default_factory=list)
    origin: str = ""

    @property
    def made(self) -> str:
        """How the run was made, as the sheet marks it: `driven live` or `external log` (nothing for a simulated run)."""
        return "" if self.origin == SIMULATED_RUN else self.origin

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
    """The study's name, whether it is blinded (and its arm factor and labels), factor columns, questionnaire items and rows."""

    name: str
    blind: bool
    arm_factor: str | None
    arms: list[str]
    factors: list[str]
    questionnaire: tuple[LikertItem, ...]
    rows: list[SheetRow]

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
    """The run sheet from plan.csv, design.json, study.toml, outcomes.csv, run_events.csv, scores.csv and responses.csv."""
    design = folder.read_design()
    plan = folder.read_plan()
    spec = read_spec(folder.path(SPEC))
    blinding = design.get("blinding") or {}
    outcomes = {o.run_code: o for o in read_outcomes(folder.path(OUTCOMES))}
    events = read_run_events(folder.path(RUN_EVENTS))
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
                             scores[code], judgments[code], [e for e in events if e.run_code == code], run_origin(outcome) if outcome else ""))
    arm_factor = blinding.get("factor") or (CONTROLLER if CONTROLLER in factors else None)
    arms = list(blinding.get("arms") or dict.fromkeys(row[arm_factor] for row in plan) if arm_factor else [registry.DEFAULT])
    return RunSheet(spec.name, bool(blinding), arm_factor, arms, factors, spec.questionnaire, rows)
