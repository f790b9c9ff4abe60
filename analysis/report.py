"""The study report: scores, the A/B table, model fits, figures and methods, as one document.

`build_report` turns a study's data into blocks (rendered to report.md and a self-contained
report.html), a JSON record of every number shown, and the console summary. While a blinded
study is not unblinded, every arm is named by its label and no controller is named anywhere.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from analysis.ab_table import PAPER_NAMES, PAPER_TABLE_II, RunJudgments, TableRow, count_judgments, judgments_used, table_ii
from analysis.document import Block, Bullets, Figure, Heading, Paragraph, Table, csv_cell, table_names, to_csv, to_html, to_markdown
from analysis.figures import (
    arm_colours,
    correlation_map_figure,
    min_distance_figure,
    residuals_figure,
    score_distribution_figure,
    shares_figure,
    trajectories_figure,
)
from analysis.intervals import Interval, wilson
from analysis.k_arm import CORRECTION, KArmResult
from analysis.models import Fit
from analysis.participants import ParticipantModel
from analysis.plan import PlanStatus, default_plan
from analysis.primary import SENSITIVITY_NAMES, OddsRatio, PrimaryResult, arm_effect, primary_analysis
from analysis.randomization import MAX_ALLOCATIONS
from analysis.records import (
    EXTERNAL_LOG,
    LIVE_RUN,
    PLAN_BINDING,
    SIMULATED,
    SIMULATED_RUN,
    SOFTWARE_ROBOT_RUN,
    HumanScore,
    Registration,
    Response,
    StudyData,
    recorded_key,
)
from analysis.run_log import RunLog
from analysis.score_summary import SCORES, RunScore, by_factor, counts, paper_score_shares, score_runs
from analysis.scoring import Rubric
from analysis.study_fits import fit_judgments, fit_judgments_by_run, fit_metrics, fit_run_shares
from designs.factors import CategoricalFactor, FixedFactor
from robot_logs.errors import LogError
from robot_logs.run_log import read_run

FORMAT = "navtrials.report/1"
#: How each kind of fit's parameter intervals and tests are made, by the name of its statistic.
INTERVALS = {
    "z": "Wald intervals and z tests.",
    "t": "t intervals and t tests on the degrees of freedom the fit states (least squares: the residual df; GEE: its cluster df, "
         "the runs with judgments less the estimable columns).",
    "LR chi-square": "Profile-likelihood intervals and likelihood-ratio tests: an interval excludes 0 exactly when its test rejects at 0.05.",
    "penalized LR chi-square": "Profile penalized-likelihood intervals and penalized likelihood-ratio tests (Heinze and Schemper, Statistics in Medicine 2002).",
}
#: Why the full design model's clustered fit is exploratory, said once in the report.
EXPLORATORY_WHY = (
    "The experimental unit is the run: its judgments share one robot behaviour, so they are correlated, and a run with more "
    "pedestrians would otherwise weigh more. This fits the design's whole logistic model to every judgment by generalized "
    "estimating equations with each run a cluster (Liang and Zeger, Biometrika 1986), exchangeable within a run, with "
    "sandwich standard errors corrected for few clusters and t / F references on the cluster degrees of freedom. With as "
    "many columns as a small plan has, few degrees of freedom are left, so the fit is exploratory: the planned primary "
    "analysis above answers the study's question. Participants are not modelled as a second cluster."
)
PEDESTRIANS = "Pedestrians"
NOT_AVAILABLE = "n/a"
#: The one arm every run is shown in while a blinded report compares no arms.
POOLED = "all arms"


@dataclass(frozen=True)
class DataTable(Table):
    """A table whose CSV file holds `data_rows` under `data_header`: every number in its own column as a number, an
    empty cell where there is none, instead of the text the report shows (percentages, intervals, "< 0.001")."""

    data_header: list[str] = field(default_factory=list)
    data_rows: list[list[Any]] = field(default_factory=list)

    def csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow([csv_cell(name) for name in self.data_header])
        writer.writerows([["" if cell is None else csv_cell(cell) if isinstance(cell, str) else cell for cell in row] for row in self.data_rows])
        return buffer.getvalue()


def _value(value: float | None) -> float | None:
    """A number for report.json and the CSV tables: None for NaN or an infinite value."""
    return None if value is None or math.isnan(value) or math.isinf(value) else float(value)


@dataclass(frozen=True)
class Report:
    """The report's title, content blocks, JSON record and console summary."""

    title: str
    blocks: list[Block]
    record: dict[str, Any]
    summary: list[str]

    @property
    def figures(self) -> list[Figure]:
        return [block for block in self.blocks if isinstance(block, Figure)]

    def tables(self) -> dict[str, str]:
        """Every table as CSV text, by file stem."""
        return {name: table.csv() if isinstance(table, DataTable) else to_csv(table) for name, table in table_names(self.blocks)}

    def markdown(self) -> str:
        return to_markdown(self.title, self.blocks)

    def html(self) -> str:
        return to_html(self.title, self.blocks)


def percent(share: float) -> str:
    return NOT_AVAILABLE if math.isnan(share) else f"{100.0 * share:.1f} %"


def p_text(p: float) -> str:
    if math.isnan(p):
        return NOT_AVAILABLE
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def _equals(text: str) -> str:
    return text if text.startswith("<") else f"= {text}"


def number(value: float, digits: int = 3) -> str:
    return NOT_AVAILABLE if math.isnan(value) or math.isinf(value) else f"{value:.{digits}f}"


@dataclass(frozen=True)
class _Analysis:
    """What the sections share: logs, scores, arms, pedestrian counts, judgments and fits."""

    data: StudyData
    rubric: Rubric
    logs: dict[str, RunLog | None]
    scores: dict[str, RunScore]
    arms: list[str]
    pedestrians: dict[str, int]
    judgments: list[Response]
    judgment_source: str
    judged: list[RunJudgments]
    table: list[TableRow]
    judgment_fits: list[Fit]
    metric_fits: list[Fit]
    notes: list[str]
    #: Finished runs played from external robot logs: left out of every comparison of arms and factors.
    left_out: list[str]
    #: The analysis plan in force and its standing; the planned primary analysis (None without judgments).
    plan: PlanStatus
    primary: PrimaryResult | None
    #: Human scores and judgments recorded after the key was first opened: left out of everything above, counted here.
    late: Late
    #: Why this report compares no arms (a blinded study with runs to go and no interim look: every run is in POOLED), else None.
    pooled: str | None = None


@dataclass(frozen=True)
class Late:
    """People's scores and judgments recorded after the key was first opened (`opened`, None while it never was): those who
    recorded them may have known the arms, so they are counted apart from the blind data and left out of the analysis."""

    opened: str | None
    scores: tuple[HumanScore, ...] = ()
    judgments: tuple[Response, ...] = ()

    @classmethod
    def split(cls, data: StudyData) -> tuple[StudyData, Late]:
        """The data recorded blind (before the first opening), and what came after."""
        opened = data.blinding.unblinded_utc[0] if data.blinding.unblinded_utc else None
        if opened is None:
            return data, cls(None)
        before = data.blinding.recorded_before
        scores, late_scores = _partition(data.scores, opened, before)
        responses, late_judgments = _partition(data.responses, opened, before)
        return replace(data, scores=scores, responses=responses), cls(opened, tuple(late_scores), tuple(late_judgments))

    def note(self, arm_of: dict[str, str], word: str) -> str | None:
        """The report's line on them, counted by arm, or None when there are none."""
        if not (self.scores or self.judgments):
            return None
        arms = sorted({arm_of.get(x.run_code, "?") for x in (*self.scores, *self.judgments)})
        by_arm = "; ".join(f"{word} {arm}: {sum(arm_of.get(j.run_code) == arm for j in self.judgments)} judgment(s), "
                           f"{sum(arm_of.get(s.run_code) == arm for s in self.scores)} score(s)" for arm in arms)
        return (f"**{len(self.judgments)} judgment(s) and {len(self.scores)} human score(s) were recorded after the key was first "
                f"opened ({self.opened})**, by people who may have known the arms: they are left out of every table, test and "
                f"fit of this report and counted apart ({by_arm}).")

    def record(self) -> dict[str, Any]:
        return {"opened": self.opened, "judgments": len(self.judgments), "scores": len(self.scores),
                "runs": sorted({x.run_code for x in (*self.scores, *self.judgments)})}


