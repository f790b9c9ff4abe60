"""The design's model fitted to results: logistic regression on judgments, least squares on metrics.

Both fits use the model matrix of the plan (coded factors, effect-coded categories) and report,
per column, the estimate, its standard error, a 95 % interval and a p-value (Wald z or t), and
per term an effect test: a likelihood-ratio chi-square (logistic) or a partial F test (least
squares) of the term's coefficients being zero. A column the runs cannot estimate (aliased with
earlier columns, or too few runs) is left out with a note. When judgments are perfectly separated
the maximum-likelihood estimates do not exist; the logistic fit then uses Firth's bias-reduced
(penalized) likelihood, and its column tests and intervals come from the profile penalized
likelihood (Heinze and Schemper 2002), since Wald ones misjudge penalized estimates.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq, linprog
from scipy.special import expit
from scipy.stats import chi2, norm
from scipy.stats import f as f_dist
from scipy.stats import t as t_dist

from designs.model import Model

_TOLERANCE = 1e-9


@dataclass(frozen=True)
class DesignMatrix:
    """Model-matrix rows of the runs with data, with the column labels and each term's columns."""

    x: np.ndarray
    columns: list[str]
    terms: list[tuple[str, list[int]]]

    @classmethod
    def from_model(cls, model: Model, settings: np.ndarray) -> DesignMatrix:
        """The rows of `settings` ((n, k) coded factor settings) under `model`."""
        terms = [(name, list(range(s.start, s.stop))) for name, s in zip(model.term_names, model.term_slices)]
        return cls(model.matrix(settings), model.columns, terms)

    def rows(self, keep: np.ndarray) -> DesignMatrix:
        return DesignMatrix(self.x[keep], self.columns, self.terms)


@dataclass(frozen=True)
class Parameter:
    """One model column: estimate, standard error, test statistic and p-value, and the 95 % interval
    where the fit gives one (NaN when not estimable or not given)."""

    column: str
    estimate: float
    std_error: float
    statistic: float
    p_value: float
    low: float = math.nan
    high: float = math.nan


@dataclass(frozen=True)
class EffectTest:
    """The test that all of a term's coefficients are zero."""

    term: str
    df: int
    statistic: float
    p_value: float


@dataclass(frozen=True)
class Fit:
    """A fitted model: what was fitted how, the parameters, the effect tests and what to know."""

    response: str
    method: str
    runs: int
    observations: int
    statistic: str
    test: str
    parameters: list[Parameter]
    effects: list[EffectTest]
    notes: list[str] = field(default_factory=list)
    #: Named figures of the whole fit (R^2, RMSE, the within-run correlation), in the order shown.
    summary: dict[str, float] = field(default_factory=dict)
    #: Per run (least squares only): the fitted value, the residual, and whether the value is flagged
    #: (censored at a limit), in the order of the runs fitted.
    fitted: tuple[float, ...] = ()
    residuals: tuple[float, ...] = ()
    flagged: tuple[bool, ...] = ()


def estimable_columns(x: np.ndarray) -> np.ndarray:
    """Mask of the columns that are not linear combinations of earlier columns."""
    keep: list[int] = []
    for j in range(x.shape[1]):
        if np.linalg.matrix_rank(x[:, keep + [j]]) > len(keep):
            keep.append(j)
    mask = np.zeros(x.shape[1], dtype=bool)
    mask[keep] = True
    return mask


def estimability_notes(dm: DesignMatrix, keep: np.ndarray, runs: int) -> list[str]:
    notes = []
    if runs < len(dm.columns):
        notes.append(f"Too few runs: {runs} runs with data for {len(dm.columns)} model columns.")
    for name, columns in dm.terms:
        lost = [dm.columns[j] for j in columns if not keep[j]]
        if lost:
            notes.append(
                f"{name} cannot be estimated from these runs: {', '.join(lost)} "
                "is a combination of earlier columns (aliased); it is left out of the fit."
            )
    return notes


def separation(x: np.ndarray, successes: np.ndarray, trials: np.ndarray) -> np.ndarray | None:
    """A direction b with b.x >= 0 for every yes and <= 0 for every no, if one exists (Konis' LP)."""
    signed = np.vstack([x[successes > 0], -x[successes < trials]])
    result = linprog(-signed.sum(axis=0), A_ub=-signed, b_ub=np.zeros(len(signed)), bounds=(-1.0, 1.0), method="highs")
    if result.status != 0 or -result.fun <= 1e-7:
        return None
    return np.asarray(result.x)


