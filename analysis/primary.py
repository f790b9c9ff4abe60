"""The planned primary test of a study's judgments (`analysis.plan`), one way for the report and for power:
the run-level randomization test of two arms (of more: the global test, then Holm-adjusted pairs, `analysis.k_arm`), or
the small-sample GEE's test of the factor's term in the primary model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from analysis.ab_table import RunJudgments
from analysis.clustered import fit_gee
from analysis.errors import AnalysisError
from analysis.k_arm import KArmResult, global_test, k_arm_analysis
from analysis.mixed import fit_mixed
from analysis.models import DesignMatrix, Fit, fit_logistic
from analysis.plan import RANDOMIZATION, AnalysisPlan
from analysis.randomization import RandomizationTest, randomization_test
from analysis.records import StudyData, StudyRun
from analysis.study_fits import JUDGED, relabel, settings
from designs.factors import CategoricalFactor, DesignFactor
from designs.model import Model, parse_model


def primary_model(plan: AnalysisPlan, factors: tuple[DesignFactor, ...]) -> Model:
    """The plan's primary model over the study's design factors (the coding of the design)."""
    return parse_model(plan.model, factors)


def exploratory_model(plan: AnalysisPlan, factors: tuple[DesignFactor, ...]) -> Model | None:
    return parse_model(plan.exploratory, factors) if plan.exploratory else None


def run_randomization(plan: AnalysisPlan, arms: Sequence[str], first_arm: str, strata: Sequence[tuple[str, ...]],
                      yes: np.ndarray, total: np.ndarray, level: float | None) -> RandomizationTest:
    """The randomization test of the runs' shares of yes (runs with no judgment left out): `arms` names each run's arm,
    `strata` each run's values of the plan's strata; Monte Carlo, when needed, with the plan's draws and seed."""
    judged = np.asarray(total) > 0
    shares = np.asarray(yes, dtype=float)[judged] / np.asarray(total, dtype=float)[judged]
    first = np.array([arm == first_arm for arm in arms])[judged]
    labels = np.array(["\x1f".join(s) for s in strata])[judged] if plan.strata else None
    return randomization_test(shares, first, labels, level=level, draws=plan.draws, seed=plan.seed)


def primary_p_value(plan: AnalysisPlan, factors: tuple[DesignFactor, ...], settings: np.ndarray, arms: Sequence[str], first_arm: str,
                    strata: Sequence[tuple[str, ...]], yes: np.ndarray, total: np.ndarray, draws: int | None = None) -> float:
    """The planned primary test's p-value (NaN when it gives none); `draws` overrides the plan's Monte Carlo draws."""
    if plan.test == RANDOMIZATION:
        use = plan if draws is None else replace(plan, draws=draws)
        if len(set(arms)) > 2:
            judged = np.asarray(total) > 0
            shares = np.asarray(yes, dtype=float)[judged] / np.asarray(total, dtype=float)[judged]
            kept = [arm for arm, j in zip(arms, judged) if j]
            labels = np.array(["\x1f".join(s) for s in strata])[judged] if plan.strata else None
            return global_test(shares, kept, tuple(dict.fromkeys(arms)), labels, draws=use.draws, seed=use.seed).p_value
        return run_randomization(use, arms, first_arm, strata, yes, total, None).p_value
    judged = np.asarray(total) > 0
    dm = DesignMatrix.from_model(primary_model(plan, factors), np.asarray(settings)[judged])
    return factor_p_value(fit_gee(dm, np.asarray(yes)[judged], np.asarray(total)[judged], JUDGED, plan.gee_options()), plan.factor)


def factor_p_value(fit: Fit, factor: str) -> float:
    """The p-value of the compared factor's term in a fit (NaN when the fit could not test it)."""
    return next((e.p_value for e in fit.effects if e.term == factor), math.nan)


#: How each sensitivity analysis of the plan is named in the report.
SENSITIVITY_NAMES = {
    "gee-small-sample": "GEE, exchangeable, small-sample errors",
    "gee-independence": "GEE, independence working correlation",
    "random-intercept": "random-intercept logistic mixed model",
    "firth": "logistic regression of every judgment (Firth's penalized likelihood when separated)",
}


@dataclass(frozen=True)
class OddsRatio:
    """The first arm's odds of yes over the second's, from one fit of the primary model, with its 95 % interval."""

    estimate: float
    low: float
    high: float
    p_value: float
    source: str


@dataclass(frozen=True)
class PrimaryResult:
    """The planned primary analysis of a study's judgments: the test, the effect estimates and the sensitivity fits."""

    plan: AnalysisPlan
    #: The arms compared, in the factor's order (empty when the plan compares none).
    arms: tuple[str, ...]
    runs: int
    judgments: int
    #: Each arm's mean of its runs' shares of yes, and its number of runs with judgments.
    mean_shares: dict[str, float]
    arm_runs: dict[str, int]
    randomization: RandomizationTest | None
    #: The planned test's p-value (the randomization test's, or the GEE's test of the factor's term).
    p_value: float
    odds_ratio: OddsRatio | None
    #: (plan name, fit) of each sensitivity analysis, on the primary model.
    sensitivity: tuple[tuple[str, Fit], ...]
    notes: tuple[str, ...] = ()
    #: With more than two arms, the randomization plan's global test and Holm-adjusted pairs.
    k_arms: KArmResult | None = None


