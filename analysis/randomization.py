"""The run-level randomization test of two arms: each run's share of yes compared between the arms, with the
arm labels re-drawn as the design allocates them (the same number of runs per arm within each stratum).

Under the sharp null hypothesis that the arm changes no run's share, every allocation the design could
have made was equally likely and gives the same shares, so the p-value is the share of allocations
whose statistic is at least as far from zero as the observed one (Fisher's randomization test; Rosenbaum,
Observational Studies, 2002, ch. 2). The statistic is the stratified difference of mean run shares, first
arm minus second: within each stratum the difference of the arms' means, weighted by n1 n2 / n (strata
holding one arm carry no weight). It needs no model, so an all-yes arm or separated judgments leave it intact.

The reference set is enumerated completely when it holds at most `max_allocations` allocations; otherwise
`draws` allocations are drawn at random from a recorded seed and p = (1 + hits) / (1 + draws), with its
Monte Carlo standard error.

The interval is for the average difference over the study's runs (the estimand: the stratified difference of mean run
shares the arms would give if every run were driven by each). It inverts the studentized randomization test (the
difference over its Neyman standard error, sum of w^2 (s1^2 / n1 + s2^2 / n2) over strata): a difference d is kept
when the test, on the shares with d taken off the first arm's runs, does not reject. Studentized, the test is exact
for a constant effect and keeps its level for the average effect when runs differ in their effect (Wu and Ding,
JASA 2021), so the interval needs no model of how the arm moves each run's share, which a bounded share could not
follow. It needs two runs of each arm in each stratum compared. The p-value above tests that the arm changes no run's
share; the interval's own test at 0 (`p_studentized`) can fall on the other side of alpha when p is near it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from analysis.errors import AnalysisError

#: Complete enumeration up to this many allocations (C(18, 9) = 48,620 and C(20, 10) = 184,756 are inside; the
#: matrix of allocations holds 8 bytes per run and allocation).
MAX_ALLOCATIONS = 200_000
#: Monte Carlo draws when the allocations are too many to enumerate.
DRAWS = 20_000
#: Allocations multiplied at once, which bounds the temporaries of one product.
_CHUNK = 100_000
#: Statistics closer than this count as equal (sums of the same shares in another order).
_TIE = 1e-9
#: Studentized statistics within this fraction of the observed one count as equal: far above the rounding of the sums,
#: far below any real difference, so an interval end lies within about this much of the exact one.
_RELATIVE_TIE = 1e-12


@dataclass(frozen=True)
class RandomizationTest:
    """A randomization test's result: the observed statistic, its two-sided p-value and how it was found."""

    runs: int
    strata: int
    #: Stratified difference of mean run shares, first arm minus second.
    difference: float
    p_value: float
    #: How many allocations the design could have made (prod over strata of C(n, n1)).
    allocations: int
    exact: bool
    #: Monte Carlo draws and the p-value's Monte Carlo standard error (0 and 0.0 when exact).
    draws: int
    mc_error: float
    seed: int | None
    #: Interval for the average difference by inverting the studentized test, at `level` (NaN when not asked for, or when
    #: none can be formed), and that test's p-value at a difference of 0.
    low: float = math.nan
    high: float = math.nan
    level: float = math.nan
    #: Why no interval could be formed, in words ("" when one was, or none was asked for).
    no_interval: str = ""
    p_studentized: float = math.nan

    @property
    def agrees(self) -> bool:
        """Whether the interval excludes 0 exactly when the p-value is below 1 - level."""
        return math.isnan(self.low) or ((self.low > 0.0 or self.high < 0.0) == (self.p_value < 1.0 - self.level))

    def describe(self) -> str:
        """How the p-value was found, in one phrase."""
        if self.exact:
            return f"exact: all {self.allocations:,} allocations enumerated"
        return (f"Monte Carlo: {self.draws:,} of {self.allocations:,} allocations drawn (seed {self.seed}), "
                f"Monte Carlo standard error of p {self.mc_error:.4f}")


@dataclass(frozen=True)
class _Layout:
    """The allocation rule: each run's stratum index, and each stratum's run count and first-arm count."""

    stratum: np.ndarray
    sizes: tuple[int, ...]
    firsts: tuple[int, ...]

    @property
    def count(self) -> int:
        return math.prod(math.comb(n, k) for n, k in zip(self.sizes, self.firsts))

    def stratum_weights(self) -> np.ndarray:
        """Each stratum's weight n1 n2 / n, normalised to sum to 1 (0 for a stratum holding one arm only)."""
        n = np.array(self.sizes, dtype=float)
        k = np.array(self.firsts, dtype=float)
        w = np.where((k > 0) & (k < n), k * (n - k) / n, 0.0)
        if w.sum() == 0.0:
            raise AnalysisError("no stratum holds runs of both arms: the arms cannot be compared")
        return w / w.sum()

    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """Per run, the coefficient of its share when in the first arm and when in the second."""
        n = np.array(self.sizes, dtype=float)
        k = np.array(self.firsts, dtype=float)
        w = self.stratum_weights()
        first = np.divide(w, k, out=np.zeros_like(w), where=k > 0)
        second = np.divide(w, n - k, out=np.zeros_like(w), where=n > k)
        return first[self.stratum], second[self.stratum]