def _partition(records: list[Any], opened: str, before: frozenset[str] | None) -> tuple[list[Any], list[Any]]:
    """People's scores or judgments recorded blind, and those recorded after the key was first opened at `opened`: those
    not in `before`, the list the first opening kept; without one (a key opened by an earlier release), those stamped in
    the minute of the opening or later (a blinded study stamps them to the minute, so one of that minute may have come
    after). Simulated judgments know no arm: never late."""
    minute = opened[:16]  # YYYY-MM-DDTHH:MM
    after = [getattr(r, "source", None) != SIMULATED and
             (recorded_key(r) not in before if before is not None else bool(r.recorded_utc) and r.recorded_utc[:16] >= minute)
             for r in records]
    return [r for r, late in zip(records, after, strict=True) if not late], [r for r, late in zip(records, after, strict=True) if late]


def build_report(data: StudyData, rubric: Rubric, rubric_source: str, generated_utc: str, participants: ParticipantModel = ParticipantModel()) -> Report:
    """The whole report of a study folder's data."""
    analysis = _analyse(data, rubric)
    title = f"Study report: {data.spec.name}"
    blocks = [
        *_overview(analysis, generated_utc),
        *_design_section(analysis),
        *_scores_section(analysis),
        *_deviations_section(analysis),
        *_primary_section(analysis),
        *_ab_section(analysis),
        *_figures_section(analysis),
        *_models_section(analysis),
        *_methods_section(analysis, rubric_source, participants),
    ]
    return Report(title, blocks, _record(analysis, generated_utc, rubric_source), _summary(analysis))


def _analyse(data: StudyData, rubric: Rubric) -> _Analysis:
    data, late = Late.split(data)
    pooled = _pooled_because(data)
    if pooled:
        data = replace(data, runs=[replace(run, arm=POOLED) for run in data.runs])
    notes = list(data.notes)
    logs: dict[str, RunLog | None] = {}
    for run in data.finished:
        if run.log is None:
            logs[run.code] = None
            continue
        try:
            logs[run.code] = RunLog.of(read_run(run.log))
        except LogError as exc:
            logs[run.code] = None
            notes.append(f"Run {run.code}: its log cannot be read ({exc}); it is scored from its outcome row only.")
    scores = score_runs(data.runs, logs, data.scores, rubric)
    finished = {run.code for run in data.finished}
    early = sorted({s.run_code for s in data.scores if s.run_code not in finished})
    if early:
        notes.append(f"Human scores of runs not finished yet are left out: {', '.join(early)}.")
    waiting = sorted({r.run_code for r in data.responses if r.run_code not in finished})
    if waiting:
        notes.append(f"Judgments of runs not finished yet are left out: {', '.join(waiting)}.")
    notes += _stale_results(data)
    compared = {run.code for run in data.compared}
    left_out = [run.code for run in data.finished if run.code not in compared]
    if left_out:
        notes.append(_left_out_note(data, left_out))
    judgments, source = judgments_used(r for r in data.responses if r.run_code in compared)
    skipped = [r for r in data.responses if r.source == SIMULATED and r.run_code in compared] if source == "human" else []
    if skipped:
        notes.append(f"Human judgments are used; {len(skipped)} simulated judgments are left out of the analysis.")
    pedestrians = {run.code: _pedestrian_count(run.values, logs.get(run.code)) for run in data.finished}
    arm_of = {run.code: run.arm for run in data.runs}
    arms = [POOLED] if pooled else _arm_order(data)
    judged = count_judgments(judgments, arm_of, pedestrians)
    table = table_ii(judged, arms) if judged else []
    plan = data.analysis_plan or PlanStatus(default_plan(data.spec, data.seed or 0), False, None)
    fitted = bool(judged) and not pooled  # every model holds the arm term: fitting it would compare the arms
    judgment_fits = ([fit_judgments_by_run(data, judged, plan.plan.gee_options()), fit_run_shares(data, judged), fit_judgments(data, judged)]
                     if fitted else [])
    metric_fits = fit_metrics(data) if data.compared and not pooled else []
    primary = primary_analysis(data, judged, plan.plan) if fitted else None
    return _Analysis(data, rubric, logs, scores, arms, pedestrians, judgments, source, judged, table, judgment_fits, metric_fits, notes,
                     left_out, plan, primary, late, pooled)


def _pooled_because(data: StudyData) -> str | None:
    """Why a report of this study must compare no arms: a blinded study, the key closed, runs still to go, and no interim
    look asked for (`--interim REASON`), so nobody sees the arms compared before the planned end. None when it may."""
    blinding = data.blinding
    if not blinding.blinded or blinding.revealed or blinding.looking or not data.unfinished:
        return None
    return (f"{len(data.finished)} of {len(data.runs)} runs have finished in this blinded study, so this report compares no arms: "
            f"every table and figure pools them ({POOLED}) and no model or test is fitted, so that nobody looks at the arms before "
            "the planned end. `trials report --interim REASON` compares them by label and records the look in unblinding.json.")


def _left_out_note(data: StudyData, codes: list[str]) -> str:
    """Why the runs played from external robot logs are left out of the comparisons, with what they hold."""
    judgments = sum(r.run_code in codes for r in data.responses)
    scores = sum(s.run_code in codes for s in data.scores)
    one = len(codes) == 1
    return (f"{len(codes)} run{'' if one else 's'} ({', '.join(codes)}) {'was' if one else 'were'} played from an external robot log: the "
            f"toolkit did not drive {'that robot' if one else 'those robots'}, so {'its' if one else 'their'} {judgments} judgment(s) and "
            f"{scores} human score(s) are not credited to a {data.blinding.arm_word.lower()}: {'it is' if one else 'they are'} left out of "
            "Table II, the scores by arm and factor, and the model fits.")


def _origins(data: StudyData) -> str | None:
    """How the finished runs were made, in one line, when any was not simulated."""
    made = [run.origin for run in data.finished]
    if all(origin == SIMULATED_RUN for origin in made):
        return None
    words = {LIVE_RUN: "driven live on the robot",
             SOFTWARE_ROBOT_RUN: "driven live on the software robot (`trials robot-sim`, a rehearsal: no real robot, no real people)",
             SIMULATED_RUN: "simulated", EXTERNAL_LOG: "played from an external robot log"}
    return "How the finished runs were made: " + ", ".join(f"{made.count(o)} {word}" for o, word in words.items() if o in made) + "."


def _stale_results(data: StudyData) -> list[str]:
    """Notes on scores and judgments recorded before their run last finished: they judge an earlier run of it."""
    notes = []
    for run in data.finished:
        finished = run.outcome.finished_utc if run.outcome else ""
        older = [r for r in [*data.scores, *data.responses] if r.run_code == run.code and r.recorded_utc and finished and r.recorded_utc < finished]
        if older:
            notes.append(f"Run {run.code} finished again ({finished}) after {len(older)} of its scores or judgments were recorded: those judge an earlier run of it.")
    return notes


def _pedestrian_count(values: dict[str, str], log: RunLog | None) -> int:
    """The plan's pedestrian count, else the number of pedestrians in the run's log."""
    if PEDESTRIANS in values:
        return int(float(values[PEDESTRIANS]))
    return len(log.pedestrians) if log is not None else 0


def _arm_order(data: StudyData) -> list[str]:
    """Arms in the order of the arm factor's levels (arm labels A, B, ... when blinded)."""
    blinding = data.blinding
    factor = next((f for f in data.spec.factors if f.name == blinding.factor), None)
    if isinstance(factor, CategoricalFactor):
        return [blinding.labels[level] for level in factor.levels if level in blinding.labels]
    return list(dict.fromkeys(run.arm for run in data.runs))


# ----------------------------------------------------------------------------------------- sections


