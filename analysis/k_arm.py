"""The planned analysis of more than two arms: a global randomization test of the runs' shares of yes across the arms,
then every pair of arms by the two-arm test (`analysis.randomization`), corrected for multiplicity by Holm's method.

The global statistic is the between-arm sum of squares of the run shares within each stratum, summed over the strata:
sum_s sum_a n_sa (mean_sa - mean_s)^2, the numerator of a one-way analysis of variance. Under the sharp null hypothesis
that the arm changes no run's share, every allocation the design could have made (the same number of runs of each arm
within each stratum) is equally likely and gives the same shares, so p is the share of allocations whose statistic is at
least the observed one. The reference set is enumerated when it holds at most `MAX_ALLOCATIONS` allocations, else
`draws` are drawn from a recorded seed and p = (1 + hits) / (1 + draws).

Each pair is then compared on its own runs, re-randomized between the two arms within the strata. Holm's step-down
adjustment (Holm, Scand. J. Statist. 6, 1979; `statsmodels.stats.multitest`) keeps the chance of any false rejection
among the m = k (k - 1) / 2 pairs at most alpha; each pair's interval is at level 1 - alpha / m (Bonferroni), so the m
intervals hold together with probability at least 1 - alpha.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from analysis.errors import AnalysisError
from analysis.randomization import DRAWS, MAX_ALLOCATIONS, RandomizationTest, randomization_test

#: Statistics within this fraction of the observed one count as equal (sums of the same shares in another order).
_RELATIVE_TIE = 1e-9
#: Allocations scored at once, which bounds the temporaries.
_CHUNK = 50_000
#: The stated correction of the pairwise comparisons.
CORRECTION = "Holm"


@dataclass(frozen=True)
class GlobalTest:
    """The global randomization test: the observed statistic, its p-value and how it was found."""

    runs: int
    strata: int
    arms: tuple[str, ...]
    #: Between-arm sum of squares of run shares within strata.
    statistic: float
    p_value: float
    #: How many allocations the design could have made (product over strata of the multinomial coefficients).
    allocations: int
    exact: bool
    draws: int
    mc_error: float
    seed: int | None

    def describe(self) -> str:
        """How the p-value was found, in one phrase."""
        if self.exact:
            return f"exact: all {self.allocations:,} allocations enumerated"
        return (f"Monte Carlo: {self.draws:,} of {self.allocations:,} allocations drawn (seed {self.seed}), "
                f"Monte Carlo standard error of p {self.mc_error:.4f}")


@dataclass(frozen=True)
class PairwiseComparison:
    """Two arms compared on their runs: the two-arm test (its interval at the pairwise level) and its Holm-adjusted p."""

    first: str
    second: str
    test: RandomizationTest
    holm_p: float


@dataclass(frozen=True)
class KArmResult:
    """The global test, then every pair in the arms' order, with the level of the pairwise intervals."""

    global_test: GlobalTest
    pairs: tuple[PairwiseComparison, ...]
    interval_level: float


def _allocation_count(arms: np.ndarray, stratum: np.ndarray) -> int:
    count = 1
    for s in np.unique(stratum):
        sizes = np.bincount(arms[stratum == s])
        count *= math.factorial(int(sizes.sum())) // math.prod(math.factorial(int(n)) for n in sizes)
    return count


def _stratum_allocations(labels: np.ndarray) -> np.ndarray:
    """Every distinct arrangement of one stratum's arm labels, as rows."""
    runs, sizes = len(labels), np.bincount(labels)
    rows: list[list[int]] = []

    def place(arm: int, free: tuple[int, ...], row: list[int]) -> None:
        if arm == len(sizes):
            rows.append(row.copy())
            return
        for chosen in itertools.combinations(free, int(sizes[arm])):
            for i in chosen:
                row[i] = arm
            place(arm + 1, tuple(i for i in free if i not in chosen), row)

    place(0, tuple(range(runs)), [0] * runs)
    return np.array(rows, dtype=np.int64).reshape(-1, runs)


def _enumerated(arms: np.ndarray, stratum: np.ndarray) -> np.ndarray:
    """Every allocation of the layout as rows of a (count, runs) matrix of arm indices."""
    members = [np.flatnonzero(stratum == s) for s in np.unique(stratum)]
    parts = [_stratum_allocations(arms[runs]) for runs in members]
    grid = np.stack(np.meshgrid(*[np.arange(len(p)) for p in parts], indexing="ij"), axis=-1).reshape(-1, len(parts))
    out = np.zeros((len(grid), len(arms)), dtype=np.int64)
    for runs, part, column in zip(members, parts, grid.T):
        out[:, runs] = part[column]
    return out


