"""Exact n-run D-optimal designs by exchange from many seeded random starts.

Each start draws n candidate points at random (with replacement) and repeatedly makes the
single row-for-candidate swap that raises det(X'X) most, using Fedorov's delta

    det(M') / det(M) = (1 + d(x_new)) (1 - d(x_old)) + d(x_old, x_new)^2,
    d(u, v) = u' M^-1 v,

until no swap helps. Candidates may repeat and balance is never imposed, so optima that
replicate points are reachable.

Continuous factors: when every term is linear in each continuous factor, the delta of moving
one coordinate is convex in it, so some optimum has every continuous coordinate at -1 or +1
and the candidate grid suffices. When a continuous factor is squared, the optimum may lie
off the grid (Box & Draper's 6-run quadratic design is one), so those starts draw continuous
coordinates uniformly and alternate three steps: a coordinate exchange over the whole range
(each move maximises the delta exactly: it is a quartic in the coordinate), a joint polish of
all those coordinates by L-BFGS-B on log det(X'X), and the candidate exchange.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError
from designs.factors import ContinuousFactor
from designs.model import Model

#: A swap must raise det(X'X) by this relative margin to count, so loops always end.
_MIN_GAIN = 1e-9
#: Coordinate jumps are taken while they gain this much; the joint polish does the fine work.
_COORDINATE_GAIN = 1e-4
#: Two log-determinants this close are the same optimum.
LOG_DET_TOL = 1e-7
#: Coordinate values at which the quartic delta is sampled, and the fine grid it is maximised on.
_PROBES = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
_PROBE_INVERSE = np.linalg.inv(np.vander(_PROBES, 5, increasing=True))
_FINE = np.linspace(-1.0, 1.0, 401)
_FINE_POWERS = np.vander(_FINE, 5, increasing=True).T
#: Largest candidate set enumerated (the product of the factors' candidate settings).
MAX_CANDIDATES = 200_000


@dataclass(frozen=True)
class ExactDesign:
    """The best design over all starts, with how the starts fared.

    Attributes:
        settings: (n, k) factor settings of the runs (coded values / level indices).
        log_det: log det(X'X) of the design.
        start_log_dets: log det(X'X) each start ended at, in start order.
        seed: the master seed; start s uses SeedSequence(seed).spawn(starts)[s].
    """

    settings: np.ndarray
    log_det: float
    start_log_dets: np.ndarray
    seed: int

    @property
    def starts(self) -> int:
        return len(self.start_log_dets)

    @property
    def hits(self) -> int:
        """How many starts reached the best value found."""
        return int(np.sum(self.start_log_dets >= self.log_det - LOG_DET_TOL))


def candidate_set(model: Model) -> np.ndarray:
    """(N, k) every combination of the factors' candidate settings (continuous: -1, 0, 1)."""
    grids = [factor.candidate_settings for factor in model.factors]
    size = int(np.prod([len(grid) for grid in grids]))
    if size > MAX_CANDIDATES:
        raise DesignError(f"the candidate set would have {size} points (limit {MAX_CANDIDATES}); use fewer factors or levels")
    return np.array(list(itertools.product(*grids)), dtype=float)


def check_runs(model: Model, runs: int) -> None:
    """Raise DesignError when `runs` cannot estimate the model's p parameters."""
    if runs < model.p:
        raise DesignError(f"runs = {runs} is too few: the model has p = {model.p} parameters, so it needs at least {model.p} runs")


def d_optimal(model: Model, runs: int, *, seed: int, starts: int = 100) -> ExactDesign:
    """The exact D-optimal `runs`-run design for `model`, best of `starts` seeded starts."""
    check_runs(model, runs)
    if starts < 1:
        raise DesignError(f"starts must be at least 1, got {starts}")
    candidates = candidate_set(model)
    rows = model.matrix(candidates)
    squared = squared_continuous(model)
    best_settings, best = None, -np.inf
    ends = np.empty(starts)
    for s, child in enumerate(np.random.SeedSequence(seed).spawn(starts)):
        rng = np.random.default_rng(child)
        settings = candidates[rng.integers(len(candidates), size=runs)]
        settings[:, squared] = rng.uniform(-1.0, 1.0, size=(runs, len(squared)))
        settings, log_det = _optimise(model, settings, candidates, rows, squared)
        ends[s] = log_det
        if log_det > best:
            best_settings, best = settings, log_det
    if not np.isfinite(best):
        raise DesignError(f"no {runs}-run design can estimate every term of the model (X'X stays singular)")
    return ExactDesign(best_settings, best, ends, seed)


def squared_continuous(model: Model) -> list[int]:
    """Indices of the continuous factors that some term squares."""
    squared = {i for term in model.terms for i, power in term.parts if power == 2}
    return [i for i, f in enumerate(model.factors) if isinstance(f, ContinuousFactor) and i in squared]


def _optimise(
    model: Model, settings: np.ndarray, candidates: np.ndarray, rows: np.ndarray, squared: list[int]
) -> tuple[np.ndarray, float]:
    """Alternate coordinate exchange and joint polish (squared continuous factors) with candidate exchange."""
    x = model.matrix(settings)
    while True:
        moved = bool(squared) and _coordinate_exchange(model, x, settings, squared, _COORDINATE_GAIN)
        swapped = _exchange(x, settings, candidates, rows)
        if not squared or (not (moved or swapped) and not _polish(model, x, settings, squared)):
            break
    sign, log_det = np.linalg.slogdet(x.T @ x)
    return settings, float(log_det) if sign > 0 else -np.inf


def _singular(info: np.ndarray) -> bool:
    sign, log_det = np.linalg.slogdet(info)
    return bool(sign <= 0 or log_det < -30.0)


def _inverse_information(x: np.ndarray) -> np.ndarray:
    """(X'X)^-1, with a small ridge while X'X is singular so that exchange can leave it."""
    info = x.T @ x
    if _singular(info):
        info = info + 1e-6 * max(1.0, np.trace(info) / len(info)) * np.eye(len(info))
    return np.linalg.inv(info)


def _exchange(x: np.ndarray, settings: np.ndarray, candidates: np.ndarray, rows: np.ndarray) -> bool:
    """Fedorov exchange in place: make the best row-for-candidate swap while one helps."""
    swapped = False
    for _ in range(50 * len(x)):
        inv = _inverse_information(x)
        xa = x @ inv
        d_old = (xa * x).sum(axis=1)
        d_new = ((rows @ inv) * rows).sum(axis=1)
        delta = np.outer(1.0 - d_old, 1.0 + d_new) + (xa @ rows.T) ** 2
        i, j = np.unravel_index(np.argmax(delta), delta.shape)
        if delta[i, j] <= 1.0 + _MIN_GAIN:
            break
        x[i], settings[i] = rows[j], candidates[j]
        swapped = True
    return swapped


def _coordinate_exchange(model: Model, x: np.ndarray, settings: np.ndarray, factors: list[int], min_gain: float) -> bool:
    """Make the best single-coordinate move anywhere in [-1, 1] while one raises det(X'X) by min_gain.

    Nothing moves while X'X is singular: the candidate exchange, free in every factor, repairs that.
    """
    moved = False
    for _ in range(50 * len(x)):
        if _singular(x.T @ x):
            break
        inv = np.linalg.inv(x.T @ x)
        best_gain, best_move = 1.0 + min_gain, None
        for f in factors:
            values, gains = _best_coordinate(model, x, settings, inv, f)
            i = int(np.argmax(gains))
            if gains[i] > best_gain:
                best_gain, best_move = gains[i], (i, f, values[i])
        if best_move is None:
            break
        i, f, value = best_move
        settings[i, f] = value
        x[i] = model.matrix(settings[i])[0]
        moved = True
    return moved


def _polish(model: Model, x: np.ndarray, settings: np.ndarray, factors: list[int]) -> bool:
    """Maximise log det(X'X) over all coordinates of `factors` at once (L-BFGS-B, in place).

    Returns whether det(X'X) rose by more than the exchange's minimum relative gain.

    Model rows are at most quadratic in a coordinate, so a central difference with any step
    is its exact derivative; the gradient of log det is 2 x_i' (X'X)^-1 dx_i/dt.
    """
    from scipy.optimize import minimize  # only models with squared continuous factors need it

    n = len(settings)

    def trial(values: np.ndarray) -> np.ndarray:
        out = settings.copy()
        out[:, factors] = values.reshape(n, len(factors))
        return out

    def objective(values: np.ndarray) -> tuple[float, np.ndarray]:
        points = trial(values)
        rows = model.matrix(points)
        sign, log_det = np.linalg.slogdet(rows.T @ rows)
        if sign <= 0:
            return 1e6, np.zeros_like(values)
        weighted = rows @ np.linalg.inv(rows.T @ rows)
        gradient = np.empty((n, len(factors)))
        for j, f in enumerate(factors):
            up, down = points.copy(), points.copy()
            up[:, f] += 1.0
            down[:, f] -= 1.0
            gradient[:, j] = ((model.matrix(up) - model.matrix(down)) * weighted).sum(axis=1)
        return -log_det, -gradient.ravel()

    start = settings[:, factors].ravel()
    before, _ = objective(start)
    result = minimize(objective, start, jac=True, method="L-BFGS-B", bounds=[(-1.0, 1.0)] * len(start))
    if result.fun >= before:
        return False
    settings[:, factors] = result.x.reshape(n, len(factors))
    x[:] = model.matrix(settings)
    return bool(before - result.fun > _MIN_GAIN)


def _best_coordinate(model: Model, x: np.ndarray, settings: np.ndarray, inv: np.ndarray, f: int) -> tuple[np.ndarray, np.ndarray]:
    """For every row, the value of coordinate f that maximises Fedorov's delta, and that delta.

    The delta is a quartic in the coordinate (model columns are at most quadratic in it), so
    five samples fix it exactly; it is maximised on a fine grid, then by Newton steps.
    """
    n, k = settings.shape
    trial = np.repeat(settings[:, None, :], len(_PROBES), axis=1)
    trial[:, :, f] = _PROBES
    cand = model.matrix(trial.reshape(-1, k)).reshape(n, len(_PROBES), -1)
    d_old = ((x @ inv) * x).sum(axis=1)
    xa = x @ inv
    d_new = np.einsum("igj,jk,igk->ig", cand, inv, cand)
    gains = (1.0 - d_old)[:, None] * (1.0 + d_new) + np.einsum("igj,ij->ig", cand, xa) ** 2
    quartic = gains @ _PROBE_INVERSE.T
    values = _FINE[np.argmax(quartic @ _FINE_POWERS, axis=1)]
    slope = quartic[:, 1:] * np.arange(1, 5)
    curvature = slope[:, 1:] * np.arange(1, 4)
    spacing = _FINE[1] - _FINE[0]
    for _ in range(3):
        first = (slope * np.vander(values, 4, increasing=True)).sum(axis=1)
        second = (curvature * np.vander(values, 3, increasing=True)).sum(axis=1)
        step = np.where(second < 0.0, -first / np.where(second < 0.0, second, -1.0), 0.0)
        values = np.clip(values + np.clip(step, -spacing, spacing), -1.0, 1.0)
    return values, (quartic * np.vander(values, 5, increasing=True)).sum(axis=1)
