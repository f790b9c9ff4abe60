"""Logistic and least-squares fits on a design against statsmodels, hand-solved cases and failure notes."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import statsmodels.api as sm
from scipy import stats
from scipy.optimize import approx_fprime, minimize
from scipy.special import logit
from scipy.stats import chi2

from analysis.models import DesignMatrix, _Likelihood, fit_least_squares, fit_logistic, separation
from designs.exchange import optimal_design
from designs.factors import CategoricalFactor, DiscreteFactor
from designs.model import parse_model
from designs.presets import ab


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
    counts = np.column_stack([successes, trials - successes])
    for j, parameter in enumerate(fit.parameters):
        others = [k for k in range(dm.x.shape[1]) if k != j]

        def held(value: float, column: int = j, others: list[int] = others) -> float:
            """statsmodels' log-likelihood with `column` held at `value` (an offset), the others refitted."""
            return sm.GLM(counts, dm.x[:, others], family=sm.families.Binomial(), offset=value * dm.x[:, column]).fit().llf

        # Each column's test is the likelihood ratio of dropping it, and its interval ends are where the profile deviance
        # reaches chi-square(1, 0.95): the likelihood's own interval, which excludes 0 exactly when the test rejects.
        assert parameter.statistic == pytest.approx(2 * (reference.llf - held(0.0)), abs=1e-6)
        assert parameter.p_value == pytest.approx(stats.chi2.sf(parameter.statistic, 1), abs=1e-9)
        for end in (parameter.low, parameter.high):
            assert 2 * (reference.llf - held(end)) == pytest.approx(stats.chi2.ppf(0.95, 1), abs=1e-5)
        assert (parameter.low > 0 or parameter.high < 0) == (parameter.p_value < 0.05)
    # The effect test of Controller drops its column: the LR statistic of the two nested fits.
    reduced = sm.GLM(counts, dm.x[:, [0, 1, 3]], family=sm.families.Binomial()).fit()
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


@cache
def _ab_all_yes() -> tuple[DesignMatrix, np.ndarray, np.ndarray]:
    """The 18-run A/B plan and its 11-column model, 4 judgments a run: arm A all yes, arm B's drawn at 50 % (seed 0).
    Firth's penalized likelihood has several local maxima here once a column is held away from its estimate."""
    spec = ab(("A", "B"))
    model = spec.build_model()
    design = optimal_design(model, 18, seed=1, starts=spec.starts, criterion=spec.criterion, per_run=spec.per_run())
    dm = DesignMatrix.from_model(model, design.settings)
    arm_a = dm.x[:, dm.columns.index("Controller[A]")] > 0
    return dm, np.where(arm_a, 4, np.random.default_rng(0).binomial(4, 0.5, 18)), np.full(18, 4)


def _penalized_with_gradient(x: np.ndarray, k: np.ndarray, n: np.ndarray, beta: np.ndarray) -> tuple[float, np.ndarray]:
    """Firth's penalized log-likelihood and its gradient, d log det I / d b_a = trace(I^-1 dI/db_a) / 2 written per column."""
    eta = x @ beta
    p = 1.0 / (1.0 + np.exp(-eta))
    w = n * p * (1 - p)
    information = x.T @ (w[:, None] * x)
    inverse = np.linalg.inv(information)
    value = float(np.sum(k * eta - n * np.logaddexp(0.0, eta)) + 0.5 * np.linalg.slogdet(information)[1])
    penalty = [0.5 * np.trace(inverse @ (x.T @ ((w * (1 - 2 * p) * x[:, a])[:, None] * x))) for a in range(x.shape[1])]
    return value, x.T @ (k - n * p) + np.array(penalty)


def _multistart(x: np.ndarray, k: np.ndarray, n: np.ndarray, column: int, value: float, starts: list[np.ndarray]) -> tuple[float, np.ndarray]:
    """The best of scipy's BFGS maxima of the penalized likelihood from `starts`, with `column` held at `value`."""
    others = [j for j in range(x.shape[1]) if j != column]

    def negative(free: np.ndarray) -> tuple[float, np.ndarray]:
        beta = np.empty(x.shape[1])
        beta[others], beta[column] = free, value
        v, g = _penalized_with_gradient(x, k, n, beta)
        return -v, -g[others]

    best = max((minimize(negative, s[others], jac=True, method="BFGS", options={"gtol": 1e-9}) for s in starts), key=lambda r: -r.fun)
    beta = np.empty(x.shape[1])
    beta[others], beta[column] = best.x, value
    return -float(best.fun), beta


