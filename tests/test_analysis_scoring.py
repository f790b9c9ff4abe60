"""The 1-2-3 rubric on hand-made outcome rows and logs, and its thresholds from rubric.toml."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import AnalysisError
from analysis.records import Outcome
from analysis.run_log import RunLog
from analysis.scoring import AutoScore, Rubric, hesitations, read_rubric, score_run

CLEAN = Outcome(
    run_code="AAAAA", status="goal", seed=1, perception="positions", duration_s=12.0, time_to_goal_s=12.0,
    path_length_m=10.0, min_distance_m=1.1, time_within_0_5m_s=0.0, time_within_1_2m_s=1.5, collisions=0,
    max_deceleration_mps2=0.8, max_jerk_mps3=2.0, path_irregularity_rad_per_m=0.05, turn_in_place_s=0.0,
    backing_up_s=0.0, stopped_s=0.0, finished_utc="2026-01-01T00:00:00+00:00",
)


def _log(speeds: list[tuple[float, float]], dt: float = 0.1) -> RunLog:
    """A robot driving along x with piecewise-constant speed: [(seconds, v), ...]."""
    v = np.concatenate([np.full(int(round(s / dt)), speed) for s, speed in speeds])
    t = np.arange(len(v)) * dt
    x = np.cumsum(v) * dt
    robot = np.column_stack([t, x, np.zeros_like(t), np.zeros_like(t), v, np.zeros_like(t)])
    return RunLog(robot, {}, [], {})


def test_clean_run_scores_3() -> None:
    assert score_run(CLEAN, _log([(12.0, 1.0)]), Rubric()).score == 3


@pytest.mark.parametrize(
    "change",
    [{"status": "collision", "collisions": 1}, {"collisions": 1}, {"min_distance_m": 0.0}],
)
def test_collision_scores_1(change: dict[str, object]) -> None:
    score = score_run(replace(CLEAN, **change), None, Rubric())
    assert (score.score, score.reasons) == (1, ("collision",))


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"min_distance_m": 0.42}, "passed within 0.42 m"),
        ({"turn_in_place_s": 1.4}, "turned in place 1.4 s"),
        ({"backing_up_s": 0.8}, "backed up 0.8 s"),
        ({"stopped_s": 2.5}, "stood still 2.5 s"),
        ({"status": "timeout"}, "timed out"),
    ],
)
def test_unnatural_behaviour_scores_2(change: dict[str, object], reason: str) -> None:
    score = score_run(replace(CLEAN, **change), None, Rubric())
    assert score.score == 2
    assert score.reasons == (reason,)


def test_thresholds_are_inclusive_below_and_configurable() -> None:
    at_limits = replace(CLEAN, min_distance_m=0.5, turn_in_place_s=1.0, backing_up_s=0.5, stopped_s=1.0)
    assert score_run(at_limits, None, Rubric()).score == 3
    strict = Rubric(intimate_distance_m=1.2, stopped_s=0.0)
    assert score_run(at_limits, None, strict) == AutoScore(2, ("passed within 0.50 m", "stood still 1.0 s"))


def test_hesitation_comes_from_the_log() -> None:
    dip = _log([(4.0, 1.0), (1.5, 0.2), (6.0, 1.0)])
    assert hesitations(dip, Rubric()) == 1
    assert score_run(CLEAN, dip, Rubric()).reasons == ("hesitated 1x",)
    # Too short, a standstill (the stopping rule's job), the start and the final approach are no hesitation.
    assert hesitations(_log([(4.0, 1.0), (0.6, 0.2), (6.0, 1.0)]), Rubric()) == 0
    assert hesitations(_log([(4.0, 1.0), (1.5, 0.0), (6.0, 1.0)]), Rubric()) == 0
    assert hesitations(_log([(2.0, 0.1), (8.0, 1.0), (2.0, 0.1)]), Rubric()) == 0
    assert hesitations(dip, Rubric(hesitation_min_s=2.0)) == 0
    assert score_run(CLEAN, dip, Rubric(hesitations=2)).score == 3


def test_read_rubric(tmp_path: Path) -> None:
    path = tmp_path / "rubric.toml"
    path.write_text("[rubric]\nintimate_distance_m = 0.45\nhesitations = 2\n")
    assert read_rubric(path) == Rubric(intimate_distance_m=0.45, hesitations=2)
    path.write_text("[rubric]\nintimate = 0.45\n")
    with pytest.raises(AnalysisError, match="unknown rubric key 'intimate'"):
        read_rubric(path)
    path.write_text("[rubric]\nstopped_s = -1\n")
    with pytest.raises(AnalysisError, match="stopped_s must be a number >= 0"):
        read_rubric(path)
    path.write_text("stopped_s = 1\n")
    with pytest.raises(AnalysisError, match=r"expected a \[rubric\] table"):
        read_rubric(path)
    with pytest.raises(AnalysisError, match="no rubric file"):
        read_rubric(tmp_path / "absent.toml")
