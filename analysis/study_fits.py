"""The study's own model (its plan's terms) fitted to the judgments and to the outcome metrics of its runs."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np

from analysis.ab_table import RunJudgments
from analysis.clustered import DEFAULT, fit_gee
from analysis.gee_options import GeeOptions
from analysis.models import DesignMatrix, Fit, fit_least_squares, fit_logistic
from analysis.records import Blinding, StudyData, StudyRun
from designs.factors import CategoricalFactor

#: Outcome metrics fitted by least squares: (column of outcomes.csv, how the report names it).
METRICS = (
    ("min_distance_m", "minimum gap (m)"),
    ("time_within_1_2m_s", "time in personal space (s)"),
    ("duration_s", "duration (s)"),
    ("path_irregularity_rad_per_m", "path irregularity (rad/m)"),
)


def settings(data: StudyData, runs: list[StudyRun]) -> np.ndarray:
    """(n, k) coded settings of the runs' plan values, one column per design factor."""
    factors = data.model.factors
    rows = []
    for run in runs:
        row = []
        for factor in factors:
            value = run.values[factor.name]
            row.append(factor.encode(value) if isinstance(factor, CategoricalFactor) else factor.encode(float(value)))
        rows.append(row)
    return np.asarray(rows, dtype=float).reshape(len(runs), len(factors))


def relabel(fit: Fit, blinding: Blinding) -> Fit:
    """Column labels with controller names instead of arm labels, once the report may name them: in the parameters and
    in the notes that name columns (separation, aliasing)."""
    if not (blinding.blinded and blinding.open) or blinding.factor is None:
        return fit
    names = {f"{blinding.factor}[{arm}]": f"{blinding.factor}[{name}]" for arm, name in blinding.labels.items()}

    def rename(column: str) -> str:
        return "*".join(names.get(part, part) for part in column.split("*"))

    pattern = re.compile("|".join(map(re.escape, names)))

    def in_note(note: str) -> str:
        return pattern.sub(lambda match: names[match.group()], note)

    return replace(fit, parameters=[replace(p, column=rename(p.column)) for p in fit.parameters], notes=[in_note(n) for n in fit.notes])


JUDGED = "judged socially compliant"


def _judged_matrix(data: StudyData, judged: list[RunJudgments]) -> tuple[DesignMatrix, np.ndarray, np.ndarray]:
    """The model rows of the judged runs, their yes counts and their judgment counts."""
    by_code = {run.code: run for run in data.runs}
    dm = DesignMatrix.from_model(data.model, settings(data, [by_code[j.code] for j in judged]))
    return dm, np.array([j.yes for j in judged], dtype=float), np.array([j.total for j in judged], dtype=float)


def fit_judgments(data: StudyData, judged: list[RunJudgments]) -> Fit:
    """Logistic regression of every judgment on the plan's terms, as if judgments were independent (descriptive)."""
    dm, yes, total = _judged_matrix(data, judged)
    return relabel(fit_logistic(dm, yes, total, JUDGED), data.blinding)


def fit_judgments_by_run(data: StudyData, judged: list[RunJudgments], options: GeeOptions = DEFAULT) -> Fit:
    """The design's logistic model by GEE, each run a cluster of judgments (the plan's exploratory fit)."""
    dm, yes, total = _judged_matrix(data, judged)
    return relabel(fit_gee(dm, yes, total, JUDGED, options), data.blinding)


def fit_run_shares(data: StudyData, judged: list[RunJudgments]) -> Fit:
    """Least squares of each run's share of yes on the plan's terms: every run weighs the same."""
    dm, yes, total = _judged_matrix(data, judged)
    return relabel(fit_least_squares(dm, yes / total, "share of yes per run"), data.blinding)


#: The metric a run that ran out of time has only as a lower bound: it stopped at the time limit.
CENSORED_BY_TIMEOUT = "duration_s"
TIMEOUT = "timeout"


def fit_metrics(data: StudyData) -> list[Fit]:
    """Least squares of each outcome metric on the plan's terms, over the finished runs the toolkit drove that have
    a value (a run played from an external robot log measures a robot no arm drove); durations of runs that timed
    out are flagged as censored."""
    fits = []
    for column, name in METRICS:
        runs = [run for run in data.compared if getattr(run.outcome, column) is not None]
        if not runs:  # no finished run has this metric (time to goal when none arrived): nothing to fit
            continue
        dm = DesignMatrix.from_model(data.model, settings(data, runs))
        y = np.array([getattr(run.outcome, column) for run in runs], dtype=float)
        fit = relabel(fit_least_squares(dm, y, name), data.blinding)
        censored = tuple(column == CENSORED_BY_TIMEOUT and run.outcome is not None and run.outcome.status == TIMEOUT for run in runs)
        if any(censored):
            note = (
                f"{sum(censored)} of {len(runs)} runs timed out: their {name} is only the time limit, a lower bound (censored), "
                "so least squares understates the effects on it; they are marked in the residual plot."
            )
            fit = replace(fit, flagged=censored, notes=[*fit.notes, note])
        fits.append(fit)
    return fits
