"""The progress page's figures: runs finished per day (and per block when the plan has a Block column),
judgments and scores collected, and Table II so far with the arms by label only (`analysis.ab_table`), from
the runs the toolkit drove, as the report has it."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from analysis.ab_table import TableRow, count_judgments, judgments_used, table_ii
from analysis.run_log import RunLog
from robot_logs.run_log import read_run
from trials.console.sheet import RunSheet
from trials.controllers import registry
from trials.outcomes import read_outcomes
from trials.responses import read_responses
from trials.scenario import PEDESTRIANS
from trials.scores import read_scores
from trials.study import OUTCOMES, RESPONSES, SCORES, StudyFolder

#: The plan column that groups runs into blocks, when the study has one.
BLOCK = "Block"


@dataclass(frozen=True)
class Progress:
    """Runs finished per day and per block, the counts of judgments (human), participants and scores, the
    arms in order, Table II from the judgments the report would use (`source`: human or simulated) and the runs
    it leaves out, those played from external robot logs."""

    per_day: dict[str, int]
    per_block: dict[str, tuple[int, int]]
    judgments: int
    participants: int
    scores: int
    arms: list[str]
    source: str
    table: list[TableRow]
    left_out: list[str]


def progress(folder: StudyFolder, sheet: RunSheet) -> Progress:
    """The study's progress from its public files (the sealed key is never opened)."""
    outcomes = {o.run_code: o for o in read_outcomes(folder.path(OUTCOMES))}
    per_day = Counter(o.finished_utc[:10] for o in outcomes.values())
    per_block: dict[str, tuple[int, int]] = {}
    for row in sheet.rows:
        if BLOCK in row.settings:
            done, total = per_block.get(row.settings[BLOCK], (0, 0))
            per_block[row.settings[BLOCK]] = (done + (row.code in outcomes), total + 1)
    responses = [r for r in read_responses(folder.path(RESPONSES)) if r.run_code in outcomes]
    left_out = [row.code for row in sheet.rows if row.external]
    used, source = judgments_used(r for r in responses if r.run_code not in left_out)
    human = [r for r in responses if r.source == "human"]
    arm_of = {row.code: row.settings.get(sheet.arm_factor, registry.DEFAULT) if sheet.arm_factor else registry.DEFAULT for row in sheet.rows}
    pedestrians = {row.code: _pedestrians(row.settings, folder.run_log(row.code)) for row in sheet.rows if row.code in outcomes}
    judged = count_judgments(used, arm_of, pedestrians)
    return Progress(dict(sorted(per_day.items())), per_block, len(human), len({r.participant for r in human}),
                    len(read_scores(folder.path(SCORES))), sheet.arms, source, table_ii(judged, sheet.arms) if judged else [], left_out)


def _pedestrians(settings: dict[str, str], log: Path) -> int:
    """The plan's pedestrian count, else the number of people in the run's log (a logged trial)."""
    if PEDESTRIANS in settings:
        return int(float(settings[PEDESTRIANS]))
    return len(RunLog.of(read_run(log)).pedestrians) if log.exists() else 0