def _layout(first: np.ndarray, strata: np.ndarray | None) -> _Layout:
    labels = np.zeros(len(first), dtype=int) if strata is None else np.unique(strata, return_inverse=True)[1].reshape(-1)
    sizes = tuple(int(n) for n in np.bincount(labels))
    firsts = tuple(int(k) for k in np.bincount(labels, weights=first.astype(float), minlength=len(sizes)))
    return _Layout(labels, sizes, firsts)


@lru_cache(maxsize=2)
def _enumerated(stratum: tuple[int, ...], sizes: tuple[int, ...], firsts: tuple[int, ...]) -> np.ndarray:
    """Every allocation of the layout as rows of a (count, runs) matrix: 1 for the first arm, 0 for the second."""
    members = [np.flatnonzero(np.array(stratum) == s) for s in range(len(sizes))]
    parts = []
    for runs, k in zip(members, firsts):
        chosen = np.fromiter(itertools.chain.from_iterable(itertools.combinations(range(len(runs)), k)), dtype=np.int64,
                             count=math.comb(len(runs), k) * k).reshape(-1, k)
        rows = np.zeros((len(chosen), len(runs)), dtype=bool)
        np.put_along_axis(rows, chosen, True, axis=1)
        parts.append(rows)
    grid = np.stack(np.meshgrid(*[np.arange(len(p)) for p in parts], indexing="ij"), axis=-1).reshape(-1, len(parts))
    allocations = np.zeros((len(grid), len(stratum)), dtype=bool)
    for s, (runs, rows) in enumerate(zip(members, parts)):
        allocations[:, runs] = rows[grid[:, s]]
    as_numbers = allocations.astype(float)  # a float matrix multiplies by BLAS, many times faster than a boolean one
    as_numbers.flags.writeable = False
    return as_numbers


def _drawn(layout: _Layout, draws: int, rng: np.random.Generator) -> np.ndarray:
    """`draws` allocations at random: within each stratum, a random set of its runs of the stratum's first-arm count."""
    allocations = np.zeros((draws, len(layout.stratum)))
    for s, k in enumerate(layout.firsts):
        runs = np.flatnonzero(layout.stratum == s)
        ranks = np.argsort(rng.random((draws, len(runs))), axis=1)
        allocations[np.arange(draws)[:, None], runs[ranks[:, :k]]] = 1.0
    return allocations


def randomization_test(shares: np.ndarray, first: np.ndarray, strata: np.ndarray | None = None, *, level: float | None = 0.95,
                       max_allocations: int = MAX_ALLOCATIONS, draws: int = DRAWS, seed: int = 0) -> RandomizationTest:
    """The two-sided randomization test of the runs' `shares` between the arms (`first`: True for a run of the first arm),
    re-randomized within `strata` (one label per run; None: all runs one stratum); with `level`, the inverted interval.

    Raises:
        AnalysisError: shares outside [0, 1] or not finite, or no stratum with runs of both arms.
    """
    y = np.asarray(shares, dtype=float)
    z = np.asarray(first, dtype=bool)
    if y.shape != z.shape or y.ndim != 1 or (strata is not None and len(strata) != len(y)):
        raise AnalysisError(f"one share, one arm and one stratum per run expected, got {y.shape}, {z.shape}")
    if not np.all(np.isfinite(y)) or np.any((y < 0.0) | (y > 1.0)):
        raise AnalysisError("every run's share of yes must be a number in [0, 1]")
    layout = _layout(z, None if strata is None else np.asarray(strata))
    a, b = layout.weights()
    count = layout.count
    exact = count <= max_allocations
    allocations = (_enumerated(tuple(layout.stratum.tolist()), layout.sizes, layout.firsts) if exact
                   else _drawn(layout, draws, np.random.default_rng(seed)))

    def statistics(values: np.ndarray) -> np.ndarray:
        """The statistic of `values` under every allocation: sum of a*y over the first arm minus b*y over the second."""
        out = np.empty(len(allocations))
        for start in range(0, len(allocations), _CHUNK):
            chunk = allocations[start:start + _CHUNK]
            out[start:start + _CHUNK] = chunk @ ((a + b) * values) - float(b @ values)
        return out

    observed = float(np.where(z, a, 0.0) @ y - np.where(z, 0.0, b) @ y)
    under = statistics(y)
    hits = int(np.count_nonzero(np.abs(under) >= abs(observed) - _TIE))
    p = hits / len(allocations) if exact else (1 + hits) / (1 + len(allocations))
    mc_error = 0.0 if exact else math.sqrt(p * (1.0 - p) / draws)
    low = high = p_studentized = math.nan
    no_interval = ""
    if level is not None and np.ptp(y) == 0.0:
        # Every allocation gives the same statistic: the data say nothing about how far apart the arms could be.
        no_interval = f"every run's share of yes is {y[0]:.0%}, so no interval can be formed"
    elif level is not None:
        studentized = _Studentized(y, z, layout, allocations, exact)
        no_interval = studentized.cannot
        if not no_interval:
            p_studentized = studentized.p(0.0)
            low, high = (_edge(studentized.p, observed, 1.0 - level, side) for side in (-1.0, 1.0))
    return RandomizationTest(len(y), len(layout.sizes), observed, p, count, exact, 0 if exact else draws, mc_error,
                             None if exact else seed, low, high, math.nan if level is None else level, no_interval, p_studentized)


