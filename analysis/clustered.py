"""The primary analysis of the judgments: the plan's logistic model by GEE, with the run as the cluster.

The run is the experimental unit: its judgments share one robot behaviour, so they are correlated
and a fit that treats them as independent gives intervals that are too narrow. Generalized
estimating equations (Liang and Zeger 1986) fit the population-averaged logistic model to every
judgment, with an exchangeable working correlation inside a run (or independence, as a check).
statsmodels does the fitting. A study has few runs (18 in the A/B plan), so by default:

- the sandwich covariance carries Mancl and DeRouen's (2001) correction, each run's residuals
  r_i replaced by (I - H_i)^-1 r_i, where H_i = D_i M^-1 D_i' V_i^-1 is the run's leverage
  (statsmodels' 'bias_reduced'); Kauermann and Carroll's (2001) (I - H_i)^-1/2 r_i is the other
  choice, computed here from the fit's pieces since statsmodels does not offer it;
- parameters get t tests and t intervals, and each term a Wald F test (Wald / r against F(r, df)),
  on the cluster degrees of freedom df = runs with judgments - estimable columns; z and
  chi-square references are the large-sample option.

The exchangeable correlation alpha is a moment estimate from the Pearson residuals r: statsmodels
(the default here) divides the sum of within-run products by (pairs - p) and the scale sum r^2 by
(N - p); geepack's geeglm (its default scale.fix = FALSE) divides them by pairs and N, with no p.
The convention in use is stated in the fit's method text; GeeOptions chooses it. With geepack's convention the
estimates and alpha are geeglm's; its default errors (std.err = "san.se") are the uncorrected sandwich, so they
differ from these by the small-sample correction.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import statsmodels.api as sm
from scipy.special import expit
from scipy.stats import chi2, norm
from scipy.stats import f as f_dist
from scipy.stats import t as t_dist

from analysis.gee_options import GeeOptions
from analysis.models import DesignMatrix, Fit, effect_tests, estimability_notes, estimable_columns, parameter_rows, separation, with_intervals

DEFAULT = GeeOptions()


def judgment_rows(successes: np.ndarray, trials: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-run counts to one row per judgment: (run index of each judgment, 1 for yes and 0 for no)."""
    runs = np.repeat(np.arange(len(trials)), trials.astype(int))
    yes = np.concatenate([np.r_[np.ones(int(k)), np.zeros(int(n - k))] for k, n in zip(successes, trials)]) if len(trials) else np.zeros(0)
    return runs, yes


