"""Each finished run's score (the latest human score, else the rubric's) and the score distribution by factor.

The paper (Tsai & Oh, section V.B.1) reports 86.7 % of runs scored 3 and none scored 1.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from analysis.records import HumanScore, StudyRun
from analysis.run_log import RunLog
from analysis.scoring import AutoScore, Rubric, score_run
from designs.factors import CategoricalFactor, ContinuousFactor, Factor, FixedFactor, plain
from designs.presets import qualitative
from designs.spec import StudySpec

#: The paper's qualitative result: share (%) of runs scored 1, 2 and 3.
PAPER_SCORE_SHARES = {1: 0.0, 2: 13.3, 3: 86.7}


def paper_score_shares(spec: StudySpec) -> dict[int, float] | None:
    """The paper's score shares when the study is the paper's qualitative plan (its factors, model and
    run count), else None: they describe that plan's runs and no other study's."""
    paper = qualitative()
    same = spec.design_factors == paper.design_factors and spec.model == paper.model and spec.runs == paper.runs
    return PAPER_SCORE_SHARES if same else None
SCORES = (1, 2, 3)
_LEADING_NUMBER = re.compile(r"-?[0-9.]+")


@dataclass(frozen=True)
class RunScore:
    """The rubric's score of a run and every human score of it, oldest first."""

    code: str
    auto: AutoScore
    human: tuple[HumanScore, ...]

    @property
    def final(self) -> int:
        """The latest human score overrides the rubric's."""
        return self.human[-1].score if self.human else self.auto.score

    @property
    def source(self) -> str:
        return "human" if self.human else "rubric"


def score_runs(runs: Iterable[StudyRun], logs: dict[str, RunLog | None], scores: list[HumanScore], rubric: Rubric) -> dict[str, RunScore]:
    """RunScore of every finished run, by run code."""
    result = {}
    for run in runs:
        if run.outcome is None:
            continue
        human = tuple(s for s in scores if s.run_code == run.code)
        result[run.code] = RunScore(run.code, score_run(run.outcome, logs.get(run.code), rubric), human)
    return result


def counts(values: Iterable[int]) -> list[int]:
    """How many of the values are 1, 2 and 3."""
    values = list(values)
    return [values.count(score) for score in SCORES]


@dataclass(frozen=True)
class LevelScores:
    """Score counts of the runs at one level of one factor."""

    factor: str
    level: str
    counts: list[int]

    @property
    def mean(self) -> float:
        total = sum(self.counts)
        return sum(s * c for s, c in zip(SCORES, self.counts)) / total if total else float("nan")


def level_of(factor: Factor, value: str, distinct: list[float]) -> str:
    """The level a run's value falls in: itself, or a third of a continuous range with many values."""
    if not isinstance(factor, ContinuousFactor) or len(distinct) <= 4:
        return value
    edges = np.linspace(factor.low, factor.high, 4)
    third = min(int(np.searchsorted(edges, float(value), side="right")) - 1, 2)
    return f"{plain(round(edges[third], 2))}-{plain(round(edges[third + 1], 2))}"


def by_factor(spec: StudySpec, runs: list[StudyRun], final: dict[str, int], arm_factor: str | None) -> list[LevelScores]:
    """Score counts per level of each varying factor (the arm factor by its report label)."""
    rows = []
    scored = [run for run in runs if run.code in final]
    for factor in spec.factors:
        if isinstance(factor, FixedFactor):
            continue
        if factor.name == arm_factor:
            levels = [run.arm for run in scored]
        else:
            distinct = sorted({float(run.values[factor.name]) for run in scored}) if not isinstance(factor, CategoricalFactor) else []
            levels = [level_of(factor, run.values[factor.name], distinct) for run in scored]
        order = _level_order(factor, levels)
        for level in order:
            rows.append(LevelScores(factor.name, level, counts(final[r.code] for r, at in zip(scored, levels) if at == level)))
    return rows


def _level_order(factor: Factor, levels: list[str]) -> list[str]:
    present = list(dict.fromkeys(levels))
    if isinstance(factor, CategoricalFactor):
        known = [level for level in factor.levels if level in present]
        return known + sorted(set(present) - set(known))
    return sorted(present, key=lambda level: float(_LEADING_NUMBER.match(level).group()))  # type: ignore[union-attr]
