"""The study's fits of outcome metrics: R^2 and RMSE by hand, durations of timed-out runs flagged as censored."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from analysis.records import Blinding, Outcome, StudyData, StudyRun
from analysis.study_fits import fit_metrics
from designs.factors import DiscreteFactor
from designs.model import parse_model
from designs.spec import StudySpec

PEDESTRIANS = DiscreteFactor("Pedestrians", (2.0, 6.0))


def outcome(code: str, status: str, duration: float) -> Outcome:
    return Outcome(
        run_code=code, status=status, seed=1, perception="ideal", duration_s=duration, time_to_goal_s=None, path_length_m=10.0,
        min_distance_m=0.8, time_within_0_5m_s=0.0, time_within_1_2m_s=1.0, collisions=0, max_deceleration_mps2=0.5,
        max_jerk_mps3=1.0, path_irregularity_rad_per_m=0.1, turn_in_place_s=0.0, backing_up_s=0.0, stopped_s=0.0,
        finished_utc="2026-01-01T00:00:00+00:00",
    )


def study(durations: list[tuple[int, str, float]]) -> StudyData:
    spec = StudySpec("s", (PEDESTRIANS,), "main", len(durations))
    runs = [
        StudyRun(i + 1, f"R{i}", {"Pedestrians": str(peds)}, "NaviGAN-R", outcome(f"R{i}", status, duration), None)
        for i, (peds, status, duration) in enumerate(durations)
    ]
    return StudyData(Path("."), spec, parse_model("main", (PEDESTRIANS,)), 1, runs, [], [], Blinding(False, None, {}), ([], []))


def test_timed_out_durations_are_flagged_and_fit_summaries_are_right() -> None:
    data = study([(2, "goal", 10.0), (2, "goal", 12.0), (6, "goal", 20.0), (6, "timeout", 60.0)])
    duration = next(fit for fit in fit_metrics(data) if fit.response == "duration (s)")
    assert duration.flagged == (False, False, False, True)
    assert any("1 of 4 runs timed out" in note and "censored" in note for note in duration.notes)
    # Two groups: fitted values are the group means 11 and 40; SSE = 1 + 1 + 400 + 400 on 2 df.
    assert duration.fitted == pytest.approx((11.0, 11.0, 40.0, 40.0))
    assert duration.residuals == pytest.approx((-1.0, 1.0, -20.0, 20.0))
    y = np.array([10.0, 12.0, 20.0, 60.0])
    assert duration.summary["R^2"] == pytest.approx(1 - 802 / np.sum((y - y.mean()) ** 2))
    assert duration.summary["RMSE"] == pytest.approx(math.sqrt(802 / 2))
    gap = next(fit for fit in fit_metrics(data) if fit.response == "minimum gap (m)")
    assert not any(gap.flagged) and not any("timed out" in note for note in gap.notes)


def test_no_timeout_no_flag() -> None:
    data = study([(2, "goal", 10.0), (2, "goal", 12.0), (6, "goal", 20.0), (6, "goal", 22.0)])
    duration = next(fit for fit in fit_metrics(data) if fit.response == "duration (s)")
    assert not any(duration.flagged) and not any("timed out" in note for note in duration.notes)
