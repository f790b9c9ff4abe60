"""Logistic and least-squares fits on a design against statsmodels, hand-solved cases and failure notes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import statsmodels.api as sm
from scipy.optimize import minimize
from scipy.special import logit
from scipy.stats import chi2

from analysis.models import DesignMatrix, fit_least_squares, fit_logistic, separation
from designs.factors import CategoricalFactor, DiscreteFactor
from designs.model import parse_model


def _design(rows: int, seed: int = 0) -> tuple[DesignMatrix, np.random.Generator]:
    """Pedestrians (2, 4, 6) and an A/B arm with their interaction, random runs."""
    factors = (DiscreteFactor("Pedestrians", (2.0, 4.0, 6.0)), CategoricalFactor("Controller", ("A", "B"), blind=True))
    model = parse_model("main + interactions", factors)
    rng = np.random.default_rng(seed)
    settings = np.column_stack([rng.choice([-1.0, 0.0, 1.0], rows), rng.choice([0.0, 1.0], rows)])
    return DesignMatrix.from_model(model, settings), rng


def test_logistic_matches_statsmodels() -> None:
    dm, rng = _design(24)
    trials = rng.integers(3, 7, len(dm.x))
    truth = np.array([0.6, 0.5, -0.8, 0.3])
    successes = rng.binomial(trials, 1.0 / (1.0 + np.exp(-dm.x @ truth)))
    fit = fit_logistic(dm, successes, trials, "yes")
    reference = sm.GLM(np.column_stack([successes, trials - successes]), dm.x, family=sm.families.Binomial()).fit()
    assert fit.method.endswith("maximum likelihood") and not fit.notes
    assert [p.estimate for p in fit.parameters] == pytest.approx(reference.params, abs=1e-7)
    assert [p.std_error for p in fit.parameters] == pytest.approx(reference.bse, abs=1e-7)
    assert [p.p_value for p in fit.parameters] == pytest.approx(reference.pvalues, abs=1e-7)
    # The effect test of Controller drops its column: the LR statistic of the two nested fits.
    reduced = sm.GLM(np.column_stack([successes, trials - successes]), dm.x[:, [0, 1, 3]], family=sm.families.Binomial()).fit()
    controller = next(e for e in fit.effects if e.term == "Controller")
    assert controller.df == 1
    assert controller.statistic == pytest.approx(2 * (reference.llf - reduced.llf), abs=1e-6)
    assert [e.term for e in fit.effects] == ["Pedestrians", "Controller", "Pedestrians*Controller"]


def test_logistic_two_groups_by_hand() -> None:
    # Intercept and one +-1 column: the fitted log-odds of each group are its own logit(k / n).
    x = np.array([[1.0, 1.0], [1.0, -1.0]])
    dm = DesignMatrix(x, ["Intercept", "Arm[A]"], [("Intercept", [0]), ("Arm", [1])])
    fit = fit_logistic(dm, np.array([6, 2]), np.array([8, 8]), "yes")
    a, b = logit(6 / 8), logit(2 / 8)
    assert fit.parameters[0].estimate == pytest.approx((a + b) / 2)
    assert fit.parameters[1].estimate == pytest.approx((a - b) / 2)
    # Var of a group's logit is 1 / (n p (1 - p)); the +-1 coding halves the difference.
    var = 1 / (8 * 0.75 * 0.25)
    assert fit.parameters[1].std_error == pytest.approx(math.sqrt(2 * var) / 2)


def test_separation_falls_back_to_firth() -> None:
    # Every judgment yes: the ML intercept is infinite. Firth's intercept-only estimate is logit((k + 1/2) / (n + 1)).
    dm = DesignMatrix(np.ones((3, 1)), ["Intercept"], [("Intercept", [0])])
    successes, trials = np.array([4, 5, 3]), np.array([4, 5, 3])
    assert separation(dm.x, successes, trials) is not None
    fit = fit_logistic(dm, successes, trials, "yes")
    assert "Firth" in fit.method
    assert "perfectly separated" in fit.notes[0]
    assert fit.parameters[0].estimate == pytest.approx(logit(12.5 / 13), abs=1e-8)


def test_separation_by_an_arm_is_named() -> None:
    dm, _ = _design(12, seed=3)
    arm_a = dm.x[:, 2] > 0
    trials = np.full(len(dm.x), 4)
    successes = np.where(arm_a, 4, 0)
    assert separation(dm.x, successes, trials) is not None
    fit = fit_logistic(dm, successes, trials, "yes")
    assert "Controller[A]" in fit.notes[-1]
    assert all(np.isfinite(p.estimate) for p in fit.parameters)
    # Every run with both answers: no direction can separate them.
    assert separation(dm.x, np.where(arm_a, 3, 1), trials) is None


def test_aliased_term_is_left_out_with_a_note() -> None:
    # Every run at 4 pedestrians: the Pedestrians column is all zero, so it and its interaction cannot be estimated.
    dm, rng = _design(16)
    x = dm.x.copy()
    x[:, 1] = 0.0
    x[:, 3] = 0.0
    dm = DesignMatrix(x, dm.columns, dm.terms)
    y = rng.normal(size=16) + x[:, 2]
    fit = fit_least_squares(dm, y, "gap")
    assert math.isnan(fit.parameters[1].estimate) and math.isnan(fit.parameters[3].estimate)
    assert any("Pedestrians cannot be estimated" in note for note in fit.notes)
    assert fit.effects[0].df == 0 and math.isnan(fit.effects[0].p_value)
    reference = sm.OLS(y, x[:, [0, 2]]).fit()
    assert fit.parameters[2].estimate == pytest.approx(reference.params[1])


def test_least_squares_matches_statsmodels() -> None:
    dm, rng = _design(20, seed=7)
    y = dm.x @ np.array([1.0, -0.3, 0.4, 0.2]) + rng.normal(scale=0.3, size=20)
    fit = fit_least_squares(dm, y, "gap")
    reference = sm.OLS(y, dm.x).fit()
    assert [p.estimate for p in fit.parameters] == pytest.approx(reference.params)
    assert [p.std_error for p in fit.parameters] == pytest.approx(reference.bse)
    assert [p.p_value for p in fit.parameters] == pytest.approx(reference.pvalues)
    f_value, p_value, _ = reference.compare_f_test(sm.OLS(y, dm.x[:, [0, 2, 3]]).fit())
    pedestrians = fit.effects[0]
    assert pedestrians.statistic == pytest.approx(f_value) and pedestrians.p_value == pytest.approx(p_value)


def test_too_few_runs_are_reported() -> None:
    dm, rng = _design(3, seed=1)
    fit = fit_least_squares(dm, rng.normal(size=3), "gap")
    assert fit.notes[0].startswith("Too few runs: 3 runs with data for 4 model columns")
    assert any("No residual degrees of freedom" in note for note in fit.notes)
    assert all(math.isnan(e.p_value) for e in fit.effects)


def _penalized(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray) -> float:
    """Firth's penalized log-likelihood, written out independently: l(b) + log det(X'WX) / 2."""
    eta = x @ beta
    p = 1.0 / (1.0 + np.exp(-eta))
    information = x.T @ ((trials * p * (1 - p))[:, None] * x)
    return float(np.sum(successes * eta - trials * np.logaddexp(0.0, eta)) + 0.5 * np.linalg.slogdet(information)[1])


def _profile(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, column: int, value: float) -> float:
    """The penalized log-likelihood maximised over the other columns with one held at `value` (scipy's BFGS)."""
    others = [j for j in range(x.shape[1]) if j != column]

    def negative(free: np.ndarray) -> float:
        beta = np.empty(x.shape[1])
        beta[others], beta[column] = free, value
        return -_penalized(x, successes, trials, beta)

    return -float(minimize(negative, np.zeros(len(others)), method="BFGS", options={"gtol": 1e-10}).fun)


def test_firth_parameters_use_the_profile_penalized_likelihood() -> None:
    # Arm A all yes in every run (separated); arm B mixed. Checked against a separate maximisation.
    x = np.column_stack([np.ones(8), np.repeat([1.0, -1.0], 4), np.tile([-1.0, 1.0], 4)])
    dm = DesignMatrix(x, ["Intercept", "Arm[A]", "Peds"], [("Intercept", [0]), ("Arm", [1]), ("Peds", [2])])
    successes, trials = np.array([4, 6, 4, 6, 1, 3, 2, 4]), np.array([4, 6, 4, 6, 4, 6, 4, 6])
    fit = fit_logistic(dm, successes, trials, "yes")
    assert "Firth" in fit.method and fit.statistic == "penalized LR chi-square"
    best = -minimize(lambda b: -_penalized(x, successes, trials, b), np.zeros(3), method="BFGS", options={"gtol": 1e-10}).fun
    arm = fit.parameters[1]
    # The test of Arm = 0 and the effect test of the term are the same penalized LR statistic.
    assert arm.statistic == pytest.approx(2 * (best - _profile(x, successes, trials, 1, 0.0)), rel=1e-5)
    assert arm.p_value == pytest.approx(chi2.sf(arm.statistic, 1), rel=1e-9)
    assert next(e for e in fit.effects if e.term == "Arm").statistic == pytest.approx(arm.statistic, rel=1e-9)
    # The interval's ends are where the profile deviance reaches chi-square(1, 0.95) = 3.841.
    assert arm.low < arm.estimate < arm.high and math.isfinite(arm.high)
    for end in (arm.low, arm.high):
        assert 2 * (best - _profile(x, successes, trials, 1, end)) == pytest.approx(chi2.ppf(0.95, 1), abs=1e-4)
    # The profile interval is not the symmetric Wald one.
    assert arm.high - arm.estimate > 1.2 * (arm.estimate - arm.low)
