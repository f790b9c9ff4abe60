"""Exact optimal designs (criterion D, I or A) by coordinate exchange from many seeded random starts.

Each start draws its runs at random from the allowed candidate points (a continuous factor that
some term raises to a power starts anywhere in its range) and then, run by run, makes the best
change of one coordinate, or the best swap for a whole candidate point, while the criterion
improves (Meyer and Nachtsheim's coordinate exchange with Fedorov's row swaps). Candidates may
repeat and balance is never imposed, so optima that replicate points are reachable. The inner
loop is compiled (`designs/kernels.py`) and updates (X'X)^-1 by rank-one steps. A small D-optimal design whose
factors all stay on their grids opens by Fedorov's row exchange in numpy instead (`designs/row_exchange.py`): its
search takes less time than loading the compiled kernels.

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
from designs.exchange_numerics import MAX_PASSES
from designs.factors import CategoricalFactor, ContinuousFactor
from designs.model import Model
from designs.row_exchange import WORK_LIMIT, RowExchange, pass_work

CRITERION_NAMES = {"D": "largest det(X'X)", "I": "smallest average prediction variance", "A": "smallest trace((X'X)^-1)"}
CRITERIA = tuple(CRITERION_NAMES)
#: Two criterion values this close (relative; for D absolute on log det, so relative on det) are the same optimum:
#: symmetric designs agree to about 1e-12, distinct local optima differ by 1e-3 or more.
VALUE_TOL = 1e-6
#: Largest candidate set enumerated (the product of the factors' candidate settings).
MAX_CANDIDATES = 200_000
#: Whole candidate points are tried as row swaps while candidates x p stays below this; beyond it the
#: coordinate moves alone search (each swap costs p^2 per candidate).
_SWAP_BUDGET = 4_000
#: Iterated local search when the starts disagree: the work of a start's kicks (runs x factors x p^2 a kick),
#: the most kicks a start makes, and the runs each kick moves to random candidate points.
KICK_WORK = 28_500_000
MAX_KICKS = 150
KICK_RUNS = 3
#: A search restarts from a fresh opening after PATIENCE kicks in a row without gain; the opening (random runs and
#: the grid exchange) is charged as RESTART_KICKS kicks, about its cost (6 factors, 40 runs: 0.46 ms against 0.32 ms
#: a kick); a start stops once AGREED of its searches tie for the best.
PATIENCE = 20
RESTART_KICKS = 2
AGREED = 3
#: The starts are searched again in batches of this many, in start order; once AGREED of those searched tie for the best,
#: the rest are not (a best design that several starts reach is the one more searching would keep finding). The batches
#: are the same on any number of threads, so the design is too.
AGREE_BATCH = 8
#: A kick under I or A costs about 7.5 times one under D (2.4 against 0.32 ms at 6 factors, 40 runs): their trials
#: form (X'X)^-1 y and W (X'X)^-1 y, where D's need only the moved columns. It counts 4 times, not 7.5: that kept
#: their search times at the previous search's (6 factors, 40 runs, 100 starts: I 27.7 s and A 20.0 s of CPU against
#: 29.2 and 19.4 s) with 37 kicks a start there, where the full cost would leave 20.
TRACE_KICK_COST = 4
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
        kicks: the iterated local search's kick budget per start, restarts charged (0: the starts agreed without it).
        searched: how many starts, the first in start order, were searched again with kicks (`AGREE_BATCH`).
        row_exchange: whether the starts opened by the numpy row exchange (`designs/row_exchange.py`) rather than the
            compiled coordinate exchange.
    """

    settings: np.ndarray
    criterion: str
    value: float
    start_values: np.ndarray
    seed: int
    kicks: int = 0
    searched: int = 0
    row_exchange: bool = False

    @property
    def starts(self) -> int:
        return len(self.start_values)

    @property
    def hits(self) -> int:
        """How many starts reached the best value found (within VALUE_TOL)."""
        return int(np.sum(_same(self.start_values, self.value, self.criterion)))


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
                   progress: Callable[[int, int], None] | None = None, threads: int = 1) -> ExactDesign:
    """The best `runs`-run design for `model` under `criterion`, best of `starts` seeded starts.

    Each start runs the coordinate exchange from its random runs (curved continuous coordinates drawn
    anywhere in their range), or, where `_Search.row_exchange` says it suits, the numpy row exchange of all starts at
    once. When the starts end at different values, the starts search again, in batches of
    `AGREE_BATCH` in start order until `AGREED` of those searched tie for the best, each from its end snapped to the
    grid: the exchange on the grid and kicks of iterated local search, restarted from fresh openings of its own while
    its kick budget (`_Search.kicks`) lasts (`_Search.restarts`), then the exchange with continuous moves from each
    grid design tied for its best; it keeps the best of its ends.

    `kept` (m, k) are runs already made (augmenting a study): they open the design unchanged and
    `runs` - m new runs are searched around them. `per_run` maps a factor the runs fix (block,
    covariate) to its setting in each of the `runs` runs. `progress(done, starts)` is called after each start of
    each round. The starts search on `threads` threads; each has its own generator and arrays, so the design does not
    depend on how many.
    """
    check_runs(model, runs)
    kept = np.zeros((0, len(model.factors))) if kept is None else np.asarray(kept, dtype=float)
    if starts < 1:
        raise DesignError(f"starts must be at least 1, got {starts}")
    search = _Search.of(model, criterion, restrictions, per_run or {}, len(kept))
    rngs = [np.random.default_rng(child) for child in np.random.SeedSequence(seed).spawn(starts)]
    designs = [search.spread(rng, search.opening(rng, kept, runs, per_run or {})) for rng in rngs]
    ends = np.empty(starts)

    def open_start(s: int) -> None:
        search.exchange(designs[s], search.continuous)
        ends[s] = search.value(designs[s])

    def search_again(s: int) -> None:
        tied = search.restarts(search.snap(designs[s]), rngs[s], kept, runs, per_run or {}, kicks)
        # Under I and A every continuous factor moves, and a continuous exchange costs far more than under D (46 ms at
        # 4 factors and 20 runs, against 6 ms under D at 6 factors and 40 runs): one tied design is polished there.
        for settings in tied if criterion == "D" else tied[:1]:
            if search.continuous.any():
                search.exchange(settings, search.continuous)
            value = search.value(settings)
            if _better(value, ends[s], criterion):
                designs[s], ends[s] = settings, value

    rows = search.row_exchange(starts, runs)
    if rows is None:
        _each_start(open_start, range(starts), starts, threads, progress)
    else:
        opened = np.stack(designs)
        rows.exchange(opened)
        designs = list(opened)
        ends[:] = [search.value(settings) for settings in designs]
        if progress is not None:
            progress(starts, starts)
    kicks = search.kicks(runs) if starts > 1 and not np.all(_same(ends, _best(ends, criterion), criterion)) else 0
    searched = 0
    while searched < (starts if kicks else 0):
        batch = range(searched, min(searched + AGREE_BATCH, starts))
        _each_start(search_again, batch, starts, threads, progress)
        searched = batch.stop
        if _same(ends[:searched], _best(ends[:searched], criterion), criterion).sum() >= AGREED:
            break
    best = _best(ends, criterion)
    if not np.isfinite(best):
        why = " or no allowed setting fits some run's block or covariate" if restrictions else ""
        raise DesignError(f"no {runs}-run design can estimate every term of the model (X'X stays singular{why})")
    best_settings = designs[int(np.flatnonzero(ends == best)[0])]
    return ExactDesign(best_settings, criterion, float(best), ends, seed, kicks, searched, rows is not None)