def _overview(a: _Analysis, generated_utc: str) -> list[Block]:
    data, blinding = a.data, a.data.blinding
    items = [
        f"Study `{data.spec.name}`: {len(data.runs)} planned runs, model `{data.spec.model}`, design seed {data.seed}; report made {generated_utc}.",
        f"Finished runs: {len(data.finished)} of {len(data.runs)}."
        + (f" **Not finished yet ({len(data.unfinished)}):** {', '.join(r.code for r in data.unfinished)}; this report covers the finished runs only." if data.unfinished else ""),
    ]
    if blinding.blinded and not blinding.revealed:
        items.append(f"**Blinded, arms pooled:** {a.pooled}" if a.pooled else
                     f"**Blinded:** runs are shown by arm label ({', '.join(a.arms)}); the sealed key was not opened. `trials report --unblind` names the controllers.")
        if blinding.unblinded_utc:
            items.append(f"The key was opened before (first at {blinding.unblinded_utc[0]}).")
    elif blinding.blinded:
        mapping = ", ".join(f"{arm} = {name}" for arm, name in sorted(blinding.labels.items()))
        items.append(
            f"**Unblinded** at {blinding.unblinded_utc[-1]}. {blinding.check} Arms: {mapping}. First unblinded at {blinding.unblinded_utc[0]}."
        )
        if blinding.completeness:
            items.append(f"**Interim unblinding** with {blinding.completeness}, for this reason: {blinding.interim}" if blinding.interim
                         else f"The key was opened with {blinding.completeness}.")
    else:
        items.append("Not blinded.")
    if blinding.looking:
        items.append(f"**Interim look** at the blinded arms with {blinding.completeness}, for this reason: {blinding.interim} "
                     "(recorded in unblinding.json).")
    earlier = blinding.looks[:-1] if blinding.looking else blinding.looks
    if earlier:
        items.append(f"Interim looks at the blinded arms before this report ({len(earlier)}): "
                     + "; ".join(f"{look.utc}, {look.completeness}, for this reason: {look.reason}" for look in earlier) + ".")
    origins = _origins(data)
    if origins:
        items.append(origins)
    human = {s.run_code for s in data.scores if s.run_code in a.scores}
    items.append(f"Scores: {len(human)} of {len(a.scores)} finished runs have a human score; the rest are scored by the rubric.")
    items.append(_judgment_line(a))
    items.append(_registration_line(data.registration))
    items.append(a.plan.describe())
    primary = _primary_result(a)
    if primary:
        items.append(primary)
    late = a.late.note({run.code: run.arm for run in data.runs}, blinding.arm_word)
    if late:
        items.append(late)
    blocks: list[Block] = [Heading("Study"), Bullets(items)]
    if a.notes:
        blocks += [Paragraph("**Notes on the data:**"), Bullets(a.notes)]
    return blocks


def _registration_line(registration: Registration | None) -> str:
    """The pre-registration's digest and whether the study, and the analysis run, are what it registered."""
    if registration is None:
        return "No pre-registration: the study was designed by an earlier release (its key's commitment is what binds it)."
    line = f"Pre-registration: {registration.file}, sha256 {registration.digest}. "
    changed = [name for name in registration.differs if name != PLAN_BINDING]
    line += (f"**Changed since it was written: the {' and the '.join(changed)}** (the study is not the one registered). " if changed
             else "The design and sealed key are those it registered. ")
    line += ("**The analysis run is not the registered one**: study.toml's [analysis] table changed after the pre-registration."
             if PLAN_BINDING in registration.differs else "The analysis run is the registered one.")
    return line + {None: " `--commitment HEX` checks it against the digest recorded outside the study.",
                   True: " It matches the digest recorded outside the study (`--commitment`).",
                   False: " **It does not match the digest recorded outside the study** (`--commitment`): it, or the study it binds, "
                          "was changed after `trials design` printed the digest."}[registration.recorded]


def _deviations_section(a: _Analysis) -> list[Block]:
    """The live runs' manipulation checks and protocol deviations (`trials.live_checks`), counted per arm, and each flagged
    run with the operator's decision: a run decided `rerun` is no longer data, one that `stands` is, flag and all."""
    checks = a.data.checks
    if not checks:
        return []
    arm_of = {run.code: run.arm for run in a.data.runs}
    word = a.data.blinding.arm_word
    counted = []
    for arm in a.arms:
        mine = [c for c in checks if arm_of.get(c.run_code) == arm]
        counted.append([arm, len(mine), sum(c.condition_met is True for c in mine), sum(bool(c.flag) for c in mine),
                        sum(c.decision == "stands" for c in mine), sum(c.decision == "rerun" for c in mine), sum(c.undecided for c in mine)])
    flagged = [c for c in checks if c.flag]
    undecided = [c.run_code for c in flagged if c.undecided]
    which = {c.run_code: "" if a.pooled else f" ({word.lower()} {arm_of.get(c.run_code, '?')})" for c in flagged}
    items = [f"Run {c.run_code}{which[c.run_code]}: {c.flag}; " + (f"**{c.decision}**: {c.reason}" if c.decision else "**undecided**")
             for c in flagged]
    blocks: list[Block] = [
        Heading("Live runs: manipulation checks and deviations"),
        Paragraph("Each live run's check: how many people were tracked near the robot at once against its row's Pedestrians, "
                  "and a flag when the row's condition was not met or the run ended early (a timeout or an abort). The operator "
                  "decides each flagged run: it stands as data, or is rerun (`trials deviation`)."),
        DataTable([word, "Live runs", "Condition met", "Flagged", "Stands", "Rerun", "Undecided"], [list(map(str, row)) for row in counted],
                  f"Live runs by {word.lower()}, every attempt (a run rerun counts once for each time it was driven).", {1, 2, 3, 4, 5, 6},
                  [word.lower(), "live_runs", "condition_met", "flagged", "stands", "rerun", "undecided"], counted),
    ]
    if undecided:
        blocks.append(Paragraph(f"**{len(undecided)} flagged run(s) have no decision yet** ({', '.join(undecided)}): their results "
                                "are in the analysis as they stand."))
    if items:
        blocks.append(Bullets(items))
    return blocks


def _judgment_line(a: _Analysis) -> str:
    if not a.judgments:
        return "Judgments: none recorded (`trials respond`, or `trials respond --simulate` for simulated runs)."
    participants = len({r.participant for r in a.judgments})
    line = f"Judgments: {len(a.judgments)} from {participants} participants on {len(a.judged)} runs"
    if a.judgment_source == SIMULATED:
        seeds = sorted({str(r.seed) for r in a.judgments if r.seed is not None})
        return line + f", **simulated** by the participant model (seed {', '.join(seeds) or 'unrecorded'}), not real people."
    return line + ", from people."


def _scores_section(a: _Analysis) -> list[Block]:
    if not a.scores:
        return [Heading("Scores"), Paragraph("No finished runs to score.")]
    if not a.data.compared:
        return [Heading("Scores"), Paragraph("No finished run the toolkit drove: the runs played from an external robot log are left out of the "
                                             "score shares (see the notes)."), Heading("Every run", 3), _runs_table(a)]
    final = {code: s.final for code, s in a.scores.items() if code not in a.left_out}
    total = counts(final.values())
    n = sum(total)
    paper = paper_score_shares(a.data.spec)
    rows = []
    for score, count in zip(SCORES, total):
        interval = wilson(count, n)
        rows.append([str(score), str(count), percent(interval.share), f"{percent(interval.low)} - {percent(interval.high)}", *([f"{paper[score]:.1f} %"] if paper else [])])
    data_rows = [[score, count, *(_value(v) for v in _share_interval(count, n)), *([paper[score] / 100.0] if paper else [])]
                 for score, count in zip(SCORES, total)]
    rubric_only = counts(s.auto.score for code, s in a.scores.items() if code in final)
    blocks: list[Block] = [
        Heading("Scores"),
        Paragraph("1 = collision, 2 = no collision but unnatural (turning in place, backing up, stopping or hesitating, passing within intimate distance), 3 = natural and comfortable."),
        DataTable(
            ["Score", "Runs", "Share", "Wilson 95 %", *(["Paper (Tsai & Oh)"] if paper else [])],
            rows + [["all", str(n), "", "", *([""] if paper else [])]],
            f"Final scores (a human score overrides the rubric's). The rubric alone: {rubric_only[0]} x 1, {rubric_only[1]} x 2, {rubric_only[2]} x 3."
            + (f" Runs played from an external robot log ({len(a.left_out)}) are left out." if a.left_out else ""),
            {1, 2},
            ["score", "runs", "share", "share_low", "share_high", *(["paper_share"] if paper else [])],
            data_rows + [["all", n, None, None, None, *([None] if paper else [])]],
        ),
    ]
    arm_runs = {arm: [final[r.code] for r in a.data.compared if r.arm == arm] for arm in a.arms}
    if len(a.arms) > 1:
        word = a.data.blinding.arm_word
        blocks.append(
            DataTable(
                [word, "Runs", "Score 1", "Score 2", "Score 3", "Share scored 3"],
                [[arm, str(len(v)), *map(str, counts(v)), percent(counts(v)[2] / len(v) if v else math.nan)] for arm, v in arm_runs.items()],
                f"Scores by {word.lower()}.",
                {1, 2, 3, 4, 5},
                [word.lower(), "runs", "score_1", "score_2", "score_3", "share_scored_3"],
                [[arm, len(v), *counts(v), counts(v)[2] / len(v) if v else None] for arm, v in arm_runs.items()],
            )
        )
    level_rows = by_factor(a.data.spec, a.data.compared, final, a.data.blinding.factor)
    blocks.append(Heading("Scores against each factor", 3))
    factor_name = {a.data.blinding.factor: a.data.blinding.arm_word}
    blocks.append(
        DataTable(
            ["Factor", "Level", "Runs", "Score 1", "Score 2", "Score 3", "Mean score"],
            [[factor_name.get(row.factor, row.factor), row.level, str(sum(row.counts)), *map(str, row.counts), number(row.mean, 2)] for row in level_rows],
            align_right={2, 3, 4, 5, 6},
            data_header=["factor", "level", "runs", "score_1", "score_2", "score_3", "mean_score"],
            data_rows=[[factor_name.get(row.factor, row.factor), row.level, sum(row.counts), *row.counts, _value(row.mean)] for row in level_rows],
        )
    )
    blocks += [Heading("Every run", 3), _runs_table(a)]
    return blocks


