"""Table I's two aggregations and their 95 % intervals, on hand-made episode tables."""

from __future__ import annotations

import csv
import io

import pytest

from navigan.playback.intervals import mean_interval, rate_interval, wilson
from navigan.playback.paper import PaperTable
from navigan.playback.table import POOLED, SPLIT_MEAN, aggregate, csv_text


def episode(comfortable: bool, arrived: bool, social_score: float, min_distance: float | None = 1.0) -> dict:
    """One episode's scores, the ones the table reads."""
    return {"comfortable": comfortable, "arrived": arrived, "collided": False, "social_score": social_score,
            "min_distance": min_distance, "time_to_goal": 10.0 if arrived else None,
            "path_ratio": 1.0 if arrived else None, "irregularity": 0.5, "ade": 0.25}


#: Two splits of unequal size: split a, 4 episodes, C 1/4, A 4/4; split b, 1 episode, C 1/1, A 0/1.
SPLITS = [
    [episode(True, True, 0.2), episode(False, True, 0.4), episode(False, True, 0.4), episode(False, True, 0.6)],
    [episode(True, False, -0.1)],
]


def test_pooled_and_split_mean_values_differ_as_the_arithmetic_says():
    pooled = aggregate(POOLED, ["navigan-r"], {"navigan-r": SPLITS}, seed=0)
    mean = aggregate(SPLIT_MEAN, ["navigan-r"], {"navigan-r": SPLITS}, seed=0)
    assert pooled.values["navigan-r"]["C"] == pytest.approx(2 / 5)
    assert mean.values["navigan-r"]["C"] == pytest.approx((1 / 4 + 1) / 2)
    assert pooled.values["navigan-r"]["A"] == pytest.approx(4 / 5) and mean.values["navigan-r"]["A"] == 0.5
    assert pooled.values["navigan-r"]["S"] == pytest.approx(1.5 / 5)
    assert mean.values["navigan-r"]["S"] == pytest.approx((0.4 - 0.1) / 2)
    assert pooled.values["navigan-r"]["episodes"] == mean.values["navigan-r"]["episodes"] == 5
    assert mean.values["navigan-r"]["time_to_goal_s"] == 10.0  # split b has no arrival: left out, not zero


def test_wilson_interval_matches_its_formula():
    # 8 of 10 at z = 1.96: (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)
    assert wilson(8, 10) == pytest.approx((0.4902, 0.9433), abs=1e-4)
    assert wilson(3, 3) == pytest.approx((0.4385, 1.0), abs=1e-4)
    assert rate_interval([[True] * 8 + [False] * 2], pooled=True) == wilson(8, 10)
    # pooled over splits = Wilson over all episodes
    assert rate_interval([[True, False, False, False], [True]], pooled=True) == wilson(2, 5)


def test_split_mean_rate_interval_uses_the_effective_size():
    # equal rates and sizes: the effective size is the pooled size, so both intervals agree
    same = [[True, True, False, False], [True, True, False, False]]
    assert rate_interval(same, pooled=False) == pytest.approx(wilson(4, 8))
    # rates 0.75 (n 4) and 0.5 (n 2): mean 0.625, variance (0.1875/4 + 0.25/2) / 4 = 0.04296875
    mixed = [[True, True, True, False], [True, False]]
    size = 0.625 * 0.375 / 0.04296875
    assert size == pytest.approx(5.4545, abs=1e-4)
    assert rate_interval(mixed, pooled=False) == pytest.approx(wilson(0.625 * size, size))
    # every split all-or-nothing: no spread within splits, Wilson at the total count
    assert rate_interval([[True] * 3, [False] * 2], pooled=False) == pytest.approx(wilson(2.5, 5))


def test_bootstrap_interval_is_seeded_and_brackets_the_mean():
    scores = [[0.1, 0.2, 0.3, 0.4], [0.9]]
    low, high = mean_interval(scores, pooled=True, seed=3)
    assert (low, high) == mean_interval(scores, pooled=True, seed=3)
    assert (low, high) != mean_interval(scores, pooled=True, seed=4)
    assert low < 0.38 < high and 0.1 <= low and high <= 0.9
    # per split: the one-episode split never varies, so the mean's ends are (split a's ends + 0.9) / 2
    low_a, high_a = mean_interval(scores[:1], pooled=True, seed=3)
    assert mean_interval(scores, pooled=False, seed=3) == pytest.approx(((low_a + 0.9) / 2, (high_a + 0.9) / 2))
    assert low_a < 0.25 < high_a
    assert mean_interval([[0.5, 0.5], [0.5]], pooled=False, seed=0) == (0.5, 0.5)


def test_csv_holds_both_aggregations_with_interval_rows_and_empty_cells():
    paper = PaperTable("hand copy", {"C": {"R": 0.97}})
    tables = [aggregate(scope, ["navigan-r", "navigan-r-shield"],
                        {"navigan-r": SPLITS, "navigan-r-shield": SPLITS}, seed=0) for scope in (POOLED, SPLIT_MEAN)]
    rows = list(csv.DictReader(io.StringIO(csv_text(tables, paper, "paper"))))
    assert list(rows[0]) == ["protocol", "scope", "metric", "source", "R", "R_shield"]
    assert {r["protocol"] for r in rows} == {"paper"}
    cells = {(r["scope"], r["metric"], r["source"]): r for r in rows}
    low, high = wilson(2, 5)
    assert cells[POOLED, "C", "ours_low"]["R"] == f"{low:.3f}" and cells[POOLED, "C", "ours_high"]["R"] == f"{high:.3f}"
    assert cells[SPLIT_MEAN, "C", "ours"]["R"] == "0.625" and cells[SPLIT_MEAN, "C", "paper"]["R"] == "0.970"
    assert cells[POOLED, "C", "paper"]["R_shield"] == ""  # no paper column
    assert not any("n/a" in v for r in rows for v in r.values())
