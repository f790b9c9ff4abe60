"""Proportions with Wilson score intervals; two proportions compared by their difference, their odds
ratio and an exact test.

Wilson (1927): for k successes in n trials and z the normal quantile of the level,
    centre = (k + z^2/2) / (n + z^2),  half-width = z sqrt(k (n - k) / n + z^2/4) / (n + z^2).
It stays inside [0, 1] and keeps close to its nominal coverage for small n, unlike the Wald interval.
Rounding can put an end a hair past the share itself (k = n gives 0.9999999999999999 for some n), so
the ends are clamped to hold the share: low <= k / n <= high always.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.stats import fisher_exact, norm
from statsmodels.stats.proportion import confint_proportions_2indep


@dataclass(frozen=True)
class Proportion:
    """k of n with its Wilson interval (NaN share and interval when n is 0)."""

    k: int
    n: int
    low: float
    high: float

    @property
    def share(self) -> float:
        return self.k / self.n if self.n else math.nan


def wilson(k: int, n: int, level: float = 0.95) -> Proportion:
    """The Wilson score interval of k successes in n trials at the given level."""
    if not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    if n == 0:
        return Proportion(0, 0, math.nan, math.nan)
    z = float(norm.ppf(0.5 + level / 2.0))
    denominator = n + z * z
    centre = (k + z * z / 2.0) / denominator
    half = z * math.sqrt(k * (n - k) / n + z * z / 4.0) / denominator
    share = k / n
    return Proportion(k, n, min(share, max(0.0, centre - half)), max(share, min(1.0, centre + half)))


def exact_difference(first: Proportion, second: Proportion) -> float:
    """Two-sided p-value of Fisher's exact test that two proportions are equal (NaN if either is empty)."""
    if first.n == 0 or second.n == 0:
        return math.nan
    table = [[first.k, first.n - first.k], [second.k, second.n - second.k]]
    return float(fisher_exact(table, alternative="two-sided").pvalue)


@dataclass(frozen=True)
class Interval:
    """An estimate with its confidence interval (all NaN when it cannot be computed)."""

    estimate: float
    low: float
    high: float


NO_INTERVAL = Interval(math.nan, math.nan, math.nan)


def difference(first: Proportion, second: Proportion, level: float = 0.95) -> Interval:
    """first - second share with Newcombe's hybrid score interval (from the two Wilson intervals)."""
    if first.n == 0 or second.n == 0:
        return NO_INTERVAL
    low, high = confint_proportions_2indep(first.k, first.n, second.k, second.n, method="newcomb", compare="diff", alpha=1.0 - level)
    estimate = first.share - second.share
    return Interval(estimate, min(float(low), estimate), max(float(high), estimate))


def odds_ratio(first: Proportion, second: Proportion, level: float = 0.95) -> Interval:
    """The odds ratio of first to second with Woolf's logit interval, 0.5 added to every cell (Gart's
    adjustment), so that an arm with all yes or all no still gives a finite estimate and interval."""
    if first.n == 0 or second.n == 0:
        return NO_INTERVAL
    low, high = confint_proportions_2indep(first.k, first.n, second.k, second.n, method="logit-adjusted", compare="odds-ratio", alpha=1.0 - level)
    estimate = (first.k + 0.5) * (second.n - second.k + 0.5) / ((first.n - first.k + 0.5) * (second.k + 0.5))
    return Interval(estimate, float(low), float(high))