def _runs_table(a: _Analysis) -> Table:
    data = a.data
    shown = [f.name for f in data.spec.factors if not isinstance(f, FixedFactor) and f.name != data.blinding.factor]
    header = ["Order", "Run", *shown, data.blinding.arm_word, "Status", "Min gap (m)", "Rubric", "Human scores", "Score"]
    rows = []
    data_rows: list[list[Any]] = []
    for run in data.runs:
        cells = [str(run.order), run.code, *(run.values[name] for name in shown), run.arm]
        scored = a.scores.get(run.code)
        if run.outcome is None or scored is None:
            rows.append(cells + ["not run yet", "", "", "", ""])
            data_rows.append([run.order, *cells[1:], "not run yet", None, None, "", None])
            continue
        rubric = f"{scored.auto.score}" + (f" ({'; '.join(scored.auto.reasons)})" if scored.auto.reasons else "")
        human = "; ".join(f"{s.score} by {s.scorer or 'unnamed'}" + (f" ({s.note})" if s.note else "") for s in scored.human)
        gap = run.outcome.min_distance_m
        status = run.outcome.status if run.origin == SIMULATED_RUN else f"{run.outcome.status} ({run.origin})"
        rows.append(cells + [status, NOT_AVAILABLE if gap is None else f"{gap:.2f}", rubric, human, f"**{scored.final}**"])
        data_rows.append([run.order, *cells[1:], status, gap, scored.auto.score, human, scored.final])
    return DataTable(header, rows, "In run order. Score: the latest human score, else the rubric's. A run played from an external robot log "
                     "is listed here and left out of every comparison.", {0, len(shown) + 4},
                     ["order", "run", *shown, data.blinding.arm_word.lower(), "status", "min_gap_m", "rubric_score", "human_scores", "score"], data_rows)


def _ab_section(a: _Analysis) -> list[Block]:
    blinding = a.data.blinding
    if len(a.arms) < 2 and not a.judged and not a.pooled:
        return []
    heading = "A/B comparison (Table II)" if len(a.arms) > 1 else "Judgments (share judged socially compliant)"
    blocks: list[Block] = [Heading(heading)]
    if not a.table and a.left_out:
        return blocks + [Paragraph("No judgments of runs the toolkit drove yet; those of runs played from an external robot log are left out (see the notes).")]
    if not a.table:
        return blocks + [Paragraph("No judgments of finished runs yet: record them with `trials respond` (or `trials respond --simulate` for simulated runs).")]
    paper = blinding.open and all(arm in PAPER_TABLE_II for arm in a.arms)
    header = ["Runs with"]
    for arm in a.arms:
        header += [f"{arm}: runs", f"{arm}: yes / judged", f"{arm}: % (Wilson 95 %)"]
        if paper:
            header.append(f"{PAPER_NAMES[arm]} (paper)")
    two = len(a.arms) == 2
    if two:
        header += ["Difference (95 % CI)", "Odds ratio (95 % CI)", "Fisher's exact p", "Holm p"]
    rows = []
    data_header = ["min_pedestrians"]
    for arm in a.arms:
        data_header += [f"{arm}_runs", f"{arm}_yes", f"{arm}_judged", f"{arm}_share", f"{arm}_share_low", f"{arm}_share_high"]
        data_header += [f"{arm}_paper_share"] if paper else []
    if two:
        data_header += ["difference", "difference_low", "difference_high", "odds_ratio", "odds_ratio_low", "odds_ratio_high", "fisher_p", "holm_p"]
    data_rows: list[list[Any]] = []
    for row in a.table:
        cells = [f">= {row.min_pedestrians} pedestrians"]
        numbers: list[Any] = [row.min_pedestrians]
        for arm in a.arms:
            share = row.shares[arm]
            cells += [str(row.runs[arm]), f"{share.k} / {share.n}", f"{percent(share.share)} ({percent(share.low)} - {percent(share.high)})"]
            numbers += [row.runs[arm], share.k, share.n, _value(share.share), _value(share.low), _value(share.high)]
            if paper:
                cells.append(f"{PAPER_TABLE_II[arm].get(row.min_pedestrians, math.nan):.0f} %")
                numbers.append(_value(PAPER_TABLE_II[arm].get(row.min_pedestrians, math.nan) / 100.0))
        if two:
            d, r = row.difference, row.odds_ratio
            cells += [
                f"{_points(d.estimate)} ({_points(d.low)} to {_points(d.high)})",
                f"{number(r.estimate, 2)} ({number(r.low, 2)} - {number(r.high, 2)})",
                p_text(row.p_value),
                p_text(row.holm_p),
            ]
            numbers += [_value(v) for v in (d.estimate, d.low, d.high, r.estimate, r.low, r.high, row.p_value, row.holm_p)]
        rows.append(cells)
        data_rows.append(numbers)
    source = "simulated participants" if a.judgment_source == SIMULATED else "participants"
    caption = f"Share of judgments \"socially compliant\" by {source}, among runs with at least k pedestrians, with Wilson 95 % intervals"
    if two:
        first, second = a.arms
        caption += (
            f". Difference: {first} minus {second} in percentage points, Newcombe's score interval; odds ratio of {first} to {second} "
            "with 0.5 added to every cell (Woolf's interval); two-sided Fisher's exact test, and its p-value Holm-adjusted across the rows, "
            "which are nested"
        )
    caption += (
        ". Every judgment counts as independent here, so the intervals are narrower than the runs support: the table is descriptive; "
        "the planned run-level analysis above is the primary one."
    )
    blocks.append(DataTable(header, rows, caption, set(range(1, len(header))), data_header, data_rows))
    if blinding.blinded and not blinding.revealed:
        blocks.append(Paragraph("The paper's values are per controller; they appear beside these once the study is unblinded (`trials report --unblind`)."))
    elif not paper and len(a.arms) > 1:
        blocks.append(Paragraph("The paper's Table II compares its two planners; these arms are not those, so its values are not shown."))
    return blocks


def _primary_result(a: _Analysis) -> str | None:
    """The planned primary result in one sentence, when the plan compares two arms: never missing when an arm is all yes."""
    r = a.primary
    if r is not None and r.k_arms is not None:
        return _k_arm_result(r, r.k_arms)
    if r is None or len(r.arms) != 2:
        return None
    first, second = r.arms
    if r.randomization is None and math.isnan(r.p_value):
        return (f"**Primary result** ({r.plan.describe_test()}): no test from these judgments ({'; '.join(r.notes) or 'see the notes'}).")
    shares = f"mean run share of yes {percent(r.mean_shares[first])} for {first} against {percent(r.mean_shares[second])} for {second}"
    if r.randomization is not None:
        t = r.randomization
        interval = t.no_interval or f"{100 * (1 - r.plan.alpha):g} % CI for the average difference {_points(t.low)} to {_points(t.high)}"
        effect = f"{_difference_name(r)} {_points(t.difference)} points ({interval}), p {_equals(p_text(t.p_value))} ({t.describe()})"
    else:
        effect = f"p {_equals(p_text(r.p_value))}"
    ratio = (f"; odds ratio {first} to {second} {_ratio(r.odds_ratio.estimate)} (95 % CI {_ratio(r.odds_ratio.low)} - "
             f"{_ratio(r.odds_ratio.high)}, {r.odds_ratio.source})" if r.odds_ratio is not None else "")
    return (f"**Primary result** ({r.plan.describe_test()}; {r.runs} runs, {r.judgments} judgments): {shares}; {effect}{ratio}.")


