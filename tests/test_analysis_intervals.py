"""Wilson intervals and Fisher's exact test against statsmodels, scipy and hand-worked values."""

from __future__ import annotations

import math

import pytest
from statsmodels.stats.proportion import proportion_confint

from analysis.figures import shares_figure
from analysis.intervals import Proportion, exact_difference, wilson


@pytest.mark.parametrize(("k", "n"), [(0, 10), (3, 10), (7, 12), (10, 10), (33, 38), (1, 1)])
def test_wilson_matches_statsmodels(k: int, n: int) -> None:
    low, high = proportion_confint(k, n, alpha=0.05, method="wilson")
    interval = wilson(k, n)
    assert interval.low == pytest.approx(low, abs=1e-12)
    assert interval.high == pytest.approx(high, abs=1e-12)
    assert interval.share == pytest.approx(k / n)


def test_wilson_by_hand() -> None:
    # No successes in 10: the upper end is z^2 / (n + z^2) with z = 1.959964.
    z2 = 1.959963984540054**2
    assert wilson(0, 10).high == pytest.approx(z2 / (10 + z2), rel=1e-12)
    assert wilson(0, 10).low == 0.0
    # 5 of 10 is centred on 0.5: 0.5 -+ z sqrt(2.5 + z^2/4) / (10 + z^2) = [0.2366, 0.7634].
    half = math.sqrt(z2) * math.sqrt(2.5 + z2 / 4) / (10 + z2)
    assert wilson(5, 10).low == pytest.approx(0.5 - half)
    assert wilson(5, 10).high == pytest.approx(0.7634, abs=1e-4)


def test_wilson_empty_and_invalid() -> None:
    empty = wilson(0, 0)
    assert empty.n == 0 and math.isnan(empty.share) and math.isnan(empty.low)
    with pytest.raises(ValueError, match="0 <= k <= n"):
        wilson(5, 4)


def test_fisher_exact_by_hand() -> None:
    # [[3, 1], [1, 3]]: hypergeometric probabilities of 0..4 successes in the first row are
    # 1, 16, 36, 16, 1 (/70); the two-sided p sums those no likelier than 16/70: 34/70.
    assert exact_difference(wilson(3, 4), wilson(1, 4)) == pytest.approx(34 / 70)
    # [[10, 0], [0, 10]]: only the two extreme tables are as unlikely: 2 / C(20, 10).
    assert exact_difference(wilson(10, 10), wilson(0, 10)) == pytest.approx(2 / math.comb(20, 10))
    assert exact_difference(wilson(4, 8), wilson(4, 8)) == pytest.approx(1.0)


def test_fisher_exact_needs_both_arms() -> None:
    assert math.isnan(exact_difference(wilson(3, 4), Proportion(0, 0, math.nan, math.nan)))


@pytest.mark.parametrize("n", range(1, 61))
def test_all_yes_and_all_no_intervals_hold_their_share(n: int) -> None:
    # Rounding once gave 0.9999999999999999 as the upper end of n of n (n = 29, 30, 35, ...),
    # a negative error bar, and a report that crashed.
    all_yes, all_no = wilson(n, n), wilson(0, n)
    assert all_yes.high == 1.0 and all_yes.low < 1.0
    assert all_no.low == 0.0 and all_no.high > 0.0
    low, high = proportion_confint(n, n, alpha=0.05, method="wilson")
    assert all_yes.low == pytest.approx(low, abs=1e-12) and high == pytest.approx(1.0, abs=1e-12)
    for k in range(n + 1):
        interval = wilson(k, n)
        assert interval.low <= interval.share <= interval.high


def test_shares_figure_draws_every_all_yes_and_all_no_arm() -> None:
    rows = []
    for n in range(1, 61):
        yes, no = wilson(n, n), wilson(0, n)
        rows.append((n, {"A": (yes.share, yes.low, yes.high), "B": (no.share, no.low, no.high)}))
    image = shares_figure(rows, None, "all yes against all no")
    assert image.png().startswith(b"\x89PNG") and b"<svg" in image.svg()
