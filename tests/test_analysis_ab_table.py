"""Table II: runs and judgments per arm, the difference and odds ratio between arms, Holm across rows,
checked by hand and against statsmodels, and finite on every all-yes and all-no arm."""

from __future__ import annotations

import math

import pytest
from statsmodels.stats.proportion import confint_proportions_2indep

from analysis.ab_table import RunJudgments, table_ii
from analysis.intervals import difference, odds_ratio, wilson


def run(code: str, arm: str, pedestrians: int, yes: int, total: int) -> RunJudgments:
    return RunJudgments(code, arm, pedestrians, yes, total)


JUDGED = [
    run("a2", "A", 2, 2, 2), run("a4", "A", 4, 4, 4), run("a6", "A", 6, 5, 6), run("a6b", "A", 6, 6, 6),
    run("b2", "B", 2, 1, 2), run("b4", "B", 4, 1, 4), run("b6", "B", 6, 2, 6),
]


def test_rows_count_runs_and_judgments_per_arm() -> None:
    rows = table_ii(JUDGED, ["A", "B"])
    assert [row.min_pedestrians for row in rows] == [2, 4, 6]
    assert [row.runs for row in rows] == [{"A": 4, "B": 3}, {"A": 3, "B": 2}, {"A": 2, "B": 1}]
    assert [(row.shares["A"].k, row.shares["A"].n, row.shares["B"].k, row.shares["B"].n) for row in rows] == [(17, 18, 4, 12), (15, 16, 3, 10), (11, 12, 2, 6)]


def test_difference_and_odds_ratio_of_a_row() -> None:
    row = table_ii(JUDGED, ["A", "B"])[0]  # 17 / 18 against 4 / 12
    assert row.difference.estimate == pytest.approx(17 / 18 - 4 / 12)
    low, high = confint_proportions_2indep(17, 18, 4, 12, method="newcomb", compare="diff")
    assert (row.difference.low, row.difference.high) == pytest.approx((low, high))
    # Gart: 0.5 added to every cell, log OR = log(17.5 * 8.5 / (1.5 * 4.5)), Woolf's standard error.
    log_ratio = math.log(17.5 * 8.5 / (1.5 * 4.5))
    se = math.sqrt(1 / 17.5 + 1 / 1.5 + 1 / 4.5 + 1 / 8.5)
    assert row.odds_ratio.estimate == pytest.approx(math.exp(log_ratio))
    assert row.odds_ratio.low == pytest.approx(math.exp(log_ratio - 1.959963984540054 * se))
    assert row.odds_ratio.high == pytest.approx(math.exp(log_ratio + 1.959963984540054 * se))


def test_holm_adjusts_across_rows() -> None:
    rows = table_ii(JUDGED, ["A", "B"])
    raw = [row.p_value for row in rows]
    order = sorted(range(3), key=lambda i: raw[i])
    # Holm by hand: the i-th smallest p times (3 - i), kept monotone, capped at 1.
    expected, running = [0.0] * 3, 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (3 - rank) * raw[i]))
        expected[i] = running
    assert [row.holm_p for row in rows] == pytest.approx(expected)
    assert all(row.holm_p >= row.p_value for row in rows)


def test_one_arm_has_no_comparison() -> None:
    rows = table_ii([r for r in JUDGED if r.arm == "A"], ["A"])
    assert all(math.isnan(row.p_value) and math.isnan(row.holm_p) and math.isnan(row.odds_ratio.estimate) for row in rows)


@pytest.mark.parametrize("n", range(1, 61))
def test_all_yes_against_all_no_stays_finite(n: int) -> None:
    for first, second in ((wilson(n, n), wilson(0, n)), (wilson(0, n), wilson(n, n)), (wilson(n, n), wilson(n, n))):
        for interval in (difference(first, second), odds_ratio(first, second)):
            assert all(math.isfinite(v) for v in (interval.estimate, interval.low, interval.high))
            assert interval.low <= interval.estimate <= interval.high
    assert difference(wilson(n, n), wilson(0, n)).estimate == 1.0
    assert odds_ratio(wilson(n, n), wilson(n, n)).estimate == pytest.approx(1.0)