def fit_gee(dm: DesignMatrix, successes: np.ndarray, trials: np.ndarray, response: str, options: GeeOptions = DEFAULT) -> Fit:
    """The logistic model of `successes` of `trials` per run (rows of `dm`), clustered by run."""
    successes = np.asarray(successes, dtype=float)
    trials = np.asarray(trials, dtype=float)
    keep = estimable_columns(dm.x)
    notes = estimability_notes(dm, keep, len(trials))
    x = dm.x[:, keep]
    observations = int(trials.sum())
    clusters = int(np.count_nonzero(trials > 0))
    df = clusters - x.shape[1]
    t_reference = options.reference == "t"
    label = "t" if t_reference else "z"
    test = f"Wald F (clustered, denominator df {df})" if t_reference else "Wald chi-square (clustered)"
    method = options.method(df if df > 0 else None)
    missing = np.full(x.shape[1], math.nan)
    empty = Fit(response, method, len(trials), observations, label, test, parameter_rows(dm, keep, missing, missing, missing, missing), [], notes)
    if separation(x, successes, trials) is not None:
        notes.append("The judgments are perfectly separated: the GEE estimates do not exist; read the run-level shares and Firth's fit instead.")
        return empty
    if df <= 0:
        notes.append(f"{clusters} runs with judgments for {x.shape[1]} estimable columns: too few clusters for sandwich standard errors.")
        return empty
    runs, yes = judgment_rows(successes, trials)
    structure = sm.cov_struct.Exchangeable() if options.correlation == "exchangeable" else sm.cov_struct.Independence()
    model = sm.GEE(yes, x[runs], groups=runs, family=sm.families.Binomial(), cov_struct=structure)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = model.fit(cov_type="bias_reduced", ddof_scale=0 if options.alpha_estimator == "geepack" else None)
        except (np.linalg.LinAlgError, ValueError) as exc:
            notes.append(f"The GEE fit failed on these judgments ({exc}); read the run-level shares instead.")
            return empty
    notes += sorted({f"statsmodels: {w.message}" for w in caught})
    beta = np.asarray(result.params)
    alpha = float(np.asarray(result.model.cov_struct.dep_params)) if options.correlation == "exchangeable" else 0.0
    if options.covariance == "mancl-derouen":
        covariance = np.asarray(result.cov_params())
    else:
        covariance = adjusted_sandwich(x, successes, trials, beta, alpha, -0.5)
    if not np.all(np.isfinite(beta)) or not np.all(np.isfinite(np.diag(covariance))) or np.any(np.diag(covariance) < 0):
        notes.append("The GEE fit gave no finite estimates and standard errors on these judgments; read the run-level shares instead.")
        return empty
    se = np.sqrt(np.diag(covariance))
    statistic = beta / se
    if t_reference:
        p, quantile = 2.0 * t_dist.sf(np.abs(statistic), df), float(t_dist.ppf(0.975, df))
    else:
        p, quantile = 2.0 * norm.sf(np.abs(statistic)), float(norm.ppf(0.975))
    parameters = parameter_rows(dm, keep, beta, se, statistic, p)
    parameters = with_intervals(parameters, keep, list(zip(beta - quantile * se, beta + quantile * se)))
    position = np.cumsum(keep) - 1  # column of dm -> its index among the kept columns

    def wald(remaining: np.ndarray, r: int) -> tuple[float, float]:
        dropped = [position[j] for j in np.flatnonzero(keep) if j not in set(remaining)]
        b = beta[dropped]
        w = float(b @ np.linalg.solve(covariance[np.ix_(dropped, dropped)], b))
        return (w / r, float(f_dist.sf(w / r, r, df))) if t_reference else (w, float(chi2.sf(w, r)))

    effects = effect_tests(dm, keep, wald)
    summary = {"within-run correlation": alpha, "cluster df": float(df)}
    return Fit(response, method, len(trials), observations, label, test, parameters, effects, notes, summary)


def adjusted_sandwich(x: np.ndarray, successes: np.ndarray, trials: np.ndarray, beta: np.ndarray, alpha: float, power: float) -> np.ndarray:
    """The sandwich M^-1 (sum_i D_i' V_i^-1 A_i r_i r_i' A_i' V_i^-1 D_i) M^-1 with A_i = (I - H_i)^power, at `beta`
    and exchangeable correlation `alpha` (power -1: Mancl-DeRouen; -1/2: Kauermann-Carroll).

    Every judgment of run i has the run's model row x_i, so D_i = mu_i (1 - mu_i) 1 x_i', V_i = mu_i (1 - mu_i) R_i with
    R_i exchangeable. H_i = D_i M^-1 D_i' V_i^-1 is similar to the symmetric Q_i = V_i^-1/2 D_i M^-1 D_i' V_i^-1/2
    (H_i = V_i^1/2 Q_i V_i^-1/2), so (I - H_i)^power = V_i^1/2 (I - Q_i)^power V_i^-1/2, from Q_i's eigenvalues.
    """
    runs = []
    bread = np.zeros((len(beta), len(beta)))
    for row, k, n in zip(x, successes, trials):
        n = int(n)
        if n == 0:
            continue
        mu = float(expit(row @ beta))
        variance = mu * (1.0 - mu)
        d = variance * np.tile(row, (n, 1))
        v = variance * ((1.0 - alpha) * np.eye(n) + alpha)
        v_inv_d = np.linalg.solve(v, d)
        bread += d.T @ v_inv_d
        runs.append((d, v, v_inv_d, np.r_[np.ones(int(k)), np.zeros(n - int(k))] - mu))
    bread_inv = np.linalg.inv(bread)
    meat = np.zeros_like(bread)
    for d, v, v_inv_d, residual in runs:
        values, vectors = np.linalg.eigh(v)
        root, root_inv = (vectors * np.sqrt(values)) @ vectors.T, (vectors / np.sqrt(values)) @ vectors.T
        q = root_inv @ d @ bread_inv @ d.T @ root_inv
        lam, u = np.linalg.eigh(np.eye(len(residual)) - q)
        adjusted = root @ ((u * lam**power) @ u.T) @ root_inv @ residual
        score = v_inv_d.T @ adjusted
        meat += np.outer(score, score)
    return bread_inv @ meat @ bread_inv
