"""The random-intercept logistic model against statsmodels' binomial GLM where the run SD is 0, against a brute-force
integration of its marginal likelihood (scipy's quad per run), and across quadrature orders."""

from __future__ import annotations

import math

import numpy as np
import pytest
import statsmodels.api as sm
from scipy.integrate import quad
from scipy.special import expit

from analysis.mixed import fit_mixed, log_likelihood
from analysis.models import DesignMatrix, Fit

COLUMNS = ["Intercept", "Arm[A]", "Load"]
TERMS = [("Intercept", [0]), ("Arm", [1]), ("Load", [2])]


def varied_runs(seed: int, runs: int, sd: float) -> tuple[DesignMatrix, np.ndarray, np.ndarray]:
    """`runs` runs of 3 to 9 judgments, an arm and a per-run covariate, each run's log-odds shifted by N(0, sd^2)."""
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.ones(runs), np.tile([1.0, -1.0], runs // 2), rng.uniform(-1.0, 1.0, runs)])
    trials = rng.integers(3, 10, runs)
    successes = rng.binomial(trials, expit(x @ np.array([0.3, 0.7, -0.6]) + rng.normal(0.0, sd, runs)))
    return DesignMatrix(x, COLUMNS, TERMS), successes, trials


def brute_force(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray, sd: float) -> float:
    """The marginal log-likelihood, each run's integral over its intercept by adaptive quadrature (scipy's quad) of
    C(n, k) p^k (1 - p)^(n - k) exp(-u^2 / 2) / sqrt(2 pi)."""
    total = 0.0
    for eta, k, n in zip(x @ beta, successes.tolist(), trials.tolist()):
        def density(u: float, eta: float = float(eta), k: int = k, n: int = n) -> float:
            p = 1.0 / (1.0 + math.exp(-(eta + sd * u)))
            return math.comb(n, k) * p**k * (1.0 - p) ** (n - k) * math.exp(-0.5 * u * u) / math.sqrt(2.0 * math.pi)

        total += math.log(quad(density, -40.0, 40.0, epsabs=1e-15, epsrel=1e-13, limit=200)[0])
    return total


def estimates(fit: Fit) -> np.ndarray:
    return np.array([p.estimate for p in fit.parameters])


def test_zero_run_sd_is_the_binomial_glm() -> None:
    # Every run's count as close to its arm's expectation as whole numbers allow: less spread than binomial, so the ML
    # run SD is 0 and the fit is statsmodels' binomial GLM, down to the likelihood-ratio test of each term.
    dm, _, trials = varied_runs(5, 16, 0.0)
    successes = np.round(trials * expit(dm.x @ np.array([0.3, 0.7, -0.6])))
    fit = fit_mixed(dm, successes, trials, "yes")
    assert fit.summary["run SD"] == 0.0 and any("estimated at 0" in note for note in fit.notes)
    counts = np.column_stack([successes, trials - successes])
    glm = sm.GLM(counts, dm.x, family=sm.families.Binomial()).fit()
    assert estimates(fit) == pytest.approx(glm.params, abs=1e-6)
    assert [p.std_error for p in fit.parameters] == pytest.approx(glm.bse, rel=1e-5)
    assert [p.p_value for p in fit.parameters] == pytest.approx(glm.pvalues, rel=1e-4, abs=1e-9)
    assert fit.summary["log-likelihood"] == pytest.approx(glm.llf, abs=1e-8)
    reduced = sm.GLM(counts, dm.x[:, [0, 2]], family=sm.families.Binomial()).fit()
    assert fit.effects[0].term == "Arm" and fit.effects[0].statistic == pytest.approx(2 * (glm.llf - reduced.llf), abs=1e-6)


@pytest.fixture(scope="module")
def spread_fit() -> tuple[DesignMatrix, np.ndarray, np.ndarray, Fit]:
    """20 runs whose log-odds spread with SD 1.2 (seed 8), and their fit."""
    dm, successes, trials = varied_runs(8, 20, 1.2)
    return dm, successes, trials, fit_mixed(dm, successes, trials, "yes")


def test_fit_is_the_maximum_of_the_brute_force_likelihood(spread_fit: tuple[DesignMatrix, np.ndarray, np.ndarray, Fit]) -> None:
    dm, successes, trials, fit = spread_fit
    beta, sd = estimates(fit), fit.summary["run SD"]
    assert 0.5 < sd < 3.0 and not fit.notes
    # The quadrature's log-likelihood is the integral's, and the integral's gradient there is ~0 (central differences).
    assert fit.summary["log-likelihood"] == pytest.approx(brute_force(dm.x, successes, trials, beta, sd), abs=1e-6)
    theta, h = np.r_[beta, sd], 1e-4
    for j in range(len(theta)):
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        slope = (brute_force(dm.x, successes, trials, up[:-1], up[-1]) - brute_force(dm.x, successes, trials, down[:-1], down[-1])) / (2 * h)
        assert abs(slope) < 1e-5


def test_quadrature_orders_agree(spread_fit: tuple[DesignMatrix, np.ndarray, np.ndarray, Fit]) -> None:
    dm, successes, trials, fit = spread_fit
    beta, sd = estimates(fit), fit.summary["run SD"]
    assert log_likelihood(dm.x, successes, trials, beta, sd, 20) == pytest.approx(log_likelihood(dm.x, successes, trials, beta, sd, 40), abs=1e-6)
    assert log_likelihood(dm.x, successes, trials, beta, sd) == pytest.approx(log_likelihood(dm.x, successes, trials, beta, sd, 60), abs=1e-8)
    assert abs(log_likelihood(dm.x, successes, trials, beta, sd, 5) - log_likelihood(dm.x, successes, trials, beta, sd, 60)) > 1e-3
    # A random intercept changes the estimates and widens the errors against the plain logistic fit.
    glm = sm.GLM(np.column_stack([successes, trials - successes]), dm.x, family=sm.families.Binomial()).fit()
    assert fit.summary["log-likelihood"] > glm.llf + 1.0
    assert fit.parameters[1].std_error > glm.bse[1]


def test_likelihood_ratio_test_refits_without_the_term(spread_fit: tuple[DesignMatrix, np.ndarray, np.ndarray, Fit]) -> None:
    dm, successes, trials, fit = spread_fit
    reduced = fit_mixed(DesignMatrix(dm.x[:, [0, 2]], ["Intercept", "Load"], [("Intercept", [0]), ("Load", [1])]), successes, trials, "yes")
    arm = fit.effects[0]
    assert arm.statistic == pytest.approx(2 * (fit.summary["log-likelihood"] - reduced.summary["log-likelihood"]), abs=1e-8)
    assert arm.p_value == pytest.approx(math.erfc(math.sqrt(arm.statistic / 2)), rel=1e-9)
    assert fit.test == "likelihood-ratio chi-square" and "Gauss-Hermite" in fit.method


def test_separated_judgments_give_no_mixed_estimates() -> None:
    dm = DesignMatrix(np.column_stack([np.ones(6), np.repeat([1.0, -1.0], 3)]), COLUMNS[:2], TERMS[:2])
    fit = fit_mixed(dm, np.array([4, 4, 4, 0, 0, 0]), np.full(6, 4), "yes")
    assert all(math.isnan(p.estimate) for p in fit.parameters) and any("separated" in note for note in fit.notes)
    unjudged = fit_mixed(dm, np.zeros(6), np.zeros(6), "yes")
    assert all(math.isnan(p.estimate) for p in unjudged.parameters) and unjudged.notes[-1] == "No run has judgments: nothing to fit."
