"""One simulated data set analysed as `trials report` analyses a study: the judgments by the planned primary test
(`analysis.primary`), the run-level GEE of the design's model (`analysis.clustered`) and Table II (`analysis.ab_table`),
a continuous outcome by least squares.

A verdict keeps only what power needs: each term's p-value and each Table II row's arm shares and
Holm-adjusted p-value. A fit that gives no test (separated judgments, too few clusters) counts as
not rejecting: NaN p-value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from analysis.ab_table import RunJudgments, table_ii
from analysis.clustered import DEFAULT, fit_gee
from analysis.models import DesignMatrix, Fit, fit_least_squares
from analysis.plan import AnalysisPlan
from analysis.primary import primary_p_value
from designs.factors import CategoricalFactor
from trials.power.plans import PowerPlan


@dataclass(frozen=True)
class RowVerdict:
    """One Table II row: runs with at least `min_pedestrians`, each arm's share of yes and the
    Holm-adjusted p-value of the arms' difference."""

    min_pedestrians: int
    shares: dict[str, float]
    holm_p: float


@dataclass(frozen=True)
class Verdict:
    """What one data set shows: each model term's p-value (intercept left out) and Table II's rows."""

    term_p: dict[str, float]
    rows: tuple[RowVerdict, ...] = ()
    #: The planned primary test's p-value (NaN: no plan given, or no test).
    primary_p: float = math.nan


#: Monte Carlo draws of a randomization test whose allocations are too many to enumerate, per simulated data set:
#: fewer than a report's, which costs a little power (p is never below 1 / (1 + draws)) and keeps power fast.
POWER_DRAWS = 2000


def planned_p(plan: PowerPlan, analysis: AnalysisPlan, yes: np.ndarray, total: np.ndarray) -> float:
    """The planned primary test's p-value on `yes` of `total` judgments per run of `plan` (NaN for a plan that compares
    no factor: its GEE test is the term tests' own)."""
    if not analysis.factor:
        return math.nan
    factor = next((f for f in plan.model.factors if f.name == analysis.factor), None)
    first = str(factor.levels[0]) if isinstance(factor, CategoricalFactor) else ""
    arms = [row.get(analysis.factor, "") for row in plan.rows]
    strata = [tuple(row[name] for name in analysis.strata) for row in plan.rows]
    return primary_p_value(analysis, plan.model.factors, plan.settings, arms, first, strata, yes, total, draws=POWER_DRAWS)


def term_p_values(fit: Fit, plan: PowerPlan) -> dict[str, float]:
    """Each term's effect-test p-value (NaN for a term the fit could not test)."""
    tested = {effect.term: effect.p_value for effect in fit.effects}
    return {name: float(tested.get(name, math.nan)) for name in plan.model.term_names[1:]}


def judgments_verdict(plan: PowerPlan, yes: np.ndarray, total: np.ndarray, arm_names: list[str] | None = None,
                      analysis: AnalysisPlan | None = None) -> Verdict:
    """The GEE term tests, Table II and, with `analysis`, the planned primary test of `yes` of `total` judgments per run
    of `plan`; `arm_names` names each run's arm (default: its Controller level)."""
    dm = DesignMatrix.from_model(plan.model, plan.settings)
    fit = fit_gee(dm, yes, total, "judged socially compliant", analysis.gee_options() if analysis is not None else DEFAULT)
    arms = arm_names if arm_names is not None else plan.arm_of_runs()
    rows: tuple[RowVerdict, ...] = ()
    if plan.arms:
        judged = [RunJudgments(code, arm, peds, int(k), int(n))
                  for code, arm, peds, k, n in zip(plan.codes, arms, plan.pedestrians(), yes, total) if n > 0]
        order = list(dict.fromkeys(sorted(arms)))
        rows = tuple(RowVerdict(row.min_pedestrians, {arm: share.share for arm, share in row.shares.items()}, row.holm_p)
                     for row in table_ii(judged, order))
    return Verdict(term_p_values(fit, plan), rows, planned_p(plan, analysis, yes, total) if analysis is not None else math.nan)


def gaussian_verdict(plan: PowerPlan, y: np.ndarray) -> Verdict:
    """The least-squares term tests (partial F) of a continuous outcome `y` per run."""
    fit = fit_least_squares(DesignMatrix.from_model(plan.model, plan.settings), y, "outcome")
    return Verdict(term_p_values(fit, plan))
