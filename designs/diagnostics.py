"""Design diagnostics with JMP's conventions (coded factors, sigma = 1).

With X the n x p model matrix and V = (X'X)^-1:
- D-efficiency  100 det(X'X / n)^(1/p)
- A-efficiency  100 p / (n trace V)
- G-efficiency  100 sqrt(p / n) / sigma_M, sigma_M^2 the largest x'Vx over the design region
- average prediction variance  trace(V M), M the moment matrix of the region
- power of each term's F test at level alpha for JMP's anticipated coefficients: a term's
  columns get +1, -1, +1, ... (so a categorical term's levels differ as JMP assumes), times the
  term's anticipated coefficient (default 1), times `snr`, the signal-to-noise ratio

The design region is the box [-1, 1] for continuous factors, the levels of discrete and
categorical factors, all combinations equally likely.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.special import fdtri, ncfdtr

from designs.errors import DesignError
from designs.factors import CategoricalFactor, ContinuousFactor
from designs.model import Model

#: How the power's anticipated coefficients are set, as design.json and the report say it.
POWER_CONVENTION = "JMP's convention: +c, -c, +c, ... over each term's columns, c the term's anticipated coefficient (default 1)"
#: Levels per continuous factor of the grid searched for the largest prediction variance.
_REGION_GRID = 21
_MAX_REGION_POINTS = 200_000


@dataclass(frozen=True)
class TermPower:
    """Power of the test that all coefficients of one term are zero."""

    term: str
    parameters: int
    power: float


@dataclass(frozen=True)
class Diagnostics:
    """Everything `design.json` reports about a design's quality."""

    n: int
    p: int
    det_xtx: float
    d_efficiency: float
    a_efficiency: float
    g_efficiency: float
    average_prediction_variance: float
    max_prediction_variance: float
    standard_errors: dict[str, float]
    correlation_columns: list[str]
    correlations: np.ndarray
    alpha: float
    snr: float
    error_df: int
    term_power: list[TermPower]
    parameter_power: dict[str, float]
    #: The anticipated coefficient of each model column that the power assumes (snr included).
    anticipated: dict[str, float] = field(default_factory=dict)


def anticipated_coefficients(model: Model, snr: float = 1.0, per_term: Mapping[str, float] | None = None) -> np.ndarray:
    """JMP's anticipated coefficients: over each term's columns +1, -1, +1, ..., times the term's own
    coefficient (`per_term`, default 1) and `snr`. An unknown term name is a DesignError."""
    per_term = dict(per_term or {})
    unknown = sorted(set(per_term) - set(model.term_names))
    if unknown:
        raise DesignError(f"[anticipated] in the spec: {unknown[0]!r} is not a term of the model (terms: {', '.join(model.term_names)})")
    beta = np.empty(model.p)
    for name, columns in zip(model.term_names, model.term_slices):
        width = columns.stop - columns.start
        beta[columns] = snr * per_term.get(name, 1.0) * np.where(np.arange(width) % 2 == 0, 1.0, -1.0)
    return beta


def diagnose(model: Model, settings: np.ndarray, *, alpha: float = 0.05, snr: float = 1.0, anticipated: Mapping[str, float] | None = None) -> Diagnostics:
    """Diagnostics of the design with the given (n, k) factor settings; `anticipated` maps term names to
    their anticipated coefficient (default 1) for the power."""
    x = model.matrix(settings)
    n, p = x.shape
    info = x.T @ x
    inv = np.linalg.inv(info)
    sign, log_det = np.linalg.slogdet(info)
    columns = model.columns
    max_var = max_prediction_variance(model, inv)
    error_df = max(n - p, 1)  # JMP sets the error df of a saturated design to 1
    beta = anticipated_coefficients(model, snr, anticipated)
    term_power = [
        TermPower(model.term_name(t), s.stop - s.start, _power(inv[s, s], beta[s], alpha, error_df))
        for t, s in zip(model.terms, model.term_slices)
    ]
    parameter_power = {c: _power(inv[j : j + 1, j : j + 1], beta[j : j + 1], alpha, error_df) for j, c in enumerate(columns)}
    return Diagnostics(
        n=n,
        p=p,
        det_xtx=float(sign * np.exp(log_det)),
        d_efficiency=100.0 * float(np.exp(log_det / p)) / n,
        a_efficiency=100.0 * p / (n * float(np.trace(inv))),
        g_efficiency=100.0 * float(np.sqrt(p / n / max_var)),
        average_prediction_variance=float(np.trace(inv @ model.moment_matrix())),
        max_prediction_variance=max_var,
        standard_errors=dict(zip(columns, np.sqrt(np.diag(inv)).tolist())),
        correlation_columns=columns[1:],
        correlations=_correlations(x[:, 1:]),
        alpha=alpha,
        snr=snr,
        error_df=error_df,
        term_power=term_power,
        parameter_power=parameter_power,
        anticipated=dict(zip(columns, beta.tolist())),
    )


