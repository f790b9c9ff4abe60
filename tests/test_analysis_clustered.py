"""The run-level (clustered) analysis of judgments against statsmodels and against the small-sample sandwich
estimators written out here with numpy, on simulated judgments whose intra-run correlation is known exactly
(beta-binomial runs)."""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm
from scipy.linalg import sqrtm
from scipy.special import expit, logit
from scipy.stats import f as f_dist
from scipy.stats import norm
from scipy.stats import t as t_dist

from analysis.clustered import adjusted_sandwich, fit_gee, judgment_rows
from analysis.errors import AnalysisError
from analysis.gee_options import GeeOptions
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
    fit = fit_gee(dm, successes, trials, "yes", GeeOptions(reference="z"))
    runs, yes = judgment_rows(successes, trials)
    reference = sm.GEE(yes, dm.x[runs], groups=runs, family=sm.families.Binomial(), cov_struct=sm.cov_struct.Exchangeable()).fit(cov_type="bias_reduced")
    assert [p.estimate for p in fit.parameters] == pytest.approx(reference.params, rel=1e-10)
    assert [p.std_error for p in fit.parameters] == pytest.approx(reference.bse, rel=1e-10)
    assert fit.parameters[1].p_value == pytest.approx(reference.pvalues[1], rel=1e-8)
    # One column: the Wald chi-square of the term is the square of its z.
    assert fit.effects[0].statistic == pytest.approx(fit.parameters[1].statistic**2, rel=1e-10)
    assert fit.summary["within-run correlation"] == pytest.approx(reference.model.cov_struct.dep_params, rel=1e-10)
    assert (fit.runs, fit.observations) == (24, 144)
    assert fit.method.endswith("z and chi-square references)") and fit.test == "Wald chi-square (clustered)"


