"""The planned analysis of more than two arms against independent truths: the global test's exact p by brute-force
enumeration of every distinct arrangement of the arm labels (within strata) with the textbook between-group sum of
squares, its two-arm case equal to the two-arm test, its Monte Carlo p within its error of the exact one, Holm's
adjustment by its step-down definition, and every pair by the two-arm test on that pair's runs."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from analysis.errors import AnalysisError
from analysis.k_arm import global_test, holm, k_arm_analysis
from analysis.randomization import randomization_test


def between_ss(y: np.ndarray, arms: tuple[str, ...], strata: tuple[int, ...]) -> float:
    """Sum over strata of sum over arms of n (mean_arm - mean_stratum)^2, straight from its definition."""
    total = 0.0
    for s in set(strata):
        values = [(v, a) for v, a, t in zip(y, arms, strata) if t == s]
        overall = sum(v for v, _ in values) / len(values)
        for arm in set(a for _, a in values):
            group = [v for v, a in values if a == arm]
            total += len(group) * (sum(group) / len(group) - overall) ** 2
    return total


def brute_force_p(y: np.ndarray, arms: tuple[str, ...], strata: tuple[int, ...]) -> float:
    """The share of distinct within-stratum arrangements of the labels whose between-arm SS is at least the observed."""
    positions = {s: [i for i, t in enumerate(strata) if t == s] for s in sorted(set(strata))}
    per_stratum = [sorted(set(itertools.permutations([arms[i] for i in runs]))) for runs in positions.values()]
    observed = between_ss(y, arms, strata)
    hits = count = 0
    for choice in itertools.product(*per_stratum):
        labels = [""] * len(y)
        for runs, arrangement in zip(positions.values(), choice):
            for i, label in zip(runs, arrangement):
                labels[i] = label
        count += 1
        hits += between_ss(y, tuple(labels), strata) >= observed - 1e-12
    return hits / count


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_exact_p_of_three_arms_is_the_brute_force_one(seed):
    rng = np.random.default_rng(seed)
    y = rng.integers(0, 5, 9) / 4.0  # shares of four judgments: ties, as real ones have
    arms = ("A", "B", "C") * 3
    test = global_test(y, arms, ("A", "B", "C"))
    assert test.exact and test.allocations == math.factorial(9) // math.factorial(3) ** 3
    assert test.p_value == pytest.approx(brute_force_p(y, arms, (0,) * 9), abs=1e-12)
    assert test.statistic == pytest.approx(between_ss(y, arms, (0,) * 9), abs=1e-12)


def test_the_exact_p_within_strata_is_the_brute_force_one():
    rng = np.random.default_rng(5)
    y = rng.integers(0, 5, 10) / 4.0
    arms = ("A", "B", "C", "A", "B", "A", "B", "C", "C", "A")
    strata = (0, 0, 0, 0, 0, 1, 1, 1, 1, 1)
    test = global_test(y, arms, ("A", "B", "C"), np.array(strata))
    assert test.exact and test.strata == 2
    assert test.p_value == pytest.approx(brute_force_p(y, arms, strata), abs=1e-12)


def test_with_two_arms_it_is_the_two_arm_test():
    rng = np.random.default_rng(11)
    y = rng.random(12)
    arms = ["A"] * 6 + ["B"] * 6
    assert global_test(y, arms, ("A", "B")).p_value == randomization_test(y, np.array(arms) == "A", level=None).p_value


def test_monte_carlo_agrees_with_the_exact_p_within_its_error_and_repeats_by_seed():
    rng = np.random.default_rng(3)
    y = rng.random(12)
    arms = ("A", "B", "C") * 4
    exact = global_test(y, arms, ("A", "B", "C"))
    drawn = global_test(y, arms, ("A", "B", "C"), max_allocations=100, draws=20_000, seed=9)
    assert not drawn.exact and drawn.seed == 9 and drawn.draws == 20_000
    assert abs(drawn.p_value - exact.p_value) < 4 * drawn.mc_error
    assert global_test(y, arms, ("A", "B", "C"), max_allocations=100, draws=20_000, seed=9) == drawn


def test_holm_is_the_step_down_definition():
    p = [0.01, 0.04, 0.03, 0.2, 0.012]
    order = np.argsort(p)
    m = len(p)
    expected = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        expected[i] = running
    np.testing.assert_allclose(holm(p), expected, rtol=0, atol=1e-15)


def test_every_pair_is_the_two_arm_test_on_its_runs_at_the_bonferroni_level():
    rng = np.random.default_rng(8)
    y = np.concatenate([rng.uniform(0.6, 1.0, 6), rng.uniform(0.0, 0.4, 6), rng.uniform(0.3, 0.7, 6)])
    arms = ["A"] * 6 + ["B"] * 6 + ["C"] * 6
    result = k_arm_analysis(y, arms, ("A", "B", "C"), None, alpha=0.05, draws=5000, seed=1)
    assert [(p.first, p.second) for p in result.pairs] == [("A", "B"), ("A", "C"), ("B", "C")]
    assert result.interval_level == pytest.approx(1 - 0.05 / 3)
    for pair in result.pairs:
        keep = np.isin(arms, [pair.first, pair.second])
        alone = randomization_test(y[keep], np.array(arms)[keep] == pair.first, level=1 - 0.05 / 3)
        assert pair.test == alone
    np.testing.assert_allclose([p.holm_p for p in result.pairs], holm([p.test.p_value for p in result.pairs]))
    # A well above B: the global test and that pair reject; the interval of A - B excludes 0
    assert result.global_test.p_value < 0.01 and result.pairs[0].holm_p < 0.05 and result.pairs[0].test.low > 0


def test_fewer_than_two_arms_or_an_unknown_arm_is_refused():
    with pytest.raises(AnalysisError, match="fewer than two arms"):
        global_test(np.array([0.5, 0.6]), ["A", "A"], ("A", "B", "C"))
    with pytest.raises(AnalysisError, match="run of arm 'D', which is not one of A, B, C"):
        global_test(np.array([0.5, 0.6]), ["A", "D"], ("A", "B", "C"))
