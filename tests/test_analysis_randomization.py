"""The run-level randomization test against complete enumerations written out here independently."""

from __future__ import annotations

import itertools
import math
import statistics

import numpy as np
import pytest

from analysis.errors import AnalysisError
from analysis.randomization import randomization_test

#: Eight runs, four per arm: shares of yes per run and the arm each run was given (True: the first arm).
SHARES = np.array([0.5, 1.0, 0.75, 1.0, 0.25, 0.5, 0.0, 0.6])
FIRST = np.array([True, True, True, True, False, False, False, False])


def enumerated_p(shares: np.ndarray, first: np.ndarray, strata: np.ndarray, shift: float = 0.0) -> float:
    """Two-sided p by listing every allocation with the per-stratum arm counts, statistic = the n1 n2 / n weighted
    mean of the within-stratum differences of arm means, shares shifted by `shift` in the observed first arm."""
    y = shares - shift * first
    labels = sorted(set(strata.tolist()))
    members = {s: [i for i in range(len(y)) if strata[i] == s] for s in labels}
    counts = {s: int(sum(first[i] for i in members[s])) for s in labels}

    def statistic(arm: set[int]) -> float:
        total = weight = 0.0
        for s in labels:
            runs, k = members[s], counts[s]
            if 0 < k < len(runs):
                w = k * (len(runs) - k) / len(runs)
                mean_first = sum(y[i] for i in runs if i in arm) / k
                mean_second = sum(y[i] for i in runs if i not in arm) / (len(runs) - k)
                total += w * (mean_first - mean_second)
                weight += w
        return total / weight

    observed = abs(statistic({i for i in range(len(y)) if first[i]}))
    choices = [list(itertools.combinations(members[s], counts[s])) for s in labels]
    values = [abs(statistic(set(itertools.chain.from_iterable(pick)))) for pick in itertools.product(*choices)]
    return sum(v >= observed - 1e-9 for v in values) / len(values)


def test_exact_p_value_is_the_share_of_all_70_allocations_as_extreme():
    result = randomization_test(SHARES, FIRST)
    assert result.exact and result.allocations == 70 and result.draws == 0
    assert result.difference == pytest.approx((0.5 + 1.0 + 0.75 + 1.0) / 4 - (0.25 + 0.5 + 0.0 + 0.6) / 4)
    assert result.p_value == pytest.approx(enumerated_p(SHARES, FIRST, np.zeros(8)), abs=1e-12)
    # as far from 0: first-arm sums of 3.25 (either 0.5 with 1, 1, 0.75) and 3.35 (0.6 for the 0.5), and the mirrors
    assert result.p_value == pytest.approx(6 / 70)


def test_stratified_p_value_re_randomizes_within_strata_only():
    strata = np.array([0, 0, 1, 1, 0, 0, 1, 1])
    result = randomization_test(SHARES, FIRST, strata)
    assert result.strata == 2 and result.allocations == 36  # C(4, 2) in each stratum
    assert result.p_value == pytest.approx(enumerated_p(SHARES, FIRST, strata), abs=1e-12)


def test_unbalanced_strata_weight_each_difference_by_n1_n2_over_n():
    first = np.array([True, False, False, True, True, False, True, False])
    strata = np.array([0, 0, 0, 1, 1, 1, 1, 1])
    result = randomization_test(SHARES, first, strata)
    assert result.allocations == 3 * 10
    assert result.p_value == pytest.approx(enumerated_p(SHARES, first, strata), abs=1e-12)


def test_monte_carlo_p_value_is_within_its_error_of_the_exact_one_and_repeats_with_its_seed():
    rng = np.random.default_rng(4)
    shares = rng.random(18)
    first = np.repeat([True, False], 9)
    exact = randomization_test(shares, first, level=None)
    drawn = randomization_test(shares, first, level=None, max_allocations=1000, draws=20_000, seed=11)
    assert exact.exact and not drawn.exact and drawn.allocations == 48_620 and drawn.seed == 11
    assert 0.0 < drawn.mc_error < 0.004
    assert abs(drawn.p_value - exact.p_value) < 4 * drawn.mc_error
    assert randomization_test(shares, first, level=None, max_allocations=1000, draws=20_000, seed=11) == drawn
    assert "seed 11" in drawn.describe() and "48,620" in exact.describe()