class _Studentized:
    """The studentized randomization test of an average difference d: the stratified difference over its Neyman
    standard error, on the shares with d taken off the first arm's runs, under every allocation of the reference set."""

    def __init__(self, y: np.ndarray, z: np.ndarray, layout: _Layout, allocations: np.ndarray, exact: bool) -> None:
        n, k = np.array(layout.sizes), np.array(layout.firsts)
        compared = (k > 0) & (k < n)
        self.cannot = ("a stratum holds fewer than two runs of an arm, so the interval's standard error cannot be estimated"
                       if np.any(compared & ((k < 2) | (n - k < 2))) else "")
        weights = layout.stratum_weights()
        self.strata = [(np.flatnonzero(layout.stratum == s), int(k[s]), int(n[s]), weights[s]) for s in range(len(n)) if compared[s]]
        self.y, self.z, self.allocations, self.exact = y, z.astype(float), allocations, exact
        if not self.cannot:
            self.observed = self._difference_and_error(y, z[np.newaxis, :].astype(float))

    def _difference_and_error(self, values: np.ndarray, allocations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The stratified difference and its Neyman standard error under each allocation (rows of 0/1)."""
        difference = np.zeros(len(allocations))
        variance = np.zeros(len(allocations))
        for runs, k, n, w in self.strata:
            v, chosen = values[runs], allocations[:, runs]
            first_sum, first_squares = chosen @ v, chosen @ (v * v)
            second_sum, second_squares = v.sum() - first_sum, float(v @ v) - first_squares
            first_mean, second_mean = first_sum / k, second_sum / (n - k)
            first_var = np.maximum(first_squares - k * first_mean**2, 0.0) / (k - 1)
            second_var = np.maximum(second_squares - (n - k) * second_mean**2, 0.0) / (n - k - 1)
            difference += w * (first_mean - second_mean)
            variance += w * w * (first_var / k + second_var / (n - k))
        return difference, np.sqrt(variance)

    def p(self, shift: float) -> float:
        """The p-value of an average difference of `shift`."""
        statistic = _ratio(*self._difference_and_error(self.y - shift * self.z, self.allocations))
        observed = abs(float(_ratio(self.observed[0] - shift, self.observed[1])[0]))
        hits = int(np.count_nonzero(np.abs(statistic) >= observed * (1.0 - _RELATIVE_TIE)))
        return hits / len(statistic) if self.exact else (1 + hits) / (1 + len(statistic))


def _ratio(difference: np.ndarray, error: np.ndarray) -> np.ndarray:
    """difference / error; where the error is 0, infinite with the difference's sign, or 0 when the difference is 0 too."""
    safe = np.where(error > 0.0, error, 1.0)
    apart = np.where(difference == 0.0, 0.0, np.copysign(np.inf, difference))
    return np.where(error > 0.0, difference / safe, apart)


def _edge(p_at: Callable[[float], float], estimate: float, alpha: float, side: float) -> float:
    """The last difference from `estimate` towards `side` that the test does not reject at `alpha`, by bisection to the
    precision of a float (an average of shares stays in [-1, 1])."""
    inside, outside = estimate, side * 1.0
    if p_at(outside) > alpha:
        return outside
    for _ in range(60):
        middle = (inside + outside) / 2.0
        inside, outside = (middle, outside) if p_at(middle) > alpha else (inside, middle)
    return inside