def _logistic(
    x: np.ndarray, successes: np.ndarray, trials: np.ndarray, firth: bool, fixed: dict[int, float] | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """Newton-Raphson (with step halving) for the binomial log-likelihood, or Firth's penalized one,
    with the columns in `fixed` held at the given values (the penalty still uses every column, as
    the profile penalized likelihood of Heinze and Schemper 2002 does).

    Returns the estimates, their covariance (inverse Fisher information) and the maximised objective.
    """
    fixed = fixed or {}
    free = np.array([j not in fixed for j in range(x.shape[1])])

    def information(beta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = expit(x @ beta)
        w = trials * p * (1.0 - p)
        return p, w, x.T @ (w[:, None] * x)

    def objective(beta: np.ndarray) -> float:
        eta = x @ beta
        value = float(np.sum(successes * eta - trials * np.logaddexp(0.0, eta)))
        if firth:
            value += 0.5 * np.linalg.slogdet(information(beta)[2])[1]
        return value

    beta = np.zeros(x.shape[1])
    for j, value in fixed.items():
        beta[j] = value
    current = objective(beta)
    for _ in range(200):
        p, w, info = information(beta)
        score = x.T @ (successes - trials * p)
        if firth:
            # pinv: far out on a profile the fitted chances saturate and the information is numerically singular
            leverage = w * np.einsum("ij,jk,ik->i", x, np.linalg.pinv(info), x)
            score = score + x.T @ (leverage * (0.5 - p))
        step = np.zeros_like(beta)
        step[free] = np.linalg.lstsq(info[np.ix_(free, free)], score[free], rcond=None)[0]
        scale = 1.0
        while scale > 1e-10:
            candidate = objective(beta + scale * step)
            if candidate >= current - 1e-12:
                break
            scale /= 2.0
        beta = beta + scale * step
        current = objective(beta)
        if np.max(np.abs(scale * step)) < 1e-10:
            break
    return beta, np.linalg.pinv(information(beta)[2]), current


def fit_logistic(dm: DesignMatrix, successes: np.ndarray, trials: np.ndarray, response: str) -> Fit:
    """Binomial logistic regression of `successes` of `trials` per run on the model matrix."""
    successes = np.asarray(successes, dtype=float)
    trials = np.asarray(trials, dtype=float)
    keep = estimable_columns(dm.x)
    notes = estimability_notes(dm, keep, len(trials))
    x = dm.x[:, keep]
    direction = separation(x, successes, trials)
    firth = direction is not None
    if direction is not None:
        involved = [dm.columns[j] for j, b in zip(np.flatnonzero(keep), direction) if abs(b) > 1e-6]
        notes.append(
            "The judgments are perfectly separated (along " + ", ".join(involved) + "): maximum-likelihood "
            "estimates do not exist, so Firth's bias-reduced estimates are shown, with tests and intervals "
            "from the profile penalized likelihood."
        )
    beta, covariance, objective = _logistic(x, successes, trials, firth)
    se = np.sqrt(np.diag(covariance))
    position = np.cumsum(keep) - 1  # column of dm -> its index among the kept columns

    def constrained(columns: list[int], values: float = 0.0) -> float:
        """The maximised objective with the given kept columns held at `values`."""
        return _logistic(x, successes, trials, firth, {j: values for j in columns})[2]

    if firth:
        # Wald tests understate the uncertainty of penalized estimates; the profile penalized likelihood does not.
        statistic = np.array([_chi_square_test(objective, constrained([j]), 1)[0] for j in range(len(beta))])
        p = chi2.sf(statistic, 1)
        parameters = parameter_rows(dm, keep, beta, se, statistic, p)
        intervals = [_profile_interval(lambda b, j=j: 2.0 * (objective - constrained([j], b)), beta[j], se[j]) for j in range(len(beta))]
        parameters = with_intervals(parameters, keep, intervals)
        label = "penalized LR chi-square"
    else:
        z = beta / se
        parameters = parameter_rows(dm, keep, beta, se, z, 2.0 * norm.sf(np.abs(z)))
        parameters = with_intervals(parameters, keep, [(b - _Z95 * e, b + _Z95 * e) for b, e in zip(beta, se)])
        label = "z"

    def effect(remaining: np.ndarray, df: int) -> tuple[float, float]:
        dropped = [int(position[j]) for j in np.flatnonzero(keep) if j not in set(remaining.tolist())]
        return _chi_square_test(objective, constrained(dropped), df)

    effects = effect_tests(dm, keep, effect)
    method = "logistic regression, Firth's penalized likelihood" if firth else "logistic regression, maximum likelihood"
    test = "penalized likelihood-ratio chi-square" if firth else "likelihood-ratio chi-square"
    return Fit(response, method, len(trials), int(trials.sum()), label, test, parameters, effects, notes)


_Z95 = 1.959963984540054
_CHI2_95 = _Z95**2


def _profile_interval(deviance: Callable[[float], float], estimate: float, std_error: float) -> tuple[float, float]:
    """The 95 % profile interval: where the deviance from the optimum crosses the chi-square(1) quantile
    on each side of the estimate (infinite where it never does within 50 standard errors)."""
    ends = []
    for sign in (-1.0, 1.0):
        inner, outer = estimate, estimate + sign * std_error
        while deviance(outer) < _CHI2_95 and abs(outer - estimate) < 50.0 * std_error:
            inner, outer = outer, estimate + 2.0 * (outer - estimate)
        if deviance(outer) < _CHI2_95:
            ends.append(sign * math.inf)
        else:
            ends.append(brentq(lambda b: deviance(b) - _CHI2_95, inner, outer, xtol=1e-8))
    return ends[0], ends[1]


def with_intervals(parameters: list[Parameter], keep: np.ndarray, intervals: list[tuple[float, float]]) -> list[Parameter]:
    """The parameters with the intervals of the kept columns, in order."""
    values = iter(intervals)
    rows = []
    for parameter, kept in zip(parameters, keep):
        if kept:
            low, high = next(values)
            parameter = replace(parameter, low=float(low), high=float(high))
        rows.append(parameter)
    return rows


def _chi_square_test(full: float, reduced: float, df: int) -> tuple[float, float]:
    statistic = max(0.0, 2.0 * (full - reduced))
    return statistic, float(chi2.sf(statistic, df))


def fit_least_squares(dm: DesignMatrix, y: np.ndarray, response: str) -> Fit:
    """Ordinary least squares of one value per run on the model matrix, with partial F tests."""
    y = np.asarray(y, dtype=float)
    keep = estimable_columns(dm.x)
    notes = estimability_notes(dm, keep, len(y))
    x = dm.x[:, keep]
    beta = np.linalg.lstsq(x, y, rcond=None)[0]
    sse = float(np.sum((y - x @ beta) ** 2))
    df_error = len(y) - x.shape[1]
    if np.ptp(y) == 0.0:
        notes.append(f"{response} is the same in every run: nothing to explain.")
    if df_error == 0:
        notes.append(f"No residual degrees of freedom ({len(y)} runs for {x.shape[1]} estimable columns): no standard errors or tests.")
        sigma2 = math.nan
    else:
        sigma2 = sse / df_error
    if sigma2 == 0.0 and np.ptp(y) > 0.0:
        notes.append(f"The model reproduces {response} exactly in every run: no error left to test against.")
    se = np.sqrt(sigma2 * np.diag(np.linalg.inv(x.T @ x)))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = beta / se
        p = 2.0 * t_dist.sf(np.abs(t), df_error) if df_error else np.full(len(beta), math.nan)
    parameters = parameter_rows(dm, keep, beta, se, t, p)
    if df_error:
        half = t_dist.ppf(0.975, df_error) * se
        parameters = with_intervals(parameters, keep, list(zip(beta - half, beta + half)))

    def partial_f(columns: np.ndarray, df: int) -> tuple[float, float]:
        if not df_error or sigma2 == 0.0:
            return math.nan, math.nan
        reduced = dm.x[:, columns]
        sse_reduced = float(np.sum((y - reduced @ np.linalg.lstsq(reduced, y, rcond=None)[0]) ** 2))
        statistic = max(0.0, (sse_reduced - sse) / df) / sigma2
        return statistic, float(f_dist.sf(statistic, df, df_error))

    effects = effect_tests(dm, keep, partial_f)
    total = float(np.sum((y - y.mean()) ** 2))
    summary = {"R^2": 1.0 - sse / total if total > 0.0 else math.nan, "RMSE": math.sqrt(sigma2)}
    fitted = x @ beta
    return Fit(
        response, "least squares", len(y), len(y), "t", f"partial F (error df {df_error})", parameters, effects, notes, summary,
        tuple(fitted.tolist()), tuple((y - fitted).tolist()), (False,) * len(y),
    )


def parameter_rows(dm: DesignMatrix, keep: np.ndarray, beta: np.ndarray, se: np.ndarray, statistic: np.ndarray, p: np.ndarray) -> list[Parameter]:
    """One Parameter per model column; columns left out get NaN."""
    values = iter(zip(beta, se, statistic, p))
    rows = []
    for column, kept in zip(dm.columns, keep):
        b, s, stat, pv = next(values) if kept else (math.nan,) * 4
        rows.append(Parameter(column, float(b), float(s), float(stat), float(pv)))
    return rows


def effect_tests(dm: DesignMatrix, keep: np.ndarray, test: Callable[[np.ndarray, int], tuple[float, float]]) -> list[EffectTest]:
    """Each non-intercept term's test of dropping its estimable columns; `test(columns kept, df)`."""
    effects = []
    for name, columns in dm.terms:
        if name == "Intercept":
            continue
        dropped = [j for j in columns if keep[j]]
        if not dropped:
            effects.append(EffectTest(name, 0, math.nan, math.nan))
            continue
        remaining = np.flatnonzero(keep & ~np.isin(np.arange(len(keep)), dropped))
        statistic, p = test(remaining, len(dropped))
        effects.append(EffectTest(name, len(dropped), statistic, p))
    return effects