def max_prediction_variance(model: Model, inv: np.ndarray) -> float:
    """The largest relative prediction variance x'(X'X)^-1 x over the design region.

    The variance is convex in any coordinate that enters the model linearly, so the candidate
    grid holds its maximum unless a continuous factor is squared; then a grid of 21 values per
    such factor is searched and its best points are polished with L-BFGS-B.
    """
    squared = model.curved_continuous
    grids = [np.linspace(-1, 1, _REGION_GRID) if i in squared else model.grid(i) for i in range(len(model.factors))]
    if np.prod([len(g) for g in grids]) > _MAX_REGION_POINTS:
        grids = [model.grid(i) for i in range(len(model.factors))]
    points = np.array(list(itertools.product(*grids)))
    variance = _prediction_variance(model, inv, points)
    best = float(variance.max())
    for start in points[np.argsort(variance)[-5:]] if squared else ():
        best = max(best, _polish(model, inv, start, squared))
    return best


@dataclass(frozen=True)
class VarianceProfile:
    """The relative prediction variance along one factor, the others at their centre (first level)."""

    factor: str
    x: list[float]
    variance: list[float]
    labels: list[str]


def fraction_of_design_space(model: Model, settings: np.ndarray, points: int = 101) -> tuple[np.ndarray, np.ndarray]:
    """JMP's fraction of design space plot: the share of the region (x) whose relative prediction variance
    x'(X'X)^-1 x is at most y. The region is a grid (continuous factors at up to 11 evenly spaced values, fewer
    when there are many, levels as they are), so the curve is the same every time."""
    inv = np.linalg.inv(model.matrix(settings).T @ model.matrix(settings))
    counts = [len(model.grid(i)) for i, f in enumerate(model.factors) if not isinstance(f, ContinuousFactor)]
    continuous = [i for i, f in enumerate(model.factors) if isinstance(f, ContinuousFactor)]
    budget = _MAX_REGION_POINTS / 10 / max(1, int(np.prod(counts)))
    steps = max(3, min(11, int(budget ** (1 / max(1, len(continuous))))))
    grids = [np.linspace(-1, 1, steps) if i in continuous else model.grid(i) for i in range(len(model.factors))]
    variance = np.sort(_prediction_variance(model, inv, np.array(list(itertools.product(*grids)))))
    fractions = np.linspace(0.0, 1.0, points)
    return fractions, np.quantile(variance, fractions)


def variance_profiles(model: Model, settings: np.ndarray, points: int = 41) -> list[VarianceProfile]:
    """JMP's prediction variance profile: for each factor, the relative variance across its range."""
    inv = np.linalg.inv(model.matrix(settings).T @ model.matrix(settings))
    centre = np.zeros(len(model.factors))  # coded centre of numeric factors, first level of categorical ones
    profiles = []
    for i, factor in enumerate(model.factors):
        along = np.linspace(-1, 1, points) if isinstance(factor, ContinuousFactor) else model.grid(i)
        trial = np.repeat(centre[None], len(along), axis=0)
        trial[:, i] = along
        labels = list(factor.levels) if isinstance(factor, CategoricalFactor) else []
        x = along.tolist() if labels else [float(factor.decode(v)) for v in along]
        profiles.append(VarianceProfile(factor.name, x, _prediction_variance(model, inv, trial).tolist(), labels))
    return profiles


def _prediction_variance(model: Model, inv: np.ndarray, points: np.ndarray) -> np.ndarray:
    f = model.matrix(points)
    return np.einsum("ij,jk,ik->i", f, inv, f)


def _polish(model: Model, inv: np.ndarray, start: np.ndarray, continuous: list[int]) -> float:
    from scipy.optimize import minimize  # only models with squared continuous factors need it

    def negative(values: np.ndarray) -> float:
        point = start.copy()
        point[continuous] = values
        return -float(_prediction_variance(model, inv, point[None])[0])

    result = minimize(negative, start[continuous], method="L-BFGS-B", bounds=[(-1.0, 1.0)] * len(continuous))
    return -float(result.fun)


def _power(block: np.ndarray, beta: np.ndarray, alpha: float, error_df: int) -> float:
    """Power of the F test of H0: beta_L = 0 when beta_L is `beta` (sigma = 1); `block` is (X'X)^-1 on L."""
    r = len(block)
    noncentrality = float(beta @ np.linalg.solve(block, beta))
    critical = fdtri(r, error_df, 1.0 - alpha)
    return float(1.0 - ncfdtr(r, error_df, noncentrality, critical))


def _correlations(columns: np.ndarray) -> np.ndarray:
    """Pearson correlations between model columns; NaN where a column is constant."""
    centred = columns - columns.mean(axis=0)
    norms = np.sqrt((centred**2).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = (centred.T @ centred) / np.outer(norms, norms)
    corr[~np.isfinite(corr)] = np.nan
    return corr