@dataclass
class _Search:
    """The compiled kernels' view of one search: the model's codes, the grid, the restrictions' programs."""

    model: Model
    criterion: str
    restrictions: Restrictions | None
    first_free: int
    continuous: np.ndarray
    frozen: np.ndarray
    candidates: np.ndarray
    swaps: np.ndarray
    codes: tuple

    @classmethod
    def of(cls, model: Model, criterion: str, restrictions: Restrictions | None, per_run: dict[int, np.ndarray],
           first_free: int) -> _Search:
        weight = criterion_weight(model, criterion)
        candidates = candidate_set(model, restrictions)
        curved = model.curved_continuous
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
        codes = (kinds, levels, col_factor, col_code, centre, half, values, value_count)
        return cls(model, criterion, restrictions, first_free, continuous, frozen, candidates, swaps,
                   (codes, weight, criterion != "D", ops, args, bounds))

    def opening(self, rng: np.random.Generator, kept: np.ndarray, runs: int, per_run: dict[int, np.ndarray]) -> np.ndarray:
        """A start's runs: the kept ones, then random allowed candidates with the runs' fixed settings."""
        fresh = self.candidates[rng.integers(len(self.candidates), size=runs - len(kept))]
        settings = np.vstack([kept, fresh])
        for i, column in per_run.items():
            settings[len(kept):, i] = column[len(kept):]
        return settings

    def spread(self, rng: np.random.Generator, opening: np.ndarray) -> np.ndarray:
        """A copy of `opening` whose free runs have their curved continuous coordinates drawn uniformly where allowed:
        such a factor's optimum may lie off the grid, where the exchange from grid points would not go."""
        settings = opening.copy()
        curved = [i for i in self.model.curved_continuous if not self.frozen[i]]
        if curved:
            free = settings[self.first_free:]
            moved = free.copy()
            moved[:, curved] = rng.uniform(-1.0, 1.0, size=(len(free), len(curved)))
            keep = self.restrictions.allowed(moved, self.model.factors) if self.restrictions else np.ones(len(free), dtype=bool)
            free[keep] = moved[keep]
        return settings

    def snap(self, settings: np.ndarray) -> np.ndarray:
        """A copy whose free runs have each coordinate moved to the nearest of its factor's grid settings (frozen
        factors, and a run whose nearest grid point is not allowed, stay as they are)."""
        values, count = self.codes[0][6], self.codes[0][7]
        snapped = settings.copy()
        free = snapped[self.first_free:]
        for f in np.flatnonzero(~self.frozen):
            grid = values[f, : count[f]]
            free[:, f] = grid[np.argmin(np.abs(free[:, f, None] - grid[None, :]), axis=1)]
        if self.restrictions:
            refused = ~self.restrictions.allowed(free, self.model.factors)
            free[refused] = settings[self.first_free:][refused]
        return snapped

    def exchange(self, settings: np.ndarray, continuous: np.ndarray) -> None:
        """Coordinate exchange in place; `continuous` says which factors move anywhere in their range."""
        from designs import kernels  # numba loads only when a design is searched

        codes, weight, trace, ops, args, bounds = self.codes
        kernels.optimise_start(settings, *codes, continuous, self.frozen, weight, trace, ops, args, bounds, self.swaps,
                               _PROBES, _PROBE_INVERSE, MAX_PASSES, self.first_free)

    def row_exchange(self, starts: int, runs: int) -> RowExchange | None:
        """The numpy row exchange of all starts at once, where it suits: D, every factor on its grid, and a pass small
        enough (`row_exchange.WORK_LIMIT`) that the search takes less than loading the compiled kernels."""
        if self.criterion != "D" or self.continuous.any():
            return None
        if pass_work(self.model, self.frozen, starts, runs - self.first_free) > WORK_LIMIT:
            return None
        return RowExchange(self.model, candidate_set(self.model), self.restrictions, self.frozen, self.first_free)

    def kicks(self, runs: int) -> int:
        """Kicks per start: as many as `KICK_WORK` allows (each re-runs the exchange, about runs x factors x p^2
        a pass, `TRACE_KICK_COST` times that under I or A), at most `MAX_KICKS`."""
        work = runs * len(self.model.factors) * self.model.p ** 2 * (TRACE_KICK_COST if self.criterion != "D" else 1)
        return min(MAX_KICKS, KICK_WORK // work)

    def restarts(self, settings: np.ndarray, rng: np.random.Generator, kept: np.ndarray, runs: int,
                 per_run: dict[int, np.ndarray], kicks: int) -> list[np.ndarray]:
        """The grid designs that tie for the best among iterated local searches from `settings` and then from fresh
        openings, while the start's `kicks` last.

        A search stops once `PATIENCE` kicks in a row have not raised the criterion: held in an optimum that moving
        a few runs cannot leave, it gains little from more kicks, and a fresh opening (random allowed candidates and
        the grid exchange, charged as `RESTART_KICKS` kicks) may lead to a better one. The start stops early once
        `AGREED` of its searches tie for the best. All tied designs are returned, since the continuous exchange can end
        the same grid design, in another orientation, at a slightly different optimum.
        """
        grid_only = np.zeros_like(self.continuous)
        ends: list[np.ndarray] = []
        values: list[float] = []
        fresh, left = settings, kicks
        while True:
            self.exchange(fresh, grid_only)
            left -= self.iterate(fresh, rng, runs, left)
            ends.append(fresh)
            values.append(self.value(fresh))
            tied = _same(np.array(values), _best(np.array(values), self.criterion), self.criterion)
            if tied.sum() >= AGREED or left < RESTART_KICKS + PATIENCE:
                return [end for end, same in zip(ends, tied) if same]
            left -= RESTART_KICKS
            fresh = self.opening(rng, kept, runs, per_run)

    def iterate(self, settings: np.ndarray, rng: np.random.Generator, runs: int, kicks: int) -> int:
        """At most `kicks` kicks of iterated local search on the grid, in place, each moving `KICK_RUNS` free runs;
        returns the kicks made (fewer once `PATIENCE` kicks in a row have not raised the criterion)."""
        from designs import kernels

        free = runs - self.first_free
        moved = min(KICK_RUNS, free)
        rows = self.first_free + np.argsort(rng.random((kicks, free)), axis=1)[:, :moved]
        points = rng.integers(len(self.candidates), size=(kicks, moved))
        codes, weight, trace, ops, args, bounds = self.codes
        return kernels.iterate_start(settings, *codes, self.frozen, weight, trace, ops, args, bounds, _PROBES, _PROBE_INVERSE,
                                     MAX_PASSES, self.first_free, self.candidates, rows, points, PATIENCE)

    def value(self, settings: np.ndarray) -> float:
        """The criterion of a searched design (inf or -inf: singular, or a run left nowhere allowed)."""
        weight = self.codes[1]
        if self.restrictions and not self.restrictions.allowed(settings, self.model.factors).all():
            return -np.inf if self.criterion == "D" else np.inf  # a run's block or covariate left it nowhere allowed
        return criterion_value(self.model.matrix(settings), self.criterion, weight)


def _each_start(work: Callable[[int], None], starts: range, total: int, threads: int,
                progress: Callable[[int, int], None] | None) -> None:
    """`work(s)` for every start s of `starts` (of `total`), on `threads` threads (the kernels release the GIL);
    `progress(done, total)` as each ends, counting on from the range's first start. An error or Ctrl-C cancels the
    starts not yet begun and waits for those running."""
    if threads <= 1:
        for s in starts:
            work(s)
            if progress is not None:
                progress(s + 1, total)
        return
    from concurrent.futures import ThreadPoolExecutor, as_completed

    pool = ThreadPoolExecutor(max_workers=min(threads, len(starts)), thread_name_prefix="design-start")
    try:
        for done, future in enumerate(as_completed([pool.submit(work, s) for s in starts]), start=starts.start + 1):
            future.result()
            if progress is not None:
                progress(done, total)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _best(values: np.ndarray, criterion: str) -> float:
    return float(np.max(values) if criterion == "D" else np.min(values))


def _same(values: np.ndarray, best: float, criterion: str) -> np.ndarray:
    """Which values reach `best` within VALUE_TOL (relative; for D's log det, absolute)."""
    if criterion == "D":
        return values >= best - VALUE_TOL
    return values <= best * (1.0 + VALUE_TOL)


def _better(value: float, best: float, criterion: str) -> bool:
    """Whether `value` beats `best`: larger log det for D, smaller trace for I and A."""
    return value > best if criterion == "D" else value < best