def uneven_study() -> tuple[DesignMatrix, np.ndarray, np.ndarray]:
    """14 runs of 2 to 9 judgments, an arm and a per-run covariate, beta-binomial runs (correlation 0.25), seed 11:
    uneven clusters and three columns, so the working correlation and the corrections all matter."""
    rng = np.random.default_rng(11)
    runs = 14
    x = np.column_stack([np.ones(runs), np.tile([1.0, -1.0], runs // 2), rng.uniform(-1.0, 1.0, runs)])
    mean = expit(x @ np.array([0.4, 0.6, -0.5]))
    scale = (1.0 - 0.25) / 0.25
    trials = rng.integers(2, 10, runs)
    successes = rng.binomial(trials, rng.beta(mean * scale, (1.0 - mean) * scale))
    dm = DesignMatrix(x, ["Intercept", "Arm[A]", "Load"], [("Intercept", [0]), ("Arm", [1]), ("Load", [2])])
    return dm, successes, trials


def numpy_sandwich(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray, alpha: float, kind: str) -> np.ndarray:
    """The GEE sandwich written out from the papers: bread M = sum_i D_i' V_i^-1 D_i; each run's residual r_i replaced by
    (I - H_i)^-1 r_i (Mancl and DeRouen 2001) or (I - H_i)^-1/2 r_i (Kauermann and Carroll 2001, principal square root),
    with H_i = D_i M^-1 D_i' V_i^-1, D_i = A_i X_i, V_i = A_i^1/2 R_i A_i^1/2, A_i = diag(mu (1 - mu)), R_i exchangeable."""
    clusters = []
    for row, k, n in zip(x, successes, trials):
        xi = np.tile(row, (int(n), 1))
        mu = expit(xi @ beta)
        a = np.diag(mu * (1 - mu))
        r = (1 - alpha) * np.eye(int(n)) + alpha * np.ones((int(n), int(n)))
        v = np.sqrt(a) @ r @ np.sqrt(a)
        y = np.r_[np.ones(int(k)), np.zeros(int(n - k))]
        clusters.append((a @ xi, v, y - mu))
    m = sum(d.T @ np.linalg.inv(v) @ d for d, v, _ in clusters)
    m_inv = np.linalg.inv(m)
    meat = np.zeros_like(m)
    for d, v, e in clusters:
        h = d @ m_inv @ d.T @ np.linalg.inv(v)
        adjust = np.linalg.inv(np.eye(len(e)) - h) if kind == "md" else np.linalg.inv(np.real(sqrtm(np.eye(len(e)) - h)))
        u = d.T @ np.linalg.inv(v) @ adjust @ e
        meat += np.outer(u, u)
    return m_inv @ meat @ m_inv


@pytest.mark.parametrize("covariance,kind", [("mancl-derouen", "md"), ("kauermann-carroll", "kc")])
@pytest.mark.parametrize("estimator", ["statsmodels", "geepack"])
def test_corrected_covariance_matches_the_papers(covariance: str, kind: str, estimator: str) -> None:
    dm, successes, trials = uneven_study()
    fit = fit_gee(dm, successes, trials, "yes", GeeOptions(covariance=covariance, alpha_estimator=estimator))  # type: ignore[arg-type]
    beta = np.array([p.estimate for p in fit.parameters])
    alpha = fit.summary["within-run correlation"]
    truth = numpy_sandwich(dm.x, successes, trials, beta, alpha, kind)
    se = np.sqrt(np.diag(truth))
    assert [p.std_error for p in fit.parameters] == pytest.approx(se, rel=1e-6)
    # t on the cluster df (14 runs - 3 columns = 11): intervals and p-values.
    assert fit.summary["cluster df"] == 11.0 and fit.statistic == "t" and "11 cluster df" in fit.method
    half = t_dist.ppf(0.975, 11) * se
    assert [p.low for p in fit.parameters] == pytest.approx(beta - half, rel=1e-6)
    assert [p.high for p in fit.parameters] == pytest.approx(beta + half, rel=1e-6)
    assert [p.p_value for p in fit.parameters] == pytest.approx(2 * t_dist.sf(np.abs(beta / se), 11), rel=1e-5)
    # One column per term: Wald / 1 = t^2 against F(1, 11).
    load = fit.effects[1]
    assert load.statistic == pytest.approx((beta[2] / se[2]) ** 2, rel=1e-6)
    assert load.p_value == pytest.approx(f_dist.sf(load.statistic, 1, 11), rel=1e-6)
    assert fit.test == "Wald F (clustered, denominator df 11)"


def test_kauermann_carroll_lies_between_the_plain_and_mancl_derouen_sandwiches() -> None:
    # Leverages shrink residuals, so the plain sandwich is smallest, (I - H)^-1 inflates most; and the helper's
    # power -1 is statsmodels' own bias-reduced covariance.
    dm, successes, trials = uneven_study()
    runs, yes = judgment_rows(successes, trials)
    result = sm.GEE(yes, dm.x[runs], groups=runs, family=sm.families.Binomial(), cov_struct=sm.cov_struct.Exchangeable()).fit(cov_type="bias_reduced")
    alpha = float(result.model.cov_struct.dep_params)
    beta = np.asarray(result.params)
    md = adjusted_sandwich(dm.x, successes, trials, beta, alpha, -1.0)
    plain = adjusted_sandwich(dm.x, successes, trials, beta, alpha, 0.0)
    kc = adjusted_sandwich(dm.x, successes, trials, beta, alpha, -0.5)
    assert md == pytest.approx(np.asarray(result.cov_params()), rel=1e-6)
    assert plain == pytest.approx(np.asarray(result.cov_robust), rel=1e-6)
    assert np.all(np.diag(plain) < np.diag(kc)) and np.all(np.diag(kc) < np.diag(md))


def test_geepack_alpha_is_the_plain_moment_estimate() -> None:
    # geepack: alpha = (sum of within-run products of Pearson residuals / pairs) / (sum of squares / judgments), no p.
    dm, successes, trials = uneven_study()
    geepack = fit_gee(dm, successes, trials, "yes", GeeOptions(alpha_estimator="geepack"))
    beta = np.array([p.estimate for p in geepack.parameters])
    products, squares, pairs = 0.0, 0.0, 0.0
    for row, k, n in zip(dm.x, successes, trials):
        mu = expit(row @ beta)
        r = (np.r_[np.ones(k), np.zeros(n - k)] - mu) / np.sqrt(mu * (1 - mu))
        products += (r.sum() ** 2 - (r**2).sum()) / 2
        squares += (r**2).sum()
        pairs += n * (n - 1) / 2
    assert geepack.summary["within-run correlation"] == pytest.approx((products / pairs) / (squares / trials.sum()), rel=1e-6)
    assert "as geepack's" in geepack.method
    # statsmodels' default subtracts p = 3 from both counts: a different number on the same data.
    default = fit_gee(dm, successes, trials, "yes")
    assert abs(default.summary["within-run correlation"] - geepack.summary["within-run correlation"]) > 1e-3
    assert "as statsmodels'" in default.method


def test_independence_working_correlation_is_the_plain_logistic_fit() -> None:
    # With independence the GEE estimates are the ordinary maximum-likelihood ones; only the errors differ.
    dm, successes, trials = uneven_study()
    fit = fit_gee(dm, successes, trials, "yes", GeeOptions(correlation="independence"))
    reference = sm.GLM(np.column_stack([successes, trials - successes]), dm.x, family=sm.families.Binomial()).fit()
    assert [p.estimate for p in fit.parameters] == pytest.approx(reference.params, rel=1e-6)
    assert fit.summary["within-run correlation"] == 0.0 and "independence working correlation" in fit.method
    exchangeable = fit_gee(dm, successes, trials, "yes")
    assert abs(exchangeable.parameters[2].estimate - fit.parameters[2].estimate) > 1e-3


def test_unknown_option_is_named() -> None:
    with pytest.raises(AnalysisError, match="covariance is 'huber'; expected one of mancl-derouen, kauermann-carroll"):
        GeeOptions(covariance="huber")  # type: ignore[arg-type]


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