def _k_arm_result(r: PrimaryResult, k: KArmResult) -> str:
    """The planned result of more than two arms in one sentence: the global test, then the pairs that differ."""
    g = k.global_test
    shares = ", ".join(f"{percent(r.mean_shares[arm])} for {arm}" for arm in r.arms)
    differ = [f"{p.first} - {p.second} {_points(p.test.difference)} points (Holm p {p_text(p.holm_p)})" for p in k.pairs if p.holm_p < r.plan.alpha]
    pairs = ("pairs that differ at alpha " + f"{r.plan.alpha:g}: " + "; ".join(differ)) if differ else f"no pair differs at alpha {r.plan.alpha:g} after {CORRECTION}'s correction"
    return (f"**Primary result** ({r.plan.describe_test()}; {len(r.arms)} arms: the global test, then every pair with {CORRECTION}'s "
            f"correction; {r.runs} runs, {r.judgments} judgments): mean run share of yes {shares}; global p {_equals(p_text(g.p_value))} ({g.describe()}); {pairs}.")


def _pairwise_table(r: PrimaryResult, k: KArmResult) -> DataTable:
    """Every pair of arms: the difference of mean run shares, its interval at the pairwise level, p and Holm's p."""
    level = f"{100 * k.interval_level:.4g} %"
    rows, data_rows = [], []
    for pair in k.pairs:
        t = pair.test
        interval = t.no_interval or f"{_points(t.low)} to {_points(t.high)}"
        rows.append([f"{pair.first} - {pair.second}", f"{t.runs}", _points(t.difference), interval, p_text(t.p_value), p_text(pair.holm_p),
                     t.describe()])
        data_rows.append([pair.first, pair.second, t.runs, _value(t.difference), _value(t.low), _value(t.high), _value(t.p_value),
                          _value(pair.holm_p), t.describe()])
    g = k.global_test
    return DataTable(
        ["Pair", "Runs", "Difference (points)", f"{level} CI", "p", f"{CORRECTION} p", "Randomization"], rows,
        f"The planned pairwise comparisons after the global test (p {p_text(g.p_value)}): each pair's runs re-randomized between its two "
        f"arms{' within the strata' if r.plan.strata else ''}; the difference of mean run shares of yes, first minus second, with the "
        f"interval inverting the studentized test at {level} (1 - alpha / {len(k.pairs)}, so the {len(k.pairs)} intervals hold together "
        f"at {100 * (1 - r.plan.alpha):g} %); p-values adjusted by {CORRECTION}'s method over the {len(k.pairs)} pairs.",
        {1, 2, 3, 4, 5}, ["first", "second", "runs", "difference", "low", "high", "p", "holm_p", "randomization"], data_rows)


def _ratio(value: float) -> str:
    return "inf" if math.isinf(value) else number(value, 2)


def _share_interval(k: int, n: int) -> tuple[float, float, float]:
    interval = wilson(k, n)
    return interval.share, interval.low, interval.high


def _primary_section(a: _Analysis) -> list[Block]:
    """The analysis plan, the planned primary test with its effect estimates, and the sensitivity analyses below it."""
    r, plan = a.primary, a.plan.plan
    blocks: list[Block] = [Heading("Primary analysis (the analysis plan)"), Paragraph(a.plan.describe())]
    strata = f", re-randomized within {', '.join(plan.strata)}" if plan.strata else ""
    items = [
        f"Outcome: each judgment's answer to \"socially compliant?\" ({plan.outcome}); the run is the unit.",
        f"Primary test: {plan.describe_test()}{strata}." + (f" Factor compared: {plan.factor}." if plan.factor else ""),
        f"Primary model: `{plan.model}`; sensitivity analyses on it: {', '.join(SENSITIVITY_NAMES[n] for n in plan.sensitivity) or 'none'}.",
        f"Exploratory: the design's full model `{plan.exploratory}` (below, under the model fits)." if plan.exploratory else "No exploratory model.",
    ]
    if plan.test == "randomization":
        items.append(f"Randomization test: exact when at most {MAX_ALLOCATIONS:,} allocations, else {plan.draws:,} Monte Carlo draws from seed {plan.seed}.")
        if len(a.arms) > 2:
            items.append(f"{len(a.arms)} arms: first the global test of the between-arm sum of squares of run shares, then every pair of "
                         f"arms by the two-arm test on its own runs, p-values adjusted by {CORRECTION}'s method.")
    blocks.append(Bullets(items))
    if a.pooled:
        return blocks + [Paragraph("Not tested yet: the arms are pooled until every run has finished (see the study's overview).")]
    if r is None:
        return blocks + [Paragraph("No judgments yet: nothing to test.")]
    line = _primary_result(a)
    if line:
        blocks.append(Paragraph(line))
    if len(r.arms) == 2:
        blocks.append(_primary_table(r))
    if r.k_arms is not None:
        blocks.append(_pairwise_table(r, r.k_arms))
    t = r.randomization
    if t is not None and not t.agrees:
        blocks.append(Paragraph(
            f"**The interval and the p-value fall on different sides of alpha here.** The p-value ({p_text(t.p_value)}) is the planned "
            "test that the arm changes no run's share; the interval is for the average difference and comes from the studentized "
            f"test, whose p at a difference of 0 is {p_text(t.p_studentized)}. Near alpha the two can disagree; the planned test decides."))
    rows, data_rows = [], []
    for name, fit in r.sensitivity:
        effect = next((e for e in fit.effects if e.term == plan.factor), None)
        ratio = _arm_ratio(fit, plan.factor)
        # The column's own test, made as its interval is (Wald beside Wald, likelihood ratio beside profile likelihood).
        p = ratio.p_value if ratio else effect.p_value if effect else math.nan
        rows.append([SENSITIVITY_NAMES[name], _ratio(ratio.estimate) if ratio else NOT_AVAILABLE,
                     f"{_ratio(ratio.low)} - {_ratio(ratio.high)}" if ratio else NOT_AVAILABLE,
                     NOT_AVAILABLE if math.isnan(p) else p_text(p), fit.method + "".join(f" {note}" for note in fit.notes)])
        data_rows.append([name, *((_value(ratio.estimate), _value(ratio.low), _value(ratio.high)) if ratio else (None, None, None)),
                          _value(p), fit.method])
    if rows:
        first = f" of {r.arms[0]} to {r.arms[1]}" if len(r.arms) == 2 else ""
        blocks += [Heading("Sensitivity analyses", 3), DataTable(
            ["Analysis", f"Odds ratio{first}", "95 % CI", f"p ({plan.factor or 'term'})", "Method and notes"], rows,
            f"The primary model `{plan.model}` fitted to every judgment in other ways: the same question under other assumptions. Each "
            "row's p is the arm column's own test, made as its interval is (Wald z with a Wald interval, a likelihood ratio with a "
            "profile-likelihood one), so the interval excludes 1 exactly when p < 0.05. "
            "An analysis that cannot be fitted on these judgments (separation, too few runs) says why; the primary test above stands.",
            {1, 2, 3}, ["analysis", "odds_ratio", "odds_ratio_low", "odds_ratio_high", "p", "method"], data_rows)]
    return blocks


def _arm_ratio(fit: Fit, factor: str) -> OddsRatio | None:
    return arm_effect(fit, factor) if factor else None