def test_penalized_derivatives_match_numerical_ones() -> None:
    dm, k, n = _ab_all_yes()
    likelihood = _Likelihood(dm.x, k.astype(float), n.astype(float), firth=True)
    beta = np.random.default_rng(3).normal(0.0, 1.0, dm.x.shape[1])
    score, hessian = likelihood.derivatives(beta)
    assert score == pytest.approx(_penalized_with_gradient(dm.x, k, n, beta)[1], rel=1e-9, abs=1e-9)
    numerical = np.array([approx_fprime(beta, lambda b, a=a: likelihood.derivatives(b)[0][a], 1e-6) for a in range(len(beta))])
    assert hessian == pytest.approx(numerical, abs=1e-4)


def test_constrained_fit_reaches_a_maximum_from_any_start() -> None:
    # Far starts, with the Controller column held out on its profile: every fit ends where the free gradient vanishes
    # and the penalized likelihood curves down, and the best of them is no lower than scipy's BFGS from zero.
    dm, k, n = _ab_all_yes()
    x = dm.x
    likelihood = _Likelihood(x, k.astype(float), n.astype(float), firth=True)
    rng = np.random.default_rng(4)
    free = [j for j in range(x.shape[1]) if j != 4]
    values = []
    for start in [np.zeros(x.shape[1]), *(rng.normal(0.0, 4.0, x.shape[1]) for _ in range(4))]:
        beta, value = likelihood.maximise(start, {4: 3.0})
        score, hessian = likelihood.derivatives(beta)
        assert beta[4] == 3.0 and np.max(np.abs(score[free])) < 1e-7
        assert np.all(np.linalg.eigvalsh(hessian[np.ix_(free, free)]) < 0.0)
        assert value == pytest.approx(_penalized_with_gradient(x, k, n, beta)[0], rel=1e-12)
        values.append(value)
    assert max(values) >= _multistart(x, k, n, 4, 3.0, [np.zeros(x.shape[1])])[0] - 1e-9


@pytest.mark.slow
def test_firth_profile_ends_of_an_all_yes_study_match_a_multistart_optimiser() -> None:
    # Every end of every interval: along a scan from the estimate to the end, each point's maximum is scipy's best from
    # the previous point's maximum, the estimate, zero and three random starts; the deviance stays below
    # chi-square(1, 0.95) up to 0.0005 inside the end and is above it 0.0005 outside, so the end is right to 1e-3.
    dm, k, n = _ab_all_yes()
    x = dm.x
    fit = fit_logistic(dm, k, n, "yes")
    assert "Firth" in fit.method and all(math.isfinite(p.low) and math.isfinite(p.high) for p in fit.parameters)
    best = minimize(lambda b: tuple(-v for v in _penalized_with_gradient(x, k, n, b)), np.zeros(x.shape[1]), jac=True, method="BFGS", options={"gtol": 1e-10})
    top, optimum = -float(best.fun), best.x
    assert [p.estimate for p in fit.parameters] == pytest.approx(optimum, abs=1e-5)
    rng = np.random.default_rng(2)
    random = [optimum + rng.normal(0.0, 2.0, len(optimum)) for _ in range(3)]
    quantile = chi2.ppf(0.95, 1)
    for j, parameter in enumerate(fit.parameters):
        for end in (parameter.low, parameter.high):
            outward = np.sign(end - optimum[j])
            held = [*np.linspace(optimum[j], end, 8)[1:-1], end - 5e-4 * outward, end + 5e-4 * outward]
            previous, deviances = optimum, []
            for value in held:
                maximum, previous = _multistart(x, k, n, j, value, [previous, optimum, np.zeros(len(optimum)), *random])
                deviances.append(2.0 * (top - maximum))
            assert max(deviances[:-1]) < quantile < deviances[-1], (parameter.column, end, deviances)
