"""The simulated-participant model on a hand-made run: experience, probability, seeded answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.participants import Experience, ParticipantModel, experiences, judge_run, yes_probability
from analysis.run_log import RunLog

DT = 0.1


def _run(stop_at: float | None = None, pedestrian_y: float = 1.5) -> RunLog:
    """The robot drives along x at 1 m/s for 10 s (or stops dead at `stop_at`) past a pedestrian standing at (5, y)."""
    t = np.arange(0.0, 10.0 + DT / 2, DT)
    v = np.ones_like(t) if stop_at is None else np.where(t < stop_at, 1.0, 0.0)
    x = np.concatenate([[0.0], np.cumsum(v[:-1]) * DT])
    robot = np.column_stack([t, x, np.zeros_like(t), np.zeros_like(t), v, np.zeros_like(t)])
    person = np.column_stack([t, np.full_like(t, 5.0), np.full_like(t, pedestrian_y)])
    return RunLog(robot, {"7": person}, [], {})


def test_experience_of_a_pass() -> None:
    (lived,) = experiences(_run())
    # Closest gap: 1.5 m lateral - 0.335 m half-width - 0.25 m body.
    assert lived.pedestrian == "7"
    assert lived.closest_m == pytest.approx(0.915)
    # Gap under 1.2 m while |dx| - 0.495 < sqrt(1.45^2 - 1.165^2): 2 * 1.3583 m at 1 m/s.
    expected = 2 * (0.495 + math.sqrt(1.45**2 - 1.165**2))
    assert lived.personal_space_s == pytest.approx(expected, abs=DT)
    assert lived.abrupt == 0.0


def test_abrupt_stop_near_the_pedestrian() -> None:
    (lived,) = experiences(_run(stop_at=4.0))
    # From 1 m/s to 0 within NaviGAN's 0.4 s step: 2.5 m/s^2, felt within 2.5 m.
    assert lived.abrupt == pytest.approx(1.0 / 0.4, rel=0.05)
    (far,) = experiences(_run(stop_at=4.0, pedestrian_y=6.0))
    assert far.abrupt == 0.0


def test_yes_probability_formula() -> None:
    model = ParticipantModel()
    lived = Experience("1", closest_m=0.7, personal_space_s=2.0, abrupt=0.5)
    logit = 1.5 - 2.0 * (1.2 - 0.7) - 0.25 * 2.0 - 0.6 * 0.5 + 0.3
    assert yes_probability(lived, 0.3, model) == pytest.approx(1 / (1 + math.exp(-logit)))
    assert yes_probability(Experience("1", 0.0, 3.0, 0.0), 5.0, model) == model.yes_after_contact
    far = Experience("1", 3.0, 0.0, 0.0)
    assert yes_probability(far, 0.0, model) == pytest.approx(1 / (1 + math.exp(-1.5)))


def test_judgments_are_seeded_and_per_pedestrian() -> None:
    log = _run()
    first = judge_run(log, "NGAC3", seed=11)
    assert [j.participant for j in first] == ["S01"]
    assert judge_run(log, "NGAC3", seed=11) == first
    many = judge_run(log, "NGAC3", seed=11, participants=40)
    assert len(many) == 40 and {j.experience.pedestrian for j in many} == {"7"}
    # The answers follow the probability: with 40 draws at p ~ 0.6-0.9 some say yes, not all of a different seed agree.
    assert 0 < sum(j.compliant for j in many) < 40
    assert [j.compliant for j in judge_run(log, "NGAC3", seed=12, participants=40)] != [j.compliant for j in many]
    # A participant's tolerance is their own: the same participant has the same probability in any run.
    other = judge_run(log, "N3W3X", seed=11, participants=40)
    assert [j.probability for j in other] == [j.probability for j in many]


def test_run_without_pedestrians_is_judged_on_the_baseline() -> None:
    log = RunLog(_run().robot, {}, [], {})
    (judgment,) = judge_run(log, "AAAAA", seed=1)
    assert judgment.experience.pedestrian is None
    assert 0.5 < judgment.probability < 1.0
