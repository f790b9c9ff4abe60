"""The primary analysis of the judgments: the plan's logistic model by GEE, with the run as the cluster.

The run is the experimental unit: its judgments share one robot behaviour, so they are correlated
and a fit that treats them as independent gives intervals that are too narrow. Generalized
estimating equations (Liang and Zeger 1986) fit the population-averaged logistic model to every
judgment with an exchangeable working correlation inside a run; the standard errors are the
sandwich estimator with Mancl and DeRouen's (2001) small-sample correction, since a study has few
runs. statsmodels does the fitting; effect tests are Wald chi-square tests on that covariance.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import statsmodels.api as sm
from scipy.stats import chi2, norm

from analysis.models import DesignMatrix, Fit, effect_tests, estimability_notes, estimable_columns, parameter_rows, separation, with_intervals

TEST = "Wald chi-square (clustered)"
METHOD = "logistic GEE clustered by run (exchangeable working correlation, bias-reduced sandwich errors)"


def judgment_rows(successes: np.ndarray, trials: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-run counts to one row per judgment: (run index of each judgment, 1 for yes and 0 for no)."""
    runs = np.repeat(np.arange(len(trials)), trials.astype(int))
    yes = np.concatenate([np.r_[np.ones(int(k)), np.zeros(int(n - k))] for k, n in zip(successes, trials)]) if len(trials) else np.zeros(0)
    return runs, yes


def fit_gee(dm: DesignMatrix, successes: np.ndarray, trials: np.ndarray, response: str) -> Fit:
    """The logistic model of `successes` of `trials` per run (rows of `dm`), clustered by run."""
    successes = np.asarray(successes, dtype=float)
    trials = np.asarray(trials, dtype=float)
    keep = estimable_columns(dm.x)
    notes = estimability_notes(dm, keep, len(trials))
    x = dm.x[:, keep]
    observations = int(trials.sum())
    missing = np.full(x.shape[1], math.nan)
    empty = Fit(response, METHOD, len(trials), observations, "z", TEST, parameter_rows(dm, keep, missing, missing, missing, missing), [], notes)
    if separation(x, successes, trials) is not None:
        notes.append("The judgments are perfectly separated: the GEE estimates do not exist; read the run-level shares and Firth's fit instead.")
        return empty
    if len(trials) <= x.shape[1]:
        notes.append(f"{len(trials)} runs for {x.shape[1]} estimable columns: too few clusters for sandwich standard errors.")
        return empty
    runs, yes = judgment_rows(successes, trials)
    model = sm.GEE(yes, x[runs], groups=runs, family=sm.families.Binomial(), cov_struct=sm.cov_struct.Exchangeable())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            result = model.fit(cov_type="bias_reduced")
        except (np.linalg.LinAlgError, ValueError) as exc:
            notes.append(f"The GEE fit failed on these judgments ({exc}); read the run-level shares instead.")
            return empty
    notes += sorted({f"statsmodels: {w.message}" for w in caught})
    beta = np.asarray(result.params)
    covariance = np.asarray(result.cov_params())
    if not np.all(np.isfinite(beta)) or not np.all(np.isfinite(np.diag(covariance))) or np.any(np.diag(covariance) < 0):
        notes.append("The GEE fit did not converge to finite estimates on these judgments; read the run-level shares instead.")
        return empty
    se = np.sqrt(np.diag(covariance))
    z = beta / se
    parameters = parameter_rows(dm, keep, beta, se, z, 2.0 * norm.sf(np.abs(z)))
    half = norm.ppf(0.975) * se
    parameters = with_intervals(parameters, keep, list(zip(beta - half, beta + half)))
    position = np.cumsum(keep) - 1  # column of dm -> its index among the kept columns

    def wald(remaining: np.ndarray, df: int) -> tuple[float, float]:
        dropped = [position[j] for j in np.flatnonzero(keep) if j not in set(remaining)]
        b = beta[dropped]
        statistic = float(b @ np.linalg.solve(covariance[np.ix_(dropped, dropped)], b))
        return statistic, float(chi2.sf(statistic, df))

    effects = effect_tests(dm, keep, wald)
    correlation = float(np.asarray(result.model.cov_struct.dep_params))
    return Fit(response, METHOD, len(trials), observations, "z", TEST, parameters, effects, notes, {"within-run correlation": correlation})
