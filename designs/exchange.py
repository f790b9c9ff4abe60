"""Exact optimal designs (criterion D, I or A) by coordinate exchange from many seeded random starts.

Each start draws its runs at random from the allowed candidate points (a continuous factor that
some term raises to a power starts anywhere in its range) and then, run by run, makes the best
change of one coordinate, or the best swap for a whole candidate point, while the criterion
improves (Meyer and Nachtsheim's coordinate exchange with Fedorov's row swaps). Candidates may
repeat and balance is never imposed, so optima that replicate points are reachable. The inner
loop is compiled (`designs/kernels.py`) and updates (X'X)^-1 by rank-one steps.

Criteria, as JMP names them:
- D: maximise det(X'X)
- I: minimise the average prediction variance over the region, trace(W (X'X)^-1), W its moment matrix
- A: minimise trace((X'X)^-1), the sum of the coefficients' variances
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from designs.constraints import Restrictions, factor_arrays
from designs.errors import DesignError
from designs.factors import CategoricalFactor, ContinuousFactor
from designs.model import Model

CRITERION_NAMES = {"D": "largest det(X'X)", "I": "smallest average prediction variance", "A": "smallest trace((X'X)^-1)"}
CRITERIA = tuple(CRITERION_NAMES)
#: Two criterion values this close (relative; absolute for log det) are the same optimum.
VALUE_TOL = 1e-7
#: Largest candidate set enumerated (the product of the factors' candidate settings).
MAX_CANDIDATES = 200_000
#: Whole candidate points are tried as row swaps while candidates x p stays below this; beyond it the
#: coordinate moves alone search (each swap costs p^2 per candidate).
_SWAP_BUDGET = 4_000
_MAX_PASSES = 500
#: Chebyshev-Lobatto probes of a continuous coordinate: 7 fix a polynomial of degree 6 exactly.
_PROBES = np.cos(np.pi * np.arange(7) / 6)[::-1].copy()
_PROBE_INVERSE = np.linalg.inv(np.vander(_PROBES, 7, increasing=True))


@dataclass(frozen=True)
class ExactDesign:
    """The best design over all starts, with how the starts fared.

    Attributes:
        settings: (n, k) factor settings of the runs (coded values / level indices).
        criterion: D, I or A.
        value: the criterion of the best design: log det(X'X) (D), the average prediction
            variance (I) or trace((X'X)^-1) (A).
        start_values: the criterion each start ended at, in start order (inf or -inf: singular).
        seed: the master seed; start s uses SeedSequence(seed).spawn(starts)[s].
    """

    settings: np.ndarray
    criterion: str
    value: float
    start_values: np.ndarray
    seed: int

    @property
    def starts(self) -> int:
        return len(self.start_values)

    @property
    def hits(self) -> int:
        """How many starts reached the best value found."""
        if self.criterion == "D":
            return int(np.sum(self.start_values >= self.value - VALUE_TOL))
        return int(np.sum(self.start_values <= self.value * (1.0 + VALUE_TOL)))


def candidate_set(model: Model, restrictions: Restrictions | None = None) -> np.ndarray:
    """(N, k) every allowed combination of the factors' candidate settings (continuous: -1, 0, 1)."""
    grids = [model.grid(i) for i in range(len(model.factors))]
    size = int(np.prod([len(grid) for grid in grids]))
    if size > MAX_CANDIDATES:
        raise DesignError(f"the candidate set would have {size} points (limit {MAX_CANDIDATES}); use fewer factors or levels")
    points = np.array(list(itertools.product(*grids)), dtype=float)
    if restrictions:
        points = points[restrictions.allowed(points, model.factors)]
        if not len(points):
            raise DesignError("the disallowed combinations and constraints leave no candidate point")
    return points


def check_runs(model: Model, runs: int) -> None:
    """Raise DesignError when `runs` cannot estimate the model's p parameters."""
    if runs < model.p:
        raise DesignError(f"runs = {runs} is too few: the model has p = {model.p} parameters, so it needs at least {model.p} runs")


def criterion_weight(model: Model, criterion: str) -> np.ndarray:
    """W of trace(W (X'X)^-1): the region's moment matrix (I), the identity (A), unused for D."""
    if criterion not in CRITERIA:
        raise DesignError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    if criterion == "I":
        return model.moment_matrix()
    return np.eye(model.p)


def criterion_value(x: np.ndarray, criterion: str, weight: np.ndarray) -> float:
    """The criterion of model matrix x: log det(X'X) for D (-inf when singular), else trace(W (X'X)^-1) (inf)."""
    info = x.T @ x
    sign, log_det = np.linalg.slogdet(info)
    if sign <= 0 or log_det < -30.0:
        return -np.inf if criterion == "D" else np.inf
    if criterion == "D":
        return float(log_det)
    return float(np.sum(weight * np.linalg.inv(info)))


def optimal_design(model: Model, runs: int, *, seed: int, starts: int = 100, criterion: str = "D",
                   restrictions: Restrictions | None = None, kept: np.ndarray | None = None,
                   per_run: dict[int, np.ndarray] | None = None,
                   progress: Callable[[int, int], None] | None = None) -> ExactDesign:
    """The best `runs`-run design for `model` under `criterion`, best of `starts` seeded starts.

    `kept` (m, k) are runs already made (augmenting a study): they open the design unchanged and
    `runs` - m new runs are searched around them. `per_run` maps a factor the runs fix (block,
    covariate) to its setting in each of the `runs` runs. `progress(done, starts)` is called after each start.
    """
    from designs import kernels  # numba loads only when a design is searched

    check_runs(model, runs)
    kept = np.zeros((0, len(model.factors))) if kept is None else np.asarray(kept, dtype=float)
    if starts < 1:
        raise DesignError(f"starts must be at least 1, got {starts}")
    weight = criterion_weight(model, criterion)
    candidates = candidate_set(model, restrictions)
    curved = model.curved_continuous
    per_run = per_run or {}
    frozen = np.array([i in per_run for i in range(len(model.factors))])
    # A continuous factor entering only linearly has its D-optimum at -1 or +1 (the delta is convex in it),
    # so the grid suffices there; under I or A, or with restrictions, it too moves anywhere in its range.
    free = criterion != "D" or bool(restrictions)
    continuous = np.array([i in curved or (free and isinstance(f, ContinuousFactor)) for i, f in enumerate(model.factors)])
    grids = [model.grid(i) for i in range(len(model.factors))]
    values = np.zeros((len(grids), max(len(g) for g in grids)))
    for i, grid in enumerate(grids):
        values[i, : len(grid)] = grid
    value_count = np.array([len(g) for g in grids], dtype=np.int64)
    levels = np.array([len(f.levels) if isinstance(f, CategoricalFactor) else 0 for f in model.factors], dtype=np.int64)
    centre, half, kinds = factor_arrays(model.factors)
    col_factor, col_code = model.column_codes()
    ops, args, bounds = ((restrictions.ops, restrictions.args, restrictions.bounds) if restrictions
                         else (np.zeros(0, np.int64), np.zeros(0), np.zeros(1, np.int64)))
    swaps = candidates if len(candidates) * model.p <= _SWAP_BUDGET else np.zeros((0, len(model.factors)))
    best_settings, best = None, None
    ends = np.empty(starts)
    for s, child in enumerate(np.random.SeedSequence(seed).spawn(starts)):
        fresh = _random_start(np.random.default_rng(child), candidates, runs - len(kept), curved, restrictions, model)
        settings = np.vstack([kept, fresh])
        for i, column in per_run.items():
            settings[len(kept):, i] = column[len(kept):]
        kernels.optimise_start(settings, kinds, levels, col_factor, col_code, centre, half, values, value_count,
                               continuous, frozen, weight, criterion != "D", ops, args, bounds, swaps, _PROBES, _PROBE_INVERSE,
                               _MAX_PASSES, len(kept))
        ends[s] = criterion_value(model.matrix(settings), criterion, weight)
        if restrictions and not restrictions.allowed(settings, model.factors).all():
            ends[s] = -np.inf if criterion == "D" else np.inf  # a run's block or covariate left it nowhere allowed
        if best is None or _better(ends[s], best, criterion):
            best_settings, best = settings, ends[s]
        if progress is not None:
            progress(s + 1, starts)
    assert best is not None and best_settings is not None
    if not np.isfinite(best):
        why = " or no allowed setting fits some run's block or covariate" if restrictions else ""
        raise DesignError(f"no {runs}-run design can estimate every term of the model (X'X stays singular{why})")
    return ExactDesign(best_settings, criterion, float(best), ends, seed)


def _better(value: float, best: float, criterion: str) -> bool:
    return value > best if criterion == "D" else value < best


def _random_start(rng: np.random.Generator, candidates: np.ndarray, runs: int, curved: list[int],
                  restrictions: Restrictions | None, model: Model) -> np.ndarray:
    """Runs drawn from the allowed candidates; curved continuous coordinates then drawn uniformly where allowed."""
    settings = candidates[rng.integers(len(candidates), size=runs)]
    if curved:
        moved = settings.copy()
        moved[:, curved] = rng.uniform(-1.0, 1.0, size=(runs, len(curved)))
        keep = restrictions.allowed(moved, model.factors) if restrictions else np.ones(runs, dtype=bool)
        settings[keep] = moved[keep]
    return settings
