"""A study's state at a glance (`trials status`): runs planned, finished, pending, aborted and failed per arm,
judgments and scores collected, whether the report is older than the data, the run lock, the unblinding.

It reads only public files and the names in runs/: never the sealed key, so a blinded study's status
counts by arm label and can be shown to anyone who may see the study folder.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from analysis.records import HUMAN, SIMULATED
from robot_logs.foxglove_log import partial_path
from trials.field_study import field_reason
from trials.live_checks import read_checks
from trials.outcomes import STATUSES, outcome_cells, read_outcomes
from trials.responses import read_responses
from trials.robot.live_state import read_state
from trials.robot.settings import read_robot_settings
from trials.run_events import ABORTED, RUNNING, read_run_events, statuses
from trials.run_settings import RunSettings, distinct, read_run_settings, setting_names
from trials.runner import LockState, lock_state
from trials.scores import read_scores
from trials.study import DESIGN_DIGEST, OUTCOMES, REPORT_RECORD, RESPONSES, RUN_EVENTS, SCORES, SPEC, StudyFolder
from trials.study_data import CONTROLLER_FACTOR, INPUTS_KEY, RUBRIC_KEY, read_unblinding, report_inputs

#: The group of runs of a study that compares no controllers.
ALL_RUNS = "all"


@dataclass
class ArmCounts:
    """The runs of one arm (or controller): planned, finished by how they ended, and the unfinished by why."""

    planned: int = 0
    finished: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STATUSES, 0))
    pending: int = 0
    running: int = 0
    aborted: int = 0
    failed: int = 0


@dataclass(frozen=True)
class StudyStatus:
    """What `trials status` reports."""

    root: str
    name: str
    blinded: bool
    #: Plan column the arms are read from (the blinded factor, or Controller), None when there is none.
    arm_factor: str | None
    arms: dict[str, ArmCounts]
    failed: dict[str, str]
    aborted: list[str]
    responses: dict[str, int]
    judged_runs: int
    scores: int
    scored_runs: int
    report: str
    unblinded_utc: tuple[str, ...]
    lock: LockState
    settings: RunSettings
    #: How many finished simulated runs were made with each recorded combination of settings.
    recorded_settings: dict[tuple[str, ...], int]
    #: The robot the study's runs are driven on (the [robot] table's URI), if it has one, and the last live run's state.
    robot: str | None = None
    live: dict[str, str] | None = None
    #: Why the study is a field study (`trials.field_study`), or None: its runs may be simulated.
    field: str | None = None
    #: Whether design.json carries the digest of its own content (earlier releases wrote none, so edits go unnoticed).
    design_digest: bool = True
    #: Live runs checked (`trials.live_checks`, latest check of each), and the flagged ones with no decision yet.
    checked: int = 0
    undecided: tuple[str, ...] = ()

    @property
    def finished(self) -> int:
        return sum(sum(a.finished.values()) for a in self.arms.values())

    @property
    def planned(self) -> int:
        return sum(a.planned for a in self.arms.values())

    def record(self) -> dict[str, Any]:
        """The status as JSON-ready data (`trials status --json`)."""
        data = asdict(self)
        data["settings"] = self.settings.recorded()
        data["recorded_settings"] = [{**dict(zip(setting_names(), key)), "runs": n} for key, n in self.recorded_settings.items()]
        data["finished_runs"], data["planned_runs"] = self.finished, self.planned
        return data


def study_status(folder: StudyFolder) -> StudyStatus:
    """Gather a study's status from its public files.

    Raises:
        StudyError: no plan, or a damaged plan, design.json, outcomes.csv, scores.csv or responses.csv.
    """
    design = folder.read_design()
    plan = folder.read_plan()
    blinding = design.get("blinding") or {}
    factor = blinding.get("factor") or (CONTROLLER_FACTOR if plan and CONTROLLER_FACTOR in plan[0] else None)
    outcomes = {o.run_code: o for o in read_outcomes(folder.path(OUTCOMES), bool(blinding))}
    lock = lock_state(folder)
    arms: dict[str, ArmCounts] = {}
    failed: dict[str, str] = {}
    aborted: list[str] = []
    # the field day's record (`trials serve`): a run started, or aborted with a reason, before its log was played
    day = statuses([row["run_code"] for row in plan], read_run_events(folder.path(RUN_EVENTS)), outcomes)
    for row in plan:
        code = row["run_code"]
        counts = arms.setdefault(row[factor] if factor else ALL_RUNS, ArmCounts())
        counts.planned += 1
        if code in outcomes:
            counts.finished[outcomes[code].status] += 1
        elif folder.run_failure(code).exists():
            counts.failed += 1
            failed[code] = folder.run_failure(code).read_text(encoding="utf-8").strip()
        elif day[code] == ABORTED or (partial_path(folder.run_log(code)).exists() and not lock.held):
            counts.aborted += 1
            aborted.append(code)
        elif day[code] == RUNNING or partial_path(folder.run_log(code)).exists():
            counts.running += 1
        else:
            counts.pending += 1
    responses = read_responses(folder.path(RESPONSES))
    scores = read_scores(folder.path(SCORES))
    unblinded = read_unblinding(folder, blinding["commitment"]["digest"]) if blinding else ()
    return StudyStatus(
        root=str(folder.root.resolve()), name=str(design.get("study", "")), blinded=bool(blinding), arm_factor=factor,
        arms=arms, failed=failed, aborted=aborted,
        responses={source: sum(r.source == source for r in responses) for source in (HUMAN, SIMULATED)},
        judged_runs=len({r.run_code for r in responses}), scores=len(scores), scored_runs=len({s.run_code for s in scores}),
        report=_report_state(folder), unblinded_utc=unblinded, lock=lock,
        settings=read_run_settings(folder.path(SPEC)),
        recorded_settings=distinct(outcome_cells(o) for o in outcomes.values()),
        robot=robot.uri if (robot := read_robot_settings(folder.path(SPEC))) is not None else None,
        live=read_state(folder),
        field=field_reason(folder, bool(blinding)),
        design_digest=DESIGN_DIGEST in design,
        checked=len(checks := read_checks(folder)),
        undecided=tuple(code for code, check in checks.items() if check.undecided),
    )


def _report_state(folder: StudyFolder) -> str:
    """`none`, `current`, or `older than the data`: the digest of the report's inputs recorded in report.json against
    the files now (`trials.study_data.report_inputs`); a report.json without one is older than this rule."""
    try:
        record = json.loads(folder.path(REPORT_RECORD).read_text(encoding="utf-8"))
        recorded, rubric = record.get(INPUTS_KEY), record.get(RUBRIC_KEY)
    except FileNotFoundError:
        return "none"
    except (OSError, ValueError, AttributeError, RecursionError):  # unreadable (RecursionError: nested too deeply)
        return "older than the data"
    return "current" if recorded == report_inputs(folder, Path(rubric) if isinstance(rubric, str) else None) else "older than the data"
