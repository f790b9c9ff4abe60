"""The run-level (clustered) analysis of judgments against statsmodels, on simulated judgments whose
intra-run correlation is known exactly (beta-binomial runs)."""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm
from scipy.special import logit
from scipy.stats import norm

from analysis.clustered import fit_gee, judgment_rows
from analysis.models import DesignMatrix, fit_logistic

ARM = DesignMatrix(np.zeros((0, 2)), ["Intercept", "Arm[A]"], [("Intercept", [0]), ("Arm", [1])])


def clustered_study(
    rng: np.random.Generator, runs: int, per_run: int, shares: tuple[float, float], correlation: float
) -> tuple[DesignMatrix, np.ndarray, np.ndarray]:
    """Half the runs in arm A (column +1), half in B (-1); each run's chance of yes is drawn from a beta
    distribution with the arm's mean, so two judgments of one run correlate by exactly `correlation`."""
    arm = np.repeat([1.0, -1.0], runs // 2)
    mean = np.where(arm > 0, shares[0], shares[1])
    scale = (1.0 - correlation) / correlation
    chance = rng.beta(mean * scale, (1.0 - mean) * scale)
    trials = np.full(runs, per_run)
    successes = rng.binomial(trials, chance)
    return DesignMatrix(np.column_stack([np.ones(runs), arm]), ARM.columns, ARM.terms), successes, trials


def test_judgment_rows_expand_counts() -> None:
    runs, yes = judgment_rows(np.array([2, 0, 3]), np.array([3, 1, 3]))
    assert runs.tolist() == [0, 0, 0, 1, 2, 2, 2]
    assert yes.tolist() == [1, 1, 0, 0, 1, 1, 1]


def test_gee_equals_statsmodels() -> None:
    dm, successes, trials = clustered_study(np.random.default_rng(7), 24, 6, (0.7, 0.45), 0.3)
    fit = fit_gee(dm, successes, trials, "yes")
    runs, yes = judgment_rows(successes, trials)
    reference = sm.GEE(yes, dm.x[runs], groups=runs, family=sm.families.Binomial(), cov_struct=sm.cov_struct.Exchangeable()).fit(cov_type="bias_reduced")
    assert [p.estimate for p in fit.parameters] == pytest.approx(reference.params, rel=1e-10)
    assert [p.std_error for p in fit.parameters] == pytest.approx(reference.bse, rel=1e-10)
    assert fit.parameters[1].p_value == pytest.approx(reference.pvalues[1], rel=1e-8)
    # One column: the Wald chi-square of the term is the square of its z.
    assert fit.effects[0].statistic == pytest.approx(fit.parameters[1].statistic**2, rel=1e-10)
    assert fit.summary["within-run correlation"] == pytest.approx(reference.model.cov_struct.dep_params, rel=1e-10)
    assert (fit.runs, fit.observations) == (24, 144)


def test_separated_judgments_give_no_gee_estimates() -> None:
    dm = DesignMatrix(np.column_stack([np.ones(6), np.repeat([1.0, -1.0], 3)]), ARM.columns, ARM.terms)
    fit = fit_gee(dm, np.array([4, 4, 4, 0, 0, 0]), np.full(6, 4), "yes")
    assert all(np.isnan(p.estimate) for p in fit.parameters)
    assert any("separated" in note for note in fit.notes)


@pytest.mark.slow
def test_clustered_interval_covers_and_naive_one_is_too_narrow() -> None:
    # 24 runs of 6 judgments, intra-run correlation 0.3: the design effect 1 + 5 * 0.3 = 2.5 makes the
    # independent-judgments interval about 1.6 times too narrow (coverage near 78 %).
    shares, correlation, z = (0.7, 0.45), 0.3, norm.ppf(0.975)
    truth = (logit(shares[0]) - logit(shares[1])) / 2.0  # effect coding: arm A is +b, arm B is -b
    rng = np.random.default_rng(2021)
    covered = {"naive": 0, "gee": 0}
    correlations = []
    simulations = 300
    for _ in range(simulations):
        dm, successes, trials = clustered_study(rng, 24, 6, shares, correlation)
        for name, fit in (("naive", fit_logistic(dm, successes, trials, "yes")), ("gee", fit_gee(dm, successes, trials, "yes"))):
            arm = fit.parameters[1]
            covered[name] += abs(arm.estimate - truth) <= z * arm.std_error
            if name == "gee":
                correlations.append(fit.summary["within-run correlation"])
    assert covered["naive"] / simulations < 0.85
    assert 0.91 <= covered["gee"] / simulations <= 0.98
    assert np.mean(correlations) == pytest.approx(correlation, abs=0.05)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 13, 29, 30, 35, 38, 39, 40, 60])
def test_all_yes_and_all_no_arms_give_fits_not_crashes(n: int) -> None:
    # Three runs per arm of n judgments each: arm A all yes, arm B all no, then arm B mixed.
    dm = DesignMatrix(np.column_stack([np.ones(6), np.repeat([1.0, -1.0], 3)]), ARM.columns, ARM.terms)
    trials = np.full(6, n)
    for b_yes in (np.zeros(3, dtype=int), np.array([0, n // 2, n])):
        successes = np.r_[np.full(3, n), b_yes]
        gee = fit_gee(dm, successes, trials, "yes")
        firth = fit_logistic(dm, successes, trials, "yes")
        assert any("separated" in note for note in gee.notes) and all(np.isnan(p.estimate) for p in gee.parameters)
        assert "Firth" in firth.method
        arm = firth.parameters[1]
        assert 0.0 < arm.estimate and arm.low < arm.estimate < arm.high and 0.0 <= arm.p_value <= 1.0
