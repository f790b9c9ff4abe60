"""The design's model fitted to results: logistic regression on judgments, least squares on metrics.

Both fits use the model matrix of the plan (coded factors, effect-coded categories) and report,
per column, the estimate, its standard error, a 95 % interval and a p-value, and per term an effect
test of the term's coefficients being zero. Least squares: t intervals and tests, partial F tests.
Logistic: likelihood-ratio tests of each column and term, and profile-likelihood intervals, so that
an interval excludes 0 exactly when its column's test rejects at 0.05. A column the runs cannot
estimate (aliased with earlier columns, or too few runs) is left out with a note. When judgments are
perfectly separated the maximum-likelihood estimates do not exist; the logistic fit then uses Firth's
bias-reduced (penalized) likelihood, with tests and intervals from the profile penalized likelihood
(Heinze and Schemper 2002), since Wald ones misjudge penalized estimates. The penalized
likelihood can have several local maxima once a column is held away from its estimate (seen when
one arm is all yes), so each constrained maximum is the best over continuation from the neighbouring
profile points and seeded random starts, and each interval end is where the profile deviance first
crosses chi-square(1, 0.95) = 3.8415, bracketed by stepping outward and found by brentq.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq, linprog, minimize
from scipy.special import expit
from scipy.stats import chi2
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


class _Likelihood:
    """The binomial log-likelihood of the runs' counts, or Firth's penalized one (l(b) + log det I(b) / 2), and its
    maximisation with some columns held at given values (the penalty still uses every column, as the profile penalized
    likelihood of Heinze and Schemper 2002 does)."""

    def __init__(self, x: np.ndarray, successes: np.ndarray, trials: np.ndarray, firth: bool) -> None:
        self.x, self.successes, self.trials, self.firth = x, successes, trials, firth

    def information(self, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fitted chances, binomial weights and the Fisher information X'WX at `beta`."""
        p = expit(self.x @ beta)
        w = self.trials * p * (1.0 - p)
        return p, w, self.x.T @ (w[:, None] * self.x)

    def objective(self, beta: np.ndarray) -> float:
        eta = self.x @ beta
        value = float(np.sum(self.successes * eta - self.trials * np.logaddexp(0.0, eta)))
        if self.firth:
            value += 0.5 * np.linalg.slogdet(self.information(beta)[2])[1]
        return value

    def derivatives(self, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gradient and Hessian of the objective. Firth's penalty log det I / 2 adds X'(h (1/2 - p)) to the score
        (h the hat values) and, with Q = X I^-1 X', w' = w (1 - 2p) and w'' = w ((1 - 2p)^2 - 2p (1 - p)) the
        derivatives of the weights, (X' diag(diag(Q) w'') X - X' diag(w') (Q o Q) diag(w') X) / 2 to the Hessian."""
        p, w, info = self.information(beta)
        score = self.x.T @ (self.successes - self.trials * p)
        hessian = -info
        if self.firth:
            # pinv: far out on a profile the fitted chances saturate and the information is numerically singular
            q = self.x @ np.linalg.pinv(info) @ self.x.T
            score = score + self.x.T @ (w * np.diag(q) * (0.5 - p))
            first, second = w * (1.0 - 2.0 * p), w * ((1.0 - 2.0 * p) ** 2 - 2.0 * p * (1.0 - p))
            weighted = first[:, None] * self.x
            hessian = hessian + 0.5 * (self.x.T @ ((np.diag(q) * second)[:, None] * self.x) - weighted.T @ (q**2) @ weighted)
        return score, hessian

    def maximise(self, start: np.ndarray, fixed: dict[int, float]) -> tuple[np.ndarray, float]:
        """A local maximum from `start` with the `fixed` columns at their values: Newton steps on the free columns (on
        the Hessian where it is negative definite, else on the Fisher information, an ascent direction either way),
        halved until the objective does not fall, until the free gradient vanishes; where Newton stalls first, scipy's
        trust-region Newton (trust-exact) finishes from the best point reached."""
        free = np.array([j not in fixed for j in range(self.x.shape[1])])
        beta = np.array(start, dtype=float)
        beta[list(fixed)] = list(fixed.values())
        current = self.objective(beta)
        for _ in range(_NEWTON_STEPS):
            score, hessian = self.derivatives(beta)
            score, curvature = score[free], -hessian[np.ix_(free, free)]
            if np.max(np.abs(score), initial=0.0) < _GRADIENT_TOLERANCE:
                return beta, current
            if np.any(np.linalg.eigvalsh(curvature) <= 0.0):
                curvature = self.information(beta)[2][np.ix_(free, free)]
            step = np.zeros_like(beta)
            step[free] = np.linalg.lstsq(curvature, score, rcond=None)[0]
            scale = 1.0
            # a fall within rounding of the objective is no fall: next to the maximum the objective cannot see the step
            while scale > 1e-12 and not self.objective(beta + scale * step) >= current - 1e-12 * (1.0 + abs(current)):
                scale /= 2.0
            if scale <= 1e-12:
                break
            beta = beta + scale * step
            current = self.objective(beta)
        if not math.isfinite(current):  # still where the information is singular: a start that leads nowhere
            return beta, -math.inf

        def pieces(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            trial = beta.copy()
            trial[free] = values
            score, hessian = self.derivatives(trial)
            return -score[free], -hessian[np.ix_(free, free)]

        def negative(values: np.ndarray) -> float:
            trial = beta.copy()
            trial[free] = values
            return -self.objective(trial)

        result = minimize(negative, beta[free], jac=lambda v: pieces(v)[0], hess=lambda v: pieces(v)[1], method="trust-exact",
                          options={"gtol": _GRADIENT_TOLERANCE, "maxiter": 500})
        if -result.fun > current:
            beta = beta.copy()
            beta[free] = result.x
            current = -float(result.fun)
        return beta, current

    def starts(self, anchor: np.ndarray) -> list[np.ndarray]:
        """Seeded random starts around `anchor` (Firth only: the plain log-likelihood is concave, one start finds its maximum)."""
        if not self.firth:
            return []
        rng = np.random.default_rng(PROFILE_SEED)
        return [anchor + rng.normal(0.0, _START_SPREAD, len(anchor)) for _ in range(_RANDOM_STARTS)]

    def best(self, fixed: dict[int, float], anchor: np.ndarray) -> float:
        """The highest local maximum with `fixed` held, from `anchor`, from zero and from the random starts."""
        return max(self.maximise(start, fixed)[1] for start in [anchor, np.zeros_like(anchor), *self.starts(anchor)])


#: Firth's penalized likelihood can have several local maxima once a column is held away from its estimate, so its
#: constrained maxima are taken over several starts, drawn with this seed (the same starts every time).
PROFILE_SEED = 0
_RANDOM_STARTS = 6
_START_SPREAD = 2.0
_NEWTON_STEPS = 100
_GRADIENT_TOLERANCE = 1e-8


class _Profile:
    """The profile objective of one column: the maximum over the other columns with it held at a value. Each value
    starts from the maxima found at the nearest values held on either side (continuation along every branch found,
    beginning at the estimate) and, when exploring, from the random starts, so the profile is the upper envelope of
    the branches found, and continuous."""

    def __init__(self, likelihood: _Likelihood, column: int, estimate: np.ndarray) -> None:
        self.likelihood, self.column, self.estimate = likelihood, column, estimate
        self.found: dict[float, list[np.ndarray]] = {float(estimate[column]): [estimate]}

    def value(self, held: float, explore: bool = False) -> float:
        nearest = {max((v for v in self.found if v <= held), default=None), min((v for v in self.found if v >= held), default=None)}
        starts = [beta for v in nearest if v is not None for beta in self.found[v]]
        if explore:
            starts += self.likelihood.starts(self.estimate)
        solutions = [self.likelihood.maximise(start, {self.column: held}) for start in starts]
        solutions.sort(key=lambda solution: -solution[1])
        distinct: list[np.ndarray] = []
        for beta, _ in solutions:
            if all(np.max(np.abs(beta - other)) > 1e-5 for other in distinct):
                distinct.append(beta)
        self.found[held] = distinct[:_BRANCHES]
        return solutions[0][1]


_BRANCHES = 3


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
            f"from the profile penalized likelihood (each constrained maximum the best of several starts, seed {PROFILE_SEED})."
        )
    likelihood = _Likelihood(x, successes, trials, firth)
    beta, objective = likelihood.maximise(np.zeros(x.shape[1]), {})
    for start in likelihood.starts(beta):
        candidate, value = likelihood.maximise(start, {})
        if value > objective:
            beta, objective = candidate, value
    se = np.sqrt(np.diag(np.linalg.pinv(likelihood.information(beta)[2])))
    position = np.cumsum(keep) - 1  # column of dm -> its index among the kept columns

    def constrained(columns: list[int]) -> float:
        """The maximised objective with the given kept columns held at zero."""
        return likelihood.best({j: 0.0 for j in columns}, beta)

    # Each column's test and interval from the same (penalized) likelihood as the terms' likelihood-ratio tests: Wald
    # ones misjudge penalized estimates, and beside a likelihood-ratio test a Wald interval can disagree with it.
    statistic = np.array([_chi_square_test(objective, constrained([j]), 1)[0] for j in range(len(beta))])
    parameters = parameter_rows(dm, keep, beta, se, statistic, chi2.sf(statistic, 1))
    intervals = [_profile_interval(_Profile(likelihood, j, beta), objective, se[j]) for j in range(len(beta))]
    parameters = with_intervals(parameters, keep, intervals)
    label = "penalized LR chi-square" if firth else "LR chi-square"

    def effect(remaining: np.ndarray, df: int) -> tuple[float, float]:
        dropped = [int(position[j]) for j in np.flatnonzero(keep) if j not in set(remaining.tolist())]
        return _chi_square_test(objective, constrained(dropped), df)

    effects = effect_tests(dm, keep, effect)
    method = "logistic regression, Firth's penalized likelihood" if firth else "logistic regression, maximum likelihood"
    test = "penalized likelihood-ratio chi-square" if firth else "likelihood-ratio chi-square"
    return Fit(response, method, len(trials), int(trials.sum()), label, test, parameters, effects, notes)


_Z95 = 1.959963984540054
_CHI2_95 = _Z95**2
#: Where the profile is first looked at on each side of the estimate, in standard errors; beyond the last the end is infinite.
_PROFILE_STEPS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.5, 8.0, 10.0, 13.0, 16.0, 20.0, 25.0, 32.0, 40.0, 50.0)


def _profile_interval(profile: _Profile, maximum: float, std_error: float) -> tuple[float, float]:
    """The 95 % profile interval: where the deviance 2 (maximum - profile) crosses the chi-square(1) quantile on each
    side of the estimate. Stepping outward brackets the crossing, brentq finds it on the profile (which continuation
    keeps continuous), and the random starts are tried at the bracket's outer end and at the root: a higher branch found
    there moves the bracket outward. Infinite where the deviance never crosses within 50 standard errors."""
    estimate = float(profile.estimate[profile.column])

    def excess(held: float, explore: bool = False) -> float:
        return 2.0 * (maximum - profile.value(held, explore)) - _CHI2_95

    def crossing(inner: float, outer: float) -> float | None:
        """The crossing between `inner` (below the quantile) and `outer` (at or above it), or None when the random
        starts find a higher branch at the root that carries the profile past `outer` as well."""
        while True:
            root = brentq(excess, inner, outer, xtol=1e-9)
            if excess(root, explore=True) >= -_ROOT_TOLERANCE:
                return root
            if excess(outer) < 0.0:
                return None
            inner = root

    ends = []
    for sign in (-1.0, 1.0):
        inner, end = estimate, sign * math.inf
        for multiple in _PROFILE_STEPS:
            outer = estimate + sign * multiple * std_error
            if excess(outer) >= 0.0 and excess(outer, explore=True) >= 0.0 and (root := crossing(inner, outer)) is not None:
                end = root
                break
            inner = outer
        ends.append(end)
    return ends[0], ends[1]


_ROOT_TOLERANCE = 1e-7


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
