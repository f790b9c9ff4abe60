"""The A/B table (the paper's Table II): the share of "socially compliant" judgments per arm among
runs with at least k pedestrians, with Wilson 95 % intervals, and with two arms their difference,
odds ratio and Fisher's exact test per row, Holm-adjusted across the rows.

Judgments of one run share that run, so they are not independent; the intervals and tests treat
them as if they were, as the paper's percentages do, so the table is descriptive and the run-level
analysis (analysis/clustered.py) is the primary one. The rows are nested (every run with 6
pedestrians is also in the row for 4), so their tests are dependent; Holm's step-down adjustment
holds the family-wise error rate under any dependence.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

from statsmodels.stats.multitest import multipletests

from analysis.intervals import NO_INTERVAL, Interval, Proportion, difference, exact_difference, odds_ratio, wilson
from analysis.records import HUMAN, Response

#: Table II of the paper: % judged socially compliant among runs with >= 2, 4, 6 pedestrians.
#: Keyed by the controller names that study files hold (trials/controllers/registry.py); the paper's
#: SBPL planner is this toolkit's lattice planner, and PAPER_NAMES gives the paper's own labels.
PAPER_TABLE_II = {"Lattice": {2: 67.0, 4: 64.0, 6: 58.0}, "NaviGAN-R": {2: 67.0, 4: 75.0, 6: 75.0}}
PAPER_NAMES = {"Lattice": "SBPL", "NaviGAN-R": "NaviGAN-R"}


@dataclass(frozen=True)
class RunJudgments:
    """The judgments of one run, counted."""

    code: str
    arm: str
    pedestrians: int
    yes: int
    total: int


@dataclass(frozen=True)
class TableRow:
    """One row of Table II: each arm's runs and share; with two arms, the first minus the second share,
    their odds ratio, the exact test's p-value and that p-value Holm-adjusted across the rows."""

    min_pedestrians: int
    runs: dict[str, int]
    shares: dict[str, Proportion]
    difference: Interval
    odds_ratio: Interval
    p_value: float
    holm_p: float


def judgments_used(responses: Iterable[Response]) -> tuple[list[Response], str]:
    """The judgments the analysis uses and their source: human ones when there are any, else the simulated
    ones; a participant's latest judgment of a run replaces earlier ones."""
    responses = list(responses)
    human = [r for r in responses if r.source == HUMAN]
    chosen = human or responses
    latest = {(r.run_code, r.participant): r for r in chosen}
    source = "none" if not chosen else ("human" if human else "simulated")
    return list(latest.values()), source


def count_judgments(responses: Iterable[Response], arms: dict[str, str], pedestrians: dict[str, int]) -> list[RunJudgments]:
    """Per run with judgments: its arm, pedestrian count, yes count and total."""
    tally: dict[str, list[int]] = {}
    for response in responses:
        yes_total = tally.setdefault(response.run_code, [0, 0])
        yes_total[0] += response.compliant
        yes_total[1] += 1
    return [RunJudgments(code, arms[code], pedestrians[code], yes, total) for code, (yes, total) in tally.items()]


def table_ii(judged: list[RunJudgments], arms: list[str]) -> list[TableRow]:
    """One row per pedestrian count k present: judgments of runs with at least k pedestrians."""
    rows = []
    for k in sorted({run.pedestrians for run in judged}):
        runs, shares = {}, {}
        for arm in arms:
            chosen = [run for run in judged if run.arm == arm and run.pedestrians >= k]
            runs[arm] = len(chosen)
            shares[arm] = wilson(sum(r.yes for r in chosen), sum(r.total for r in chosen))
        if len(arms) == 2:
            pair = shares[arms[0]], shares[arms[1]]
            rows.append(TableRow(k, runs, shares, difference(*pair), odds_ratio(*pair), exact_difference(*pair), math.nan))
        else:
            rows.append(TableRow(k, runs, shares, NO_INTERVAL, NO_INTERVAL, math.nan, math.nan))
    return holm(rows)


def holm(rows: list[TableRow]) -> list[TableRow]:
    """The rows with their p-values Holm-adjusted over the rows that have one."""
    tested = [i for i, row in enumerate(rows) if not math.isnan(row.p_value)]
    if not tested:
        return rows
    adjusted = multipletests([rows[i].p_value for i in tested], method="holm")[1]
    rows = list(rows)
    for i, p in zip(tested, adjusted):
        rows[i] = replace(rows[i], holm_p=float(p))
    return rows
