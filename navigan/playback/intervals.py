"""95 % intervals for Table I: Wilson for the rates C and A, a seeded bootstrap for the social score S.

Both aggregations get one: the pooled episodes (one sample), and the mean over splits (each split
its own stratum, weighted equally, as Social GAN averages its five data sets).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from statsmodels.stats.proportion import proportion_confint

LEVEL = 0.95
#: Bootstrap resamples for S: enough that the interval's ends move by well under 0.005 between seeds.
RESAMPLES = 2000

Interval = tuple[float, float]


def wilson(successes: float, trials: float) -> Interval:
    """The Wilson score interval of a proportion (fractional counts allowed, for effective sizes)."""
    low, high = proportion_confint(successes, trials, alpha=1 - LEVEL, method="wilson")
    return float(low), float(high)


def rate_interval(groups: Sequence[Sequence[bool]], pooled: bool) -> Interval:
    """Wilson interval of a rate over the groups' episodes, pooled or as the mean of the group rates.

    The mean of group rates p = sum_g p_g / G has variance sum_g p_g (1 - p_g) / (G^2 n_g); its
    interval is Wilson's at p with the effective size p (1 - p) / variance (Kish), which is the
    pooled size when every group has the same rate and size. Groups without episodes are left out.
    """
    groups = [np.asarray(g, dtype=float) for g in groups if len(g)]
    if pooled:
        every = np.concatenate(groups)
        return wilson(float(every.sum()), len(every))
    rates = np.array([g.mean() for g in groups])
    sizes = np.array([len(g) for g in groups])
    p = float(rates.mean())
    variance = float(np.sum(rates * (1 - rates) / sizes)) / len(groups) ** 2
    if variance == 0:  # every group all or nothing: as certain as the pooled episodes
        return wilson(p * sizes.sum(), float(sizes.sum()))
    size = p * (1 - p) / variance
    return wilson(p * size, size)


def mean_interval(groups: Sequence[Sequence[float]], pooled: bool, seed: int) -> Interval:
    """Percentile bootstrap interval of the mean, over the pooled episodes or of the mean of group
    means (resampling within each group); seeded, so the same episodes give the same interval.

    Written out rather than scipy.stats.bootstrap, which refuses a group of one episode (eth and
    hotel can have that few under `--episodes`).
    """
    rng = np.random.default_rng(seed)
    groups = [np.asarray(g, dtype=float) for g in groups if len(g)]
    strata = [np.concatenate(groups)] if pooled else groups
    means = np.mean([g[rng.integers(0, len(g), (RESAMPLES, len(g)))].mean(axis=1) for g in strata], axis=0)
    low, high = np.quantile(means, [(1 - LEVEL) / 2, (1 + LEVEL) / 2])
    return float(low), float(high)
