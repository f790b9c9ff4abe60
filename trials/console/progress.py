"""The progress page's figures, from the public files only: how complete the study is (runs finished, pending,
running, aborted and failed per arm label, as `trials status` counts them; per day and per block), judgments,
participants and scores collected, and, once the arms may be compared, Table II so far (`analysis.ab_table`) from
the runs the toolkit drove, as the report has it.

While a blinded study's key is closed, nothing compares its arms: Table II is not even computed, so no page can
give an unplanned interim look (shares by arm, differences, p-values). Its arms get counts only."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from analysis.ab_table import TableRow, count_judgments, judgments_used, table_ii
from analysis.records import HUMAN, Response
from analysis.run_log import RunLog
from robot_logs.run_log import read_run
from trials.console.sheet import RunSheet
from trials.console.times import local_day
from trials.controllers import registry
from trials.outcomes import read_outcomes
from trials.responses import read_responses
from trials.scenario import PEDESTRIANS
from trials.scores import read_scores
from trials.study import OUTCOMES, RESPONSES, SCORES, StudyFolder
from trials.study_status import ALL_RUNS, ArmCounts, study_status

#: The plan column that groups runs into blocks, when the study has one.
BLOCK = "Block"


@dataclass(frozen=True)
class ArmProgress:
    """One arm's counts (by label): runs planned, finished, pending, running, aborted and failed, and human judgments."""

    planned: int
    finished: int
    pending: int
    running: int
    aborted: int
    failed: int
    judgments: int


@dataclass(frozen=True)
class Comparison:
    """Table II so far from the judgments the report would use (`source`: human or simulated), arms by label."""

    source: str
    table: list[TableRow]


@dataclass(frozen=True)
class Progress:
    """Runs finished per local day and per block (finished of planned), counts per arm, the counts of judgments
    (human), participants and scores, the arms in order, the runs left out of comparisons (played from external
    robot logs), and the comparison of the arms (None while a blinded study's key is closed)."""

    per_day: dict[str, int]
    per_block: dict[str, tuple[int, int]]
    per_arm: dict[str, ArmProgress]
    judgments: int
    participants: int
    scores: int
    arms: list[str]
    left_out: list[str]
    comparison: Comparison | None


def progress(folder: StudyFolder, sheet: RunSheet) -> Progress:
    """The study's progress from its public files (the sealed key is never opened)."""
    outcomes = {o.run_code: o for o in read_outcomes(folder.path(OUTCOMES))}
    per_day = Counter(local_day(o.finished_utc) for o in outcomes.values())
    per_block: dict[str, tuple[int, int]] = {}
    for row in sheet.rows:
        if BLOCK in row.settings:
            done, total = per_block.get(row.settings[BLOCK], (0, 0))
            per_block[row.settings[BLOCK]] = (done + (row.code in outcomes), total + 1)
    responses = read_responses(folder.path(RESPONSES))
    human = [r for r in responses if r.source == HUMAN]
    group = {row.code: row.settings[sheet.arm_factor] if sheet.arm_factor else ALL_RUNS for row in sheet.rows}
    judged = Counter(group.get(r.run_code) for r in human)
    per_arm = {arm: _arm(counts, judged[arm]) for arm, counts in study_status(folder).arms.items()}
    left_out = [row.code for row in sheet.rows if row.external]
    compared = [r for r in responses if r.run_code in outcomes and r.run_code not in left_out]
    comparison = None if sheet.sealed else _comparison(folder, sheet, compared)
    return Progress(dict(sorted(per_day.items())), per_block, per_arm, len(human), len({r.participant for r in human}),
                    len(read_scores(folder.path(SCORES))), sheet.arms, left_out, comparison)


def _arm(counts: ArmCounts, judgments: int) -> ArmProgress:
    """An arm's completeness: its finished runs in one count, however they ended (their endings compare the arms)."""
    return ArmProgress(counts.planned, sum(counts.finished.values()), counts.pending, counts.running, counts.aborted, counts.failed, judgments)


def _comparison(folder: StudyFolder, sheet: RunSheet, responses: list[Response]) -> Comparison:
    """Table II from the judgments of finished runs the toolkit drove (an open or unblinded study only)."""
    used, source = judgments_used(responses)
    arm_of = {row.code: row.settings.get(sheet.arm_factor, registry.DEFAULT) if sheet.arm_factor else registry.DEFAULT for row in sheet.rows}
    pedestrians = {row.code: _pedestrians(row.settings, folder.run_log(row.code)) for row in sheet.rows if row.outcome}
    judged = count_judgments(used, arm_of, pedestrians)
    return Comparison(source, table_ii(judged, sheet.arms) if judged else [])


def _pedestrians(settings: dict[str, str], log: Path) -> int:
    """The plan's pedestrian count, else the number of people in the run's log (a logged trial)."""
    if PEDESTRIANS in settings:
        return int(float(settings[PEDESTRIANS]))
    return len(RunLog.of(read_run(log)).pedestrians) if log.exists() else 0