def _primary_table(r: PrimaryResult) -> DataTable:
    first, second = r.arms
    rows: list[list[str]] = []
    data_rows: list[list[Any]] = []
    for arm in r.arms:
        rows.append([f"{arm}: mean run share of yes", percent(r.mean_shares[arm]), "", "", "", f"{r.arm_runs[arm]} runs"])
        data_rows.append([f"{arm}: mean run share", _value(r.mean_shares[arm]), None, None, None, f"{r.arm_runs[arm]} runs"])
    t = r.randomization
    if t is not None:
        level = f"{100 * (1 - r.plan.alpha):g} %"
        how = t.no_interval or (f"{level} interval for the average difference over the runs, by inverting the studentized test "
                                f"(its p at 0: {p_text(t.p_studentized)})")
        what = _difference_name(r)
        rows.append([f"{what.capitalize()} {first} - {second} (points)", _points(t.difference), _points(t.low), _points(t.high),
                     p_text(t.p_value), f"randomization test, {t.describe()}; {how}"])
        data_rows.append([f"{what} {first} - {second}", _value(t.difference), _value(t.low), _value(t.high), _value(t.p_value),
                          t.describe()])
    elif not math.isnan(r.p_value):
        rows.append([f"Test of {r.plan.factor}", "", "", "", p_text(r.p_value), r.plan.describe_test()])
        data_rows.append([f"test of {r.plan.factor}", None, None, None, _value(r.p_value), r.plan.describe_test()])
    if r.odds_ratio is not None:
        o = r.odds_ratio
        rows.append([f"Odds ratio {first} to {second}", _ratio(o.estimate), _ratio(o.low), _ratio(o.high), p_text(o.p_value), o.source])
        data_rows.append([f"odds ratio {first} to {second}", _value(o.estimate), _value(o.low), _value(o.high), _value(o.p_value), o.source])
    weighted = (f" The {_difference_name(r)} is the difference of the arms' mean shares within each stratum of "
                f"{', '.join(r.plan.strata)}, averaged with weights n1 n2 / n (n1, n2 the stratum's runs in each arm, n their sum), "
                "as the test compares them; it is not the difference of the two means above." if r.plan.strata else "")
    return DataTable(["Quantity", "Estimate", "Lower", "Upper", "p", "How"], rows,
                     "The planned primary result. Shares are each run's share of yes, averaged over the arm's runs (every run weighs the "
                     f"same); the odds ratio is from the first sensitivity fit that estimates it.{weighted}", {1, 2, 3, 4},
                     ["quantity", "estimate", "lower", "upper", "p", "how"], data_rows)


def _difference_name(r: PrimaryResult) -> str:
    """What the primary difference is: the plain difference of mean run shares, or its stratum-weighted form."""
    return "stratum-weighted difference" if r.plan.strata else "difference"


def _interval_text(low: float, high: float) -> str:
    if math.isnan(low) or math.isnan(high):
        return NOT_AVAILABLE
    return f"{number(low) if math.isfinite(low) else '-inf'} to {number(high) if math.isfinite(high) else 'inf'}"


def _points(share_difference: float) -> str:
    """A difference of two shares in percentage points, signed."""
    return NOT_AVAILABLE if math.isnan(share_difference) else f"{100.0 * share_difference:+.1f}"


def _models_section(a: _Analysis) -> list[Block]:
    blocks: list[Block] = [Heading("The design's model fitted to the results")]
    terms = ", ".join(a.data.model.term_names[1:]) or "intercept only"
    blocks.append(Paragraph(f"Model terms (from the plan): {terms}. Factors are coded as in the design: numeric ones on [-1, 1], categorical ones effect-coded (the last level is minus the sum of the others)."))
    if a.pooled:
        return blocks + [Paragraph("Not fitted yet: every model holds the arm, so it waits until every run has finished (see the study's overview).")]
    if a.judgment_fits:
        primary, shares, naive = a.judgment_fits
        blocks += [
            Heading("Judgments: the design's full model by run-level GEE (exploratory)", 3),
            Paragraph(EXPLORATORY_WHY),
            *_fit_blocks(primary),
            Heading("Judgments: each run's share of yes (least squares)", 3),
            Paragraph("Every run counts once, whatever its number of judgments; a check on the GEE fit that needs no model of the correlation."),
            *_fit_blocks(shares),
            Heading("Judgments: logistic regression on every judgment (descriptive)", 3),
            Paragraph("Treats the judgments as independent, as the paper's percentages do: its standard errors are too small when judgments of one run agree."),
            *_fit_blocks(naive),
        ]
    else:
        blocks.append(Paragraph("No judgments to fit yet."))
    if a.metric_fits:
        blocks.append(Heading("Outcome metrics: least squares", 3))
        terms_rows = []
        terms_data: list[list[Any]] = []
        for index, effect in enumerate(a.metric_fits[0].effects):
            terms_rows.append([effect.term, str(effect.df), *(p_text(fit.effects[index].p_value) for fit in a.metric_fits)])
            terms_data.append([effect.term, effect.df, *(_value(fit.effects[index].p_value) for fit in a.metric_fits)])
        blocks.append(
            DataTable(["Term", "df", *(f"p: {fit.response}" for fit in a.metric_fits)], terms_rows, "Partial F tests of each term (effect tests), per metric.",
                      set(range(1, 2 + len(a.metric_fits))), ["term", "df", *(f"p: {fit.response}" for fit in a.metric_fits)], terms_data)
        )
        for fit in a.metric_fits:
            blocks += [Heading(f"{fit.response}", 4), *_fit_blocks(fit, effects=False)]
        panels = [(fit.response, fit.fitted, fit.residuals, fit.flagged) for fit in a.metric_fits if fit.fitted]
        if panels:
            blocks.append(
                Figure("residuals", residuals_figure(panels), "Residual against fitted value of each outcome metric's least-squares fit, one point per run; "
                       "a pattern or a funnel says the model or its constant variance does not hold. Open triangles: durations censored by the time limit.",
                       "residuals of the outcome metrics' fits")
            )
    return blocks


def _fit_blocks(fit: Fit, effects: bool = True) -> list[Block]:
    figures = "".join(f"; {name} {number(value)}" for name, value in fit.summary.items())
    blocks: list[Block] = [Paragraph(f"{fit.method}: {fit.runs} runs, {fit.observations} observations{figures}.")]
    if effects:
        blocks.append(
            DataTable(
                ["Term", "df", fit.test, "p"],
                [[e.term, str(e.df), number(e.statistic), p_text(e.p_value)] for e in fit.effects],
                "Effect tests: dropping all of a term's columns.",
                {1, 2, 3},
                ["term", "df", "statistic", "p"],
                [[e.term, e.df, _value(e.statistic), _value(e.p_value)] for e in fit.effects],
            )
        )
    blocks.append(
        DataTable(
            ["Column", "Estimate", "Std error", "95 % CI", fit.statistic, "p"],
            [[p.column, number(p.estimate), number(p.std_error), _interval_text(p.low, p.high), number(p.statistic, 2), p_text(p.p_value)] for p in fit.parameters],
            "Parameter estimates (n/a: not estimable from these runs, or no interval). " + INTERVALS.get(fit.statistic, ""),
            {1, 2, 3, 4, 5},
            ["column", "estimate", "std_error", "low", "high", "statistic", "p"],
            [[p.column, *(_value(v) for v in (p.estimate, p.std_error, p.low, p.high, p.statistic, p.p_value))] for p in fit.parameters],
        )
    )
    if fit.notes:
        blocks.append(Bullets([f"**Note:** {note}" for note in fit.notes]))
    return blocks


def _figures_section(a: _Analysis) -> list[Block]:
    data = a.data
    word = data.blinding.arm_word.lower()
    colours = arm_colours(a.arms)
    blocks: list[Block] = [Heading("Figures")]
    if data.compared:
        groups = {arm: counts(a.scores[r.code].final for r in data.compared if r.arm == arm) for arm in a.arms}
        groups = {arm: c for arm, c in groups.items() if sum(c)} if len(a.arms) > 1 else {"all runs": counts(a.scores[r.code].final for r in data.compared)}
        paper_shares = paper_score_shares(data.spec)
        caption = f"Share of runs scored 1, 2 and 3 by {word} (bars with Wilson 95 % intervals, counts under them)" + (" and the paper's shares for this plan (diamonds)." if paper_shares else ".")
        blocks.append(Figure("scores", score_distribution_figure(groups, paper_shares, "Score distribution"), caption, "score distribution"))
    panels = []
    for run in data.finished:
        log = a.logs.get(run.code)
        if log is None:
            continue
        arm = run.arm if run.origin != EXTERNAL_LOG else f"{run.arm}, {EXTERNAL_LOG}"
        title = f"{run.order}. {run.code} | {arm}\n{a.pedestrians[run.code]} ped | score {a.scores[run.code].final}"
        panels.append((title, run.arm, log.robot[:, 1:3], [track[:, 1:3] for track in log.pedestrians.values()]))
    if panels:
        blocks.append(Figure("trajectories", trajectories_figure(panels, colours, word), "Every finished run in run order, seen from above (metres): the robot's path (colour by " + word + ") and the pedestrians' paths (grey), "
                                 "a marker where each ends; panel titles give the run's order, code, " + word + ", pedestrians and score.", "every run's paths"))
    if a.table:
        rows = [(row.min_pedestrians, {arm: (row.shares[arm].share, row.shares[arm].low, row.shares[arm].high) for arm in a.arms}) for row in a.table]
        paper = PAPER_TABLE_II if data.blinding.open and all(arm in PAPER_TABLE_II for arm in a.arms) else None
        blocks.append(Figure("ab_shares" if len(a.arms) > 1 else "judged_shares", shares_figure(rows, paper, "Judged socially compliant"), "Share of judgments \"socially compliant\" by " + word + " among runs with at least k pedestrians, with Wilson 95 % intervals"
                                 + ("; hollow diamonds: the paper's Table II." if paper else "."), "judged socially compliant"))
    points = [
        (run.arm, float(a.pedestrians[run.code]), run.outcome.min_distance_m)
        for run in data.compared
        if run.outcome is not None and run.outcome.min_distance_m is not None
    ]
    if points:
        blocks.append(Figure("min_distance", min_distance_figure(points, a.arms, f"Minimum gap by {word} and pedestrian count", a.rubric.intimate_distance_m), f"Each run's minimum gap between the robot's footprint and a pedestrian's body against its pedestrian count, one colour per {word}; "
                                 f"lines join the means per {word}; the dotted line is the intimate distance.", "minimum gap"))
    return blocks