def test_all_yes_arm_still_gets_a_p_value_and_an_interval():
    shares = np.array([1.0] * 9 + [0.5, 0.25, 1.0, 0.5, 0.75, 0.0, 0.5, 0.25, 0.5])
    first = np.repeat([True, False], 9)
    result = randomization_test(shares, first)
    assert result.difference == pytest.approx(1.0 - shares[9:].mean())
    # as far apart: this allocation, the 9 that swap the second arm's 1.0 for one of the first's, and their mirrors
    assert result.p_value == pytest.approx(20 / 48_620)
    assert result.low < result.difference < result.high <= 1.0


def studentized_p(shares: np.ndarray, first: np.ndarray, strata: np.ndarray, difference: float) -> float:
    """Two-sided p of an average difference by listing every allocation: the n1 n2 / n weighted difference of arm means
    over its Neyman standard error, on the shares with `difference` taken off the observed first arm's runs."""
    y = shares - difference * first
    labels = sorted(set(strata.tolist()))
    members = {s: [i for i in range(len(y)) if strata[i] == s] for s in labels}
    counts = {s: int(sum(first[i] for i in members[s])) for s in labels}
    total_weight = sum(counts[s] * (len(members[s]) - counts[s]) / len(members[s]) for s in labels)

    def studentized(arm: set[int]) -> float:
        estimate = variance = 0.0
        for s in labels:
            runs, k = members[s], counts[s]
            w = k * (len(runs) - k) / len(runs) / total_weight
            one, two = [y[i] for i in runs if i in arm], [y[i] for i in runs if i not in arm]
            estimate += w * (statistics.fmean(one) - statistics.fmean(two))
            variance += w * w * (statistics.variance(one) / len(one) + statistics.variance(two) / len(two))
        return estimate / math.sqrt(variance) if variance > 0 else math.copysign(math.inf, estimate) if estimate else 0.0

    observed = abs(studentized({i for i in range(len(y)) if first[i]}))
    choices = [list(itertools.combinations(members[s], counts[s])) for s in labels]
    values = [abs(studentized(set(itertools.chain.from_iterable(pick)))) for pick in itertools.product(*choices)]
    return sum(v >= observed * (1 - 1e-12) for v in values) / len(values)


@pytest.mark.parametrize("strata", [np.zeros(8), np.array([0, 0, 1, 1, 0, 0, 1, 1])], ids=["one stratum", "two strata"])
def test_interval_holds_the_average_differences_the_studentized_test_does_not_reject(strata: np.ndarray) -> None:
    result = randomization_test(SHARES, FIRST, None if not strata.any() else strata, level=0.8)
    assert result.low < result.difference < result.high
    assert result.p_studentized == pytest.approx(studentized_p(SHARES, FIRST, strata, 0.0), abs=1e-12)
    for edge, outward in ((result.low, -1.0), (result.high, 1.0)):
        # an end is where the p-value steps below 0.2, to well within 1e-10 of it
        assert studentized_p(SHARES, FIRST, strata, edge - outward * 1e-10) > 0.2
        assert studentized_p(SHARES, FIRST, strata, edge + outward * 1e-10) <= 0.2


def test_an_interval_needs_two_runs_of_each_arm_in_each_stratum() -> None:
    result = randomization_test(SHARES, FIRST, np.array([0, 0, 0, 1, 0, 0, 1, 1]), level=0.95)
    assert math.isnan(result.low) and "fewer than two runs of an arm" in result.no_interval
    assert not math.isnan(result.p_value)


def test_bad_input_is_refused_with_what_was_expected():
    with pytest.raises(AnalysisError, match=r"in \[0, 1\]"):
        randomization_test(np.array([0.5, 1.5]), np.array([True, False]))
    with pytest.raises(AnalysisError, match="both arms"):
        randomization_test(SHARES[:4], FIRST[:4])
    with pytest.raises(AnalysisError, match="one share, one arm"):
        randomization_test(SHARES, FIRST[:5])



@pytest.mark.slow
def test_the_interval_covers_the_average_difference_when_the_effect_differs_between_runs() -> None:
    """300 data sets of `benchmarks/bench_interval.py` at 0.95 against 0.6 with run SD 1 (the effect on the share differs
    from run to run): coverage at least 95 % less 2.5 Monte Carlo standard errors."""
    from benchmarks.bench_interval import one

    rng = np.random.default_rng([7, 4])
    covered = sum(one(rng, 0.95, 0.6, 1.0, exact=False)[0] for _ in range(300))
    assert covered / 300 >= 0.95 - 2.5 * math.sqrt(0.95 * 0.05 / 300)
