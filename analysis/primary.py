"""The planned primary test of a study's judgments (`analysis.plan`), one way for the report and for power:
the run-level randomization test of the arms, or the small-sample GEE's test of the factor's term in the primary model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from analysis.clustered import fit_gee
from analysis.models import DesignMatrix
from analysis.plan import RANDOMIZATION, AnalysisPlan
from analysis.randomization import RandomizationTest, randomization_test
from designs.factors import DesignFactor
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
        return run_randomization(use, arms, first_arm, strata, yes, total, None).p_value
    judged = np.asarray(total) > 0
    dm = DesignMatrix.from_model(primary_model(plan, factors), np.asarray(settings)[judged])
    fit = fit_gee(dm, np.asarray(yes)[judged], np.asarray(total)[judged], "judged socially compliant")
    return next((e.p_value for e in fit.effects if e.term == plan.factor), math.nan)