def arm_effect(fit: Fit, factor: str) -> OddsRatio | None:
    """The two-arm factor's effect in a fit as an odds ratio of the first arm to the second (effect coding: the
    first level's column is +1, the second's -1, so the log odds ratio is twice the coefficient); None when not estimated."""
    column = next((p for p in fit.parameters if p.column.startswith(f"{factor}[") and "*" not in p.column), None)
    if column is None or not math.isfinite(column.estimate):
        return None
    ends = [math.nan if math.isnan(v) else math.exp(2.0 * v) if math.isfinite(v) else (0.0 if v < 0 else math.inf)
            for v in (column.low, column.high)]
    return OddsRatio(math.exp(2.0 * column.estimate), ends[0], ends[1], column.p_value, fit.method)


def sensitivity_fit(plan: AnalysisPlan, name: str, dm: DesignMatrix, yes: np.ndarray, total: np.ndarray) -> Fit:
    """One named sensitivity analysis of the judgments on the primary model's rows `dm`, GEE fits by the plan's conventions."""
    if name == "gee-small-sample":
        return fit_gee(dm, yes, total, JUDGED, plan.gee_options())
    if name == "gee-independence":
        return fit_gee(dm, yes, total, JUDGED, plan.gee_options("independence"))
    if name == "random-intercept":
        return fit_mixed(dm, yes, total, JUDGED)
    return fit_logistic(dm, yes, total, JUDGED)


def primary_analysis(data: StudyData, judged: list[RunJudgments], plan: AnalysisPlan) -> PrimaryResult:
    """The plan's primary test, effect estimates and sensitivity fits on the judged runs of `data`."""
    by_code = {run.code: run for run in data.runs}
    runs = [by_code[j.code] for j in judged]
    yes = np.array([j.yes for j in judged], dtype=float)
    total = np.array([j.total for j in judged], dtype=float)
    dm = DesignMatrix.from_model(primary_model(plan, data.model.factors), settings(data, runs))
    fits = tuple((name, relabel(sensitivity_fit(plan, name, dm, yes, total), data.blinding)) for name in plan.sensitivity)
    arms = _arms(data, plan)
    arm_of = [_arm(data, plan, run) for run in runs]
    shares = yes / np.where(total > 0, total, 1.0)
    mean_shares = {arm: float(np.mean([s for s, a in zip(shares, arm_of) if a == arm])) if arm in arm_of else math.nan for arm in arms}
    arm_runs = {arm: arm_of.count(arm) for arm in arms}
    base = PrimaryResult(plan, arms, len(judged), int(total.sum()), mean_shares, arm_runs, None, math.nan, None, fits)
    if sum(count > 0 for count in arm_runs.values()) < 2:
        return replace(base, notes=("The plan's test compares arms; these judgments do not hold runs of two of them.",) if plan.factor else ())
    effect = None
    if len(arms) == 2:
        effect = next((replace(e, source=_odds_source(name, int(total.sum()))) for name, fit in fits
                       for e in [arm_effect(fit, plan.factor)] if e is not None), None)
    if plan.test == RANDOMIZATION:
        if min(arm_runs.values()) == 0:
            return replace(base, notes=("The randomization test compares every arm; these judgments do not hold runs of each.",))
        strata = [tuple(str(run.values[name]) for name in plan.strata) for run in runs]
        if len(arms) > 2:
            labels = np.array(["\x1f".join(s) for s in strata]) if plan.strata else None
            try:
                result = k_arm_analysis(shares, arm_of, arms, labels, plan.alpha, plan.draws, plan.seed)
            except AnalysisError as exc:
                return replace(base, notes=(f"The randomization test cannot be made on these judgments: {exc}.",))
            return replace(base, k_arms=result, p_value=result.global_test.p_value)
        try:
            test = run_randomization(plan, arm_of, arms[0], strata, yes, total, 1.0 - plan.alpha)
        except AnalysisError as exc:  # e.g. no stratum judged in both arms yet (an interim report)
            return replace(base, odds_ratio=effect, notes=(f"The randomization test cannot be made on these judgments: {exc}.",))
        return replace(base, randomization=test, p_value=test.p_value, odds_ratio=effect)
    gee = fits[0][1] if fits and fits[0][0] == "gee-small-sample" else relabel(fit_gee(dm, yes, total, JUDGED, plan.gee_options()), data.blinding)
    return replace(base, p_value=factor_p_value(gee, plan.factor), odds_ratio=effect)


#: The sensitivity fits that treat every judgment as independent of its run's others.
JUDGMENT_LEVEL = ("firth",)


def _odds_source(name: str, judgments: int) -> str:
    """Where the primary result's odds ratio comes from, saying so when that fit ignores the runs."""
    if name in JUDGMENT_LEVEL:
        return (f"{SENSITIVITY_NAMES[name]}; it treats the {judgments} judgments as independent, ignoring that judgments of one run "
                "share its behaviour, so its interval and p are narrower than the runs support")
    return SENSITIVITY_NAMES[name]


def _arms(data: StudyData, plan: AnalysisPlan) -> tuple[str, ...]:
    """The compared factor's levels as the report names them (arm labels, or controllers once unblinded)."""
    factor = next((f for f in data.spec.factors if f.name == plan.factor), None)
    if not isinstance(factor, CategoricalFactor):
        return ()
    if plan.factor == data.blinding.factor:
        return tuple(data.blinding.labels.get(level, level) for level in factor.levels)
    return tuple(factor.levels)


def _arm(data: StudyData, plan: AnalysisPlan, run: StudyRun) -> str:
    return run.arm if plan.factor == data.blinding.factor else str(run.values.get(plan.factor, ""))