def _design_section(a: _Analysis) -> list[Block]:
    """The plan's quality as `trials design` measured it: efficiencies, power and the correlation map."""
    data, d = a.data, a.data.diagnostics
    if not d:
        return []
    blocks: list[Block] = [Heading("The design")]
    efficiencies = [
        ("D-efficiency", d.get("d_efficiency")),
        ("D-efficiency bound (approximate design)", d.get("d_efficiency_bound")),
        ("D-efficiency as % of the bound", d.get("d_efficiency_vs_bound")),
        ("A-efficiency", d.get("a_efficiency")),
        ("G-efficiency", d.get("g_efficiency")),
        ("Average prediction variance", d.get("average_prediction_variance")),
    ]
    blocks.append(
        DataTable(
            ["Measure", "Value"],
            [[name, number(float(value), 3)] for name, value in efficiencies if value is not None],
            f"{d.get('n', len(data.runs))} runs, {d.get('p', data.model.p)} model columns; JMP's conventions (coded factors, sigma = 1).",
            {1},
            ["measure", "value"],
            [[name, _value(float(value))] for name, value in efficiencies if value is not None],
        )
    )
    power = d.get("power")
    if power:
        convention = power.get("convention", "every anticipated coefficient +1 (a design.json made before JMP's convention was adopted)")
        blocks.append(
            DataTable(
                ["Term", "df", "Power"],
                [[t["term"], str(t["parameters"]), number(float(t["power"]), 3)] for t in power.get("terms", [])],
                f"Power of each term's F test at alpha {power.get('alpha')} with signal-to-noise {power.get('snr')} and error df "
                f"{power.get('error_df')}; anticipated coefficients by {convention}. This is JMP's power for a Gaussian response: the "
                "power of the least-squares fits of the outcome metrics, not of the judgments' planned test (`trials power`).",
                {1, 2},
                ["term", "df", "power"],
                [[t["term"], t["parameters"], _value(float(t["power"]))] for t in power.get("terms", [])],
            )
        )
    columns, matrix = data.correlations
    if columns:
        labels = _open_labels(columns, data)
        values = np.array([[math.nan if v is None else v for v in row] for row in matrix], dtype=float)
        blocks.append(Figure("correlation_map", correlation_map_figure(labels, values, f"{data.spec.name}: correlations of model columns"), "The design's correlation map: the signed correlation r between each pair of model columns over the plan, "
                                 "from blue (-1) through white (0) to red (+1); the off-diagonal cells show how far the effects can be told apart.",
                                 "correlation map"))
    return blocks


def _open_labels(columns: list[str], data: StudyData) -> list[str]:
    blinding = data.blinding
    if not (blinding.blinded and blinding.revealed) or blinding.factor is None:
        return columns
    names = {f"{blinding.factor}[{arm}]": f"{blinding.factor}[{name}]" for arm, name in blinding.labels.items()}
    return ["*".join(names.get(part, part) for part in column.split("*")) for column in columns]


def _methods_section(a: _Analysis, rubric_source: str, participants: ParticipantModel) -> list[Block]:
    blocks: list[Block] = [
        Heading("Methods"),
        Heading("Rubric (automatic score)", 3),
        Paragraph(f"Thresholds: {rubric_source}. Score 1: the run ended in a collision (status `collision`, a collision event, or a minimum gap of 0 m). Score 2 (no collision, but unnatural) when any of these holds:"),
        Bullets(a.rubric.unnatural_rules()),
        Paragraph("Score 3: natural and comfortable (none of the above)."),
    ]
    if a.judgment_source == SIMULATED:
        blocks += [Heading("Simulated participants", 3), Bullets(participants.describe())]
    blocks += [
        Heading("Statistics", 3),
        Bullets(_statistics(a)),
    ]
    return blocks


def _statistics(a: _Analysis) -> list[str]:
    """The methods behind the numbers this report shows, and only those."""
    items = ["Shares: Wilson score intervals at 95 %."]
    if a.judged:
        items.append(
            "Primary analysis of the judgments: the analysis plan's test (study.toml [analysis]). The randomization test compares the "
            "arms' mean run shares of yes, re-drawing the arm labels as the design allocated them (the same number of runs per arm, "
            "within strata when the plan names them) over every allocation, or a seeded Monte Carlo sample of them with its standard "
            "error. The interval is for the average difference over the runs: it inverts the studentized randomization test (the "
            "difference over its Neyman standard error; Wu and Ding, JASA 2021), which needs no model of how the arm moves each share."
        )
        items.append(
            "Exploratory: the design's full logistic model by GEE with each run a cluster (statsmodels; exchangeable working "
            "correlation; small-sample sandwich errors; t tests and intervals, F tests per term on the cluster degrees of freedom). "
            "Beside it, least squares on each run's share of yes."
        )
        if len(a.arms) == 2:
            items.append(
                "Two arms, per row of Table II: the difference with Newcombe's score interval, the odds ratio with 0.5 added to every cell "
                "and Woolf's interval, two-sided Fisher's exact test on the 2 x 2 table of yes / no judgments, Holm-adjusted across the rows."
            )
        items.append(
            "Judgments, descriptive: binomial logistic regression of each run's yes / judged counts on the plan's model terms, by maximum "
            "likelihood (Newton-Raphson); likelihood-ratio chi-square tests per column and per term, and profile-likelihood intervals "
            "(the random-intercept model: Wald z tests and intervals per column). When the judgments are perfectly separated, Firth's penalized likelihood replaces "
            "maximum likelihood, with profile penalized-likelihood intervals and penalized likelihood-ratio tests for columns and terms alike."
        )
    items += [
        "Outcome metrics: least squares on the same terms; t tests and intervals per column, partial F tests per term, R^2 and RMSE.",
        "A column that is a linear combination of earlier columns over the runs with data is aliased: it is left out and the report says so.",
    ]
    return items


# ----------------------------------------------------------------------------------------- record and summary


