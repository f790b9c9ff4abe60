"""Design diagnostics with JMP's conventions (coded factors, sigma = 1).

With X the n x p model matrix and V = (X'X)^-1:
- D-efficiency  100 det(X'X / n)^(1/p)
- A-efficiency  100 p / (n trace V)
- G-efficiency  100 sqrt(p / n) / sigma_M, sigma_M^2 the largest x'Vx over the design region
- average prediction variance  trace(V M), M the moment matrix of the region
- power of each term's F test at level alpha when each of its coefficients is `snr`

The design region is the box [-1, 1] for continuous factors, the levels of discrete and
categorical factors, all combinations equally likely.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.special import fdtri, ncfdtr

from designs.exchange import squared_continuous
from designs.model import Model

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


def diagnose(model: Model, settings: np.ndarray, *, alpha: float = 0.05, snr: float = 1.0) -> Diagnostics:
    """Diagnostics of the design with the given (n, k) factor settings."""
    x = model.matrix(settings)
    n, p = x.shape
    info = x.T @ x
    inv = np.linalg.inv(info)
    sign, log_det = np.linalg.slogdet(info)
    columns = model.columns
    max_var = max_prediction_variance(model, inv)
    error_df = max(n - p, 1)  # JMP sets the error df of a saturated design to 1
    term_power = [
        TermPower(model.term_name(t), s.stop - s.start, _power(inv[s, s], snr, alpha, error_df))
        for t, s in zip(model.terms, model.term_slices)
    ]
    parameter_power = {c: _power(inv[j : j + 1, j : j + 1], snr, alpha, error_df) for j, c in enumerate(columns)}
    return Diagnostics(
        n=n,
        p=p,
        det_xtx=float(sign * np.exp(log_det)),
        d_efficiency=100.0 * float(np.exp(log_det / p)) / n,
        a_efficiency=100.0 * p / (n * float(np.trace(inv))),
        g_efficiency=100.0 * float(np.sqrt(p / n / max_var)),
        average_prediction_variance=float(np.trace(inv @ moment_matrix(model))),
        max_prediction_variance=max_var,
        standard_errors=dict(zip(columns, np.sqrt(np.diag(inv)).tolist())),
        correlation_columns=columns[1:],
        correlations=_correlations(x[:, 1:]),
        alpha=alpha,
        snr=snr,
        error_df=error_df,
        term_power=term_power,
        parameter_power=parameter_power,
    )


def moment_matrix(model: Model) -> np.ndarray:
    """(p, p) the mean of f(x) f(x)' over the design region, exact by product quadrature."""
    nodes, weights = zip(*(factor.quadrature for factor in model.factors))
    points = np.array(list(itertools.product(*nodes)))
    w = np.prod(np.array(list(itertools.product(*weights))), axis=1)
    f = model.matrix(points)
    return f.T @ (w[:, None] * f)


def max_prediction_variance(model: Model, inv: np.ndarray) -> float:
    """The largest relative prediction variance x'(X'X)^-1 x over the design region.

    The variance is convex in any coordinate that enters the model linearly, so the candidate
    grid holds its maximum unless a continuous factor is squared; then a grid of 21 values per
    such factor is searched and its best points are polished with L-BFGS-B.
    """
    squared = squared_continuous(model)
    grids = [np.linspace(-1, 1, _REGION_GRID) if i in squared else f.candidate_settings for i, f in enumerate(model.factors)]
    if np.prod([len(g) for g in grids]) > _MAX_REGION_POINTS:
        grids = [f.candidate_settings for f in model.factors]
    points = np.array(list(itertools.product(*grids)))
    variance = _prediction_variance(model, inv, points)
    best = float(variance.max())
    for start in points[np.argsort(variance)[-5:]] if squared else ():
        best = max(best, _polish(model, inv, start, squared))
    return best


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


def _power(block: np.ndarray, snr: float, alpha: float, error_df: int) -> float:
    """Power of the F test of H0: beta_L = 0 when every beta_L equals snr (sigma = 1)."""
    r = len(block)
    beta = np.full(r, snr)
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