def _drawn(arms: np.ndarray, stratum: np.ndarray, draws: int, rng: np.random.Generator) -> np.ndarray:
    """`draws` allocations at random: each stratum's arm labels shuffled among its runs."""
    out = np.tile(arms, (draws, 1))
    for s in np.unique(stratum):
        runs = np.flatnonzero(stratum == s)
        out[:, runs] = rng.permuted(out[:, runs], axis=1)
    return out


def _statistics(shares: np.ndarray, allocations: np.ndarray, stratum: np.ndarray, count: int) -> np.ndarray:
    """sum over strata and arms of S_sa^2 / n_sa, under each allocation (the between-arm sum of squares up to a constant)."""
    out = np.zeros(len(allocations))
    for s in np.unique(stratum):
        runs = np.flatnonzero(stratum == s)
        for arm in range(count):
            chosen = allocations[:, runs] == arm
            size = int(chosen[0].sum())
            if size:
                out += np.square(chosen.astype(float) @ shares[runs]) / size
    return out


def global_test(shares: np.ndarray, arms: Sequence[str], order: Sequence[str], strata: np.ndarray | None = None, *,
                max_allocations: int = MAX_ALLOCATIONS, draws: int = DRAWS, seed: int = 0) -> GlobalTest:
    """The global randomization test of the runs' `shares` across the arms (`arms` names each run's, `order` lists them),
    re-randomized within `strata` (one label per run; None: one stratum).

    Raises:
        AnalysisError: shares outside [0, 1], an arm not in `order`, or fewer than two arms with runs.
    """
    y = np.asarray(shares, dtype=float)
    if y.ndim != 1 or len(arms) != len(y) or (strata is not None and len(strata) != len(y)):
        raise AnalysisError(f"one share, one arm and one stratum per run expected, got {len(y)}, {len(arms)} and "
                            f"{len(y) if strata is None else len(strata)}")
    if not np.all(np.isfinite(y)) or np.any((y < 0.0) | (y > 1.0)):
        raise AnalysisError("every run's share of yes must be a number in [0, 1]")
    unknown = next((a for a in arms if a not in order), None)
    if unknown is not None:
        raise AnalysisError(f"run of arm {unknown!r}, which is not one of {', '.join(order)}")
    index = np.array([list(order).index(a) for a in arms], dtype=np.int64)
    if len(np.unique(index)) < 2:
        raise AnalysisError("the runs hold fewer than two arms: the arms cannot be compared")
    stratum = np.zeros(len(y), dtype=np.int64) if strata is None else np.unique(np.asarray(strata), return_inverse=True)[1].reshape(-1)
    count = _allocation_count(index, stratum)
    exact = count <= max_allocations
    allocations = _enumerated(index, stratum) if exact else _drawn(index, stratum, draws, np.random.default_rng(seed))
    observed = float(_statistics(y, index[None, :], stratum, len(order))[0])
    constant = sum(float(y[stratum == s].sum()) ** 2 / int((stratum == s).sum()) for s in np.unique(stratum))
    under = np.concatenate([_statistics(y, allocations[i:i + _CHUNK], stratum, len(order)) for i in range(0, len(allocations), _CHUNK)])
    hits = int(np.count_nonzero(under >= observed - _RELATIVE_TIE * max(abs(observed), 1e-300)))
    p = hits / len(allocations) if exact else (1 + hits) / (1 + len(allocations))
    return GlobalTest(len(y), len(np.unique(stratum)), tuple(order), max(observed - constant, 0.0), p, count, exact,
                      0 if exact else draws, 0.0 if exact else math.sqrt(p * (1.0 - p) / draws), None if exact else seed)


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values, by statsmodels."""
    from statsmodels.stats.multitest import multipletests

    return np.asarray(multipletests(np.asarray(p_values, dtype=float), method="holm")[1], dtype=float)


def k_arm_analysis(shares: np.ndarray, arms: Sequence[str], order: Sequence[str], strata: np.ndarray | None, alpha: float,
                   draws: int = DRAWS, seed: int = 0) -> KArmResult:
    """The global test, then every pair of `order`'s arms (first before second) on its own runs, Holm-adjusted, each
    interval at 1 - alpha / m.

    Raises:
        AnalysisError: as `global_test`; a pair without runs of both arms in a stratum is compared without an interval.
    """
    y = np.asarray(shares, dtype=float)
    labels = np.asarray(arms, dtype=object)
    overall = global_test(y, arms, order, strata, draws=draws, seed=seed)
    pairs = list(itertools.combinations(order, 2))
    level = 1.0 - alpha / len(pairs)
    tests = []
    for first, second in pairs:
        keep = (labels == first) | (labels == second)
        tests.append(randomization_test(y[keep], labels[keep] == first, None if strata is None else np.asarray(strata)[keep],
                                        level=level, draws=draws, seed=seed))
    adjusted = holm([t.p_value for t in tests])
    return KArmResult(overall, tuple(PairwiseComparison(a, b, t, float(h)) for (a, b), t, h in zip(pairs, tests, adjusted)), level)