def _record(a: _Analysis, generated_utc: str, rubric_source: str) -> dict[str, Any]:
    data, blinding = a.data, a.data.blinding
    total = counts(s.final for code, s in a.scores.items() if code not in a.left_out)
    return {
        "format": FORMAT,
        "generated_utc": generated_utc,
        "study": data.spec.name,
        "seed": data.seed,
        "blinding": {
            "blinded": blinding.blinded,
            "controllers_named": blinding.open,
            "unblinded_utc": list(blinding.unblinded_utc) if blinding.revealed else [],
            "arms": dict(blinding.labels) if blinding.revealed else None,
            "key_check": blinding.check if blinding.revealed else None,
            "completeness": blinding.completeness if blinding.revealed else None,
            "interim": blinding.interim if blinding.revealed else None,
            "compares_arms": a.pooled is None,
            "interim_look": {"completeness": blinding.completeness, "reason": blinding.interim} if blinding.looking else None,
            "interim_looks": [asdict(look) for look in blinding.looks],
        },
        "runs": {"planned": len(data.runs), "finished": len(data.finished), "not_finished": [r.code for r in data.unfinished],
                 "made": {origin: sum(r.origin == origin for r in data.finished)
                          for origin in (SIMULATED_RUN, LIVE_RUN, SOFTWARE_ROBOT_RUN, EXTERNAL_LOG)},
                 "left_out_of_comparisons": a.left_out},
        "rubric": {"source": rubric_source, "thresholds": asdict(a.rubric)},
        "scores": {
            code: {"arm": next(r.arm for r in data.runs if r.code == code), "made": next(r.origin for r in data.runs if r.code == code),
                   "rubric": s.auto.score, "reasons": list(s.auto.reasons), "human": [h.score for h in s.human], "final": s.final}
            for code, s in a.scores.items()
        },
        "score_counts": dict(zip(map(str, SCORES), counts(s.final for code, s in a.scores.items() if code not in a.left_out))),
        "judgments": {"source": a.judgment_source, "count": len(a.judgments)},
        "recorded_after_opening": a.late.record(),
        "table_ii": [
            {
                "min_pedestrians": row.min_pedestrians,
                "arms": {
                    arm: {"runs": row.runs[arm], "yes": p.k, "judged": p.n, "share": _json_number(p.share), "low": _json_number(p.low), "high": _json_number(p.high)}
                    for arm, p in row.shares.items()
                },
                "difference": _interval_record(row.difference),
                "odds_ratio": _interval_record(row.odds_ratio),
                "fisher_p": _json_number(row.p_value),
                "holm_p": _json_number(row.holm_p),
            }
            for row in a.table
        ],
        "scores_by_arm": {arm: dict(zip(map(str, SCORES), counts(a.scores[r.code].final for r in data.compared if r.arm == arm)))
                          for arm in a.arms} if len(a.arms) > 1 else {},
        "scores_by_factor": [{"factor": row.factor, "level": row.level, "counts": dict(zip(map(str, SCORES), row.counts)),
                              "mean": _json_number(row.mean)}
                             for row in by_factor(data.spec, data.compared, {r.code: a.scores[r.code].final for r in data.compared},
                                                  blinding.factor)] if data.compared else [],
        "design": {key: value for key, value in data.diagnostics.items() if key != "correlation_map"},
        "score_shares": {str(score): dict(zip(("share", "low", "high"), map(_json_number, _share_interval(count, sum(total)))))
                         for score, count in zip(SCORES, total)} if sum(total) else {},
        "preregistration": {"sha256": data.registration.digest, "differs": list(data.registration.differs),
                            "matches_recorded": data.registration.recorded,
                            "analysis_registered": PLAN_BINDING not in data.registration.differs} if data.registration else None,
        "analysis_plan": {"table": a.plan.plan.table(), "sha256": a.plan.plan.digest(), "declared": a.plan.declared,
                          "committed_sha256": a.plan.committed, "matches_commitment": a.plan.matches,
                          "changed_after_key_opened": a.plan.changed_after_opening, "statement": a.plan.describe()},
        "primary": _primary_record(a.primary),
        "fits": [_fit_record(fit) for fit in a.judgment_fits + a.metric_fits],
        "notes": a.notes,
    }


def _primary_record(r: PrimaryResult | None) -> dict[str, Any] | None:
    """Every number of the primary section: the test, the effect estimates, the sensitivity fits."""
    if r is None:
        return None
    t = r.randomization
    return {
        "test": r.plan.describe_test(), "arms": list(r.arms), "runs": r.runs, "judgments": r.judgments,
        "mean_run_share": {arm: _json_number(v) for arm, v in r.mean_shares.items()}, "arm_runs": r.arm_runs,
        "p": _json_number(r.p_value),
        "randomization": None if t is None else {
            "difference": _json_number(t.difference), "low": _json_number(t.low), "high": _json_number(t.high), "level": t.level,
            "p": t.p_value, "allocations": t.allocations, "exact": t.exact, "draws": t.draws, "mc_standard_error": t.mc_error,
            "seed": t.seed, "strata": t.strata, "no_interval": t.no_interval or None,
            "interval": "the average difference over the runs, by inverting the studentized randomization test",
            "p_studentized": _json_number(t.p_studentized), "interval_agrees_with_p": t.agrees},
        "odds_ratio": None if r.odds_ratio is None else {"estimate": _json_number(r.odds_ratio.estimate), "low": _json_number(r.odds_ratio.low),
                                                          "high": _json_number(r.odds_ratio.high), "p": _json_number(r.odds_ratio.p_value),
                                                          "source": r.odds_ratio.source},
        "sensitivity": [{"analysis": name, **_fit_record(fit)} for name, fit in r.sensitivity],
        "notes": list(r.notes),
        "k_arms": None if r.k_arms is None else _k_arm_record(r.k_arms),
    }


def _k_arm_record(k: KArmResult) -> dict[str, Any]:
    g = k.global_test
    return {
        "global": {"statistic": g.statistic, "statistic_is": "between-arm sum of squares of run shares within strata", "p": g.p_value,
                   "allocations": g.allocations, "exact": g.exact, "draws": g.draws, "mc_standard_error": g.mc_error, "seed": g.seed,
                   "strata": g.strata},
        "correction": CORRECTION, "interval_level": k.interval_level,
        "pairs": [{"first": p.first, "second": p.second, "runs": p.test.runs, "difference": _json_number(p.test.difference),
                   "low": _json_number(p.test.low), "high": _json_number(p.test.high), "p": p.test.p_value, "holm_p": p.holm_p,
                   "exact": p.test.exact, "no_interval": p.test.no_interval or None} for p in k.pairs],
    }


def _json_number(value: float) -> float | None:
    return None if math.isnan(value) or math.isinf(value) else value


def _interval_record(interval: Interval) -> dict[str, float | None]:
    return {"estimate": _json_number(interval.estimate), "low": _json_number(interval.low), "high": _json_number(interval.high)}


def _fit_record(fit: Fit) -> dict[str, Any]:
    return {
        "response": fit.response,
        "method": fit.method,
        "parameters": [
            {"column": p.column, **{name: _json_number(getattr(p, name)) for name in ("estimate", "std_error", "low", "high")}, "p": _json_number(p.p_value)}
            for p in fit.parameters
        ],
        "effects": [{"term": e.term, "df": e.df, "statistic": _json_number(e.statistic), "p": _json_number(e.p_value)} for e in fit.effects],
        "summary": {name: _json_number(value) for name, value in fit.summary.items()},
        "notes": fit.notes,
    }


def _summary(a: _Analysis) -> list[str]:
    data = a.data
    lines = [f"Study {data.spec.name!r}: {len(data.finished)} of {len(data.runs)} runs finished"]
    if data.unfinished:
        lines.append(f"  not finished yet: {', '.join(r.code for r in data.unfinished)}")
    origins = _origins(data)
    if origins:
        lines.append(origins)
    if data.compared:
        total = counts(a.scores[r.code].final for r in data.compared)
        n = sum(total)
        shares = ", ".join(f"{s}: {c} ({100.0 * c / n:.1f} %)" for s, c in zip(SCORES, total))
        paper = paper_score_shares(data.spec)
        lines.append(f"Scores {shares}" + (f"   [paper: 3: {paper[3]:.1f} %, 1: {paper[1]:.0f} %]" if paper else ""))
    lines.append(a.plan.describe().replace("**", ""))
    primary = _primary_result(a)
    if primary:
        lines.append(primary.replace("**", ""))
    if a.table:
        lines.append(f"Judged socially compliant ({a.judgment_source}):")
        for row in a.table:
            cells = "   ".join(f"{arm} {percent(p.share)} ({p.k}/{p.n})" for arm, p in row.shares.items())
            test = f"   Fisher p {_equals(p_text(row.p_value))} (Holm {p_text(row.holm_p)})" if len(row.shares) == 2 else ""
            lines.append(f"  >= {row.min_pedestrians} pedestrians: {cells}{test}")
    if a.pooled:
        lines.append(f"Blinded, arms pooled: {a.pooled}")
    elif data.blinding.looking:
        lines.append(f"Interim look at the blinded arms ({data.blinding.completeness}), recorded in unblinding.json: {data.blinding.interim}")
    elif data.blinding.blinded:
        lines.append("Controllers named (unblinded)" if data.blinding.revealed else "Blinded: arms shown by label")
    lines += [f"Note: {note}" for note in a.notes]
    return lines
