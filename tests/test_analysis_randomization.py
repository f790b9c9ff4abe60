"""The run-level randomization test against complete enumerations written out here independently."""

from __future__ import annotations

import itertools
from fractions import Fraction

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


def test_interval_holds_the_shifts_the_test_does_not_reject():
    result = randomization_test(SHARES, FIRST, level=0.8)
    assert result.low < result.difference < result.high
    for edge, outward in ((result.low, -1.0), (result.high, 1.0)):
        assert enumerated_p(SHARES, FIRST, np.zeros(8), edge - outward * 1e-6) > 0.2
        assert enumerated_p(SHARES, FIRST, np.zeros(8), edge + outward * 1e-3) <= 0.2


def test_bad_input_is_refused_with_what_was_expected():
    with pytest.raises(AnalysisError, match=r"in \[0, 1\]"):
        randomization_test(np.array([0.5, 1.5]), np.array([True, False]))
    with pytest.raises(AnalysisError, match="both arms"):
        randomization_test(SHARES[:4], FIRST[:4])
    with pytest.raises(AnalysisError, match="one share, one arm"):
        randomization_test(SHARES, FIRST[:5])


def _exact_interval(shares: np.ndarray, first: np.ndarray, alpha: Fraction) -> tuple[Fraction, Fraction]:
    """The inverted interval in exact rational arithmetic: every allocation enumerated, the p-value evaluated at every
    shift where it steps and between them, walking out from the estimate until it is rejected."""
    y = [Fraction(v).limit_denominator(1000) for v in shares]
    n, k = len(y), int(first.sum())

    def statistic(values: list[Fraction], chosen: tuple[int, ...]) -> Fraction:
        return sum(values[i] for i in chosen) / k - sum(values[i] for i in range(n) if i not in chosen) / (n - k)

    allocations = list(itertools.combinations(range(n), k))
    observed_z = [Fraction(int(f)) for f in first]
    observed = statistic(y, tuple(np.flatnonzero(first)))
    pairs = [(statistic(y, c), statistic(observed_z, c)) for c in allocations]

    def p(shift: Fraction) -> Fraction:
        return Fraction(sum(abs(s - shift * t) >= abs(observed - shift) for s, t in pairs), len(allocations))

    steps = sorted({d for s, t in pairs for d in ([(observed - s) / (1 - t)] if t != 1 else []) + ([(observed + s) / (1 + t)] if t != -1 else [])})
    ends = []
    for side in (-1, 1):
        candidates = sorted((d for d in steps if (d - observed) * side > 0), key=lambda d: abs(d - observed))
        end = observed
        for d in candidates:
            if p(d) <= alpha:
                break
            end = d
        ends.append(end)
    return ends[0], ends[1]


def test_interval_ends_are_the_exact_shifts_where_the_p_value_steps():
    low, high = _exact_interval(SHARES, FIRST, Fraction(1, 5))
    result = randomization_test(SHARES, FIRST, level=0.8)
    assert (low, high) == (Fraction(1, 5), Fraction(3, 4))
    # at the step itself, to the rounding of one division (a tolerance-wide bisection stopped about 1e-9 short of it)
    assert (result.low, result.high) == (pytest.approx(float(low), abs=1e-14), pytest.approx(float(high), abs=1e-14))
