"""Simulated participants: would a pedestrian of a simulated run call the robot socially compliant?

Each participant lives one pedestrian's experience of the run, read from its log:
- closest gap d (m) between the robot's footprint and the pedestrian's body;
- time T (s) the gap was under the personal-space edge (1.2 m);
- abrupt motion A: the largest of (deceleration / 1 m/s^2 + change of turn rate / 2 rad/s^2),
  both over NaviGAN's 0.4 s step, while the robot was within 2.5 m of the pedestrian.
The participant says "yes" with probability
    sigmoid(b0 - b_d max(0, 1.2 - d) - b_t T - b_a A + u),   b0 = 1.5, b_d = 2 /m, b_t = 0.25 /s, b_a = 0.6,
u ~ N(0, 0.5^2) the participant's own tolerance (drawn once per participant and seed, the same in
every run), and 0.02 when the robot touched the pedestrian. The draw is the judgment's noise.
A run with k pedestrians has k participants by default, participant i living pedestrian i; with a
set number N, participant i lives pedestrian i mod k. Participants are named S01, S02, ...
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import expit

from analysis.run_log import RunLog
from robot_logs.physical import STEP_S


@dataclass(frozen=True)
class ParticipantModel:
    """The coefficients of the simulated judgment (see the module's docstring)."""

    baseline: float = 1.5
    personal_space_m: float = 1.2
    per_metre_closer: float = 2.0
    per_second_in_personal_space: float = 0.25
    per_abrupt_unit: float = 0.6
    abrupt_range_m: float = 2.5
    deceleration_scale_mps2: float = 1.0
    turn_rate_change_scale_radps2: float = 2.0
    tolerance_sd: float = 0.5
    yes_after_contact: float = 0.02

    def describe(self) -> list[str]:
        """The model in words, with its numbers."""
        return [
            "Each simulated participant lives one pedestrian's experience of the run, read from the run's log "
            "(participant i lives pedestrian i, or i mod k when more participants than the k pedestrians are asked).",
            f"Experience: the closest gap d between the robot's footprint and the pedestrian's body; the time T the gap was under {self.personal_space_m:g} m "
            f"(personal space); abrupt motion A, the largest deceleration / {self.deceleration_scale_mps2:g} m/s^2 plus change of turn rate / "
            f"{self.turn_rate_change_scale_radps2:g} rad/s^2 over 0.4 s while the robot was within {self.abrupt_range_m:g} m.",
            f"P(yes) = sigmoid({self.baseline:g} - {self.per_metre_closer:g} max(0, {self.personal_space_m:g} - d) - "
            f"{self.per_second_in_personal_space:g} T - {self.per_abrupt_unit:g} A + u), u ~ N(0, {self.tolerance_sd:g}^2) the participant's "
            f"own tolerance (the same in every run); {self.yes_after_contact:g} when the robot touched the pedestrian.",
            "The answer is one seeded draw from P(yes): the same seed and run always give the same answers.",
        ]


@dataclass(frozen=True)
class Experience:
    """What one pedestrian lived through in a run (None: a run without pedestrians)."""

    pedestrian: str | None
    closest_m: float
    personal_space_s: float
    abrupt: float

    @property
    def contact(self) -> bool:
        return self.closest_m <= 0.0


@dataclass(frozen=True)
class Judgment:
    """A simulated participant's answer and the probability it was drawn with."""

    participant: str
    compliant: bool
    probability: float
    experience: Experience


def abruptness(log: RunLog, model: ParticipantModel) -> np.ndarray:
    """Per robot sample: deceleration and change of turn rate over the next 0.4 s, in the model's units."""
    t, v, w = log.robot[:, 0], log.robot[:, 4], log.robot[:, 5]
    ahead = np.minimum(np.searchsorted(t, t + STEP_S), len(t) - 1)
    span = np.maximum(t[ahead] - t, 1e-9)
    deceleration = np.maximum(v - v[ahead], 0.0) / span
    turn_change = np.abs(w[ahead] - w) / span
    abrupt = deceleration / model.deceleration_scale_mps2 + turn_change / model.turn_rate_change_scale_radps2
    return np.where(ahead > np.arange(len(t)), abrupt, 0.0)


def experiences(log: RunLog, model: ParticipantModel = ParticipantModel()) -> list[Experience]:
    """Each logged pedestrian's experience of the run, in id order."""
    t = log.robot[:, 0]
    dt = np.diff(t, append=t[-1])
    abrupt = abruptness(log, model)
    lived = []
    for ident in log.pedestrians:
        gap = log.gaps(ident)
        near = gap < model.abrupt_range_m
        lived.append(
            Experience(
                pedestrian=ident,
                closest_m=float(gap.min()),
                personal_space_s=float(dt[gap < model.personal_space_m].sum()),
                abrupt=float(abrupt[near].max()) if near.any() else 0.0,
            )
        )
    return lived


def yes_probability(experience: Experience, tolerance: float, model: ParticipantModel) -> float:
    """The chance this participant calls the run socially compliant."""
    if experience.contact:
        return model.yes_after_contact
    logit = (
        model.baseline
        - model.per_metre_closer * max(0.0, model.personal_space_m - experience.closest_m)
        - model.per_second_in_personal_space * experience.personal_space_s
        - model.per_abrupt_unit * experience.abrupt
        + tolerance
    )
    return float(expit(logit))


def participant_name(index: int) -> str:
    return f"S{index + 1:02d}"


def run_key(run_code: str) -> int:
    """A run code as an integer, to seed a run's draws independently of the order runs are simulated in."""
    return int.from_bytes(run_code.encode(), "big")


def judge_run(log: RunLog, run_code: str, seed: int, participants: int | None = None, model: ParticipantModel = ParticipantModel()) -> list[Judgment]:
    """Seeded judgments of one run: the same seed, run and count always give the same answers."""
    lived = experiences(log, model) or [Experience(None, float("inf"), 0.0, 0.0)]
    count = len(lived) if participants is None else participants
    judgments = []
    for index in range(count):
        tolerance = model.tolerance_sd * np.random.default_rng([seed, index]).standard_normal()
        experience = lived[index % len(lived)]
        probability = yes_probability(experience, float(tolerance), model)
        draw = np.random.default_rng([seed, run_key(run_code), index]).random()
        judgments.append(Judgment(participant_name(index), bool(draw < probability), probability, experience))
    return judgments
