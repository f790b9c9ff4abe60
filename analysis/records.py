"""Records of a study's results as the report reads them: outcome rows, human scores, judgments, runs.

The columns follow docs/study_folder.md: each CSV's columns are its record's fields, and one module of
`trials` reads and writes each file (`trials.outcomes`, `trials.scores`, `trials.responses`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.plan import PlanStatus
from designs.model import Model
from designs.spec import StudySpec

#: Sources of a participant's judgment.
HUMAN = "human"
SIMULATED = "simulated"
#: How a finished run was made (`StudyRun.origin`): simulated or driven live by the toolkit, or played from the log
#: of a robot the toolkit did not drive, whose judgments and scores are therefore not its arm's.
SIMULATED_RUN, LIVE_RUN, SOFTWARE_ROBOT_RUN, EXTERNAL_LOG = "simulated", "driven live", "software robot", "external log"


@dataclass(frozen=True)
class RunKey:
    """Which run an outcome is, how it ended ("goal", "collision", "timeout"), its seed and perception."""

    run_code: str
    status: str
    seed: int
    perception: str


@dataclass(frozen=True)
class RunMetrics:
    """A run's metrics, as `trials run` measures them (units in the names; None where a metric has
    no value: no time to goal without arriving, no minimum gap without pedestrians, no irregularity
    without moving)."""

    duration_s: float
    time_to_goal_s: float | None
    path_length_m: float
    min_distance_m: float | None
    time_within_0_5m_s: float
    time_within_1_2m_s: float
    collisions: int
    max_deceleration_mps2: float
    max_jerk_mps3: float
    path_irregularity_rad_per_m: float | None
    turn_in_place_s: float
    backing_up_s: float
    stopped_s: float


@dataclass(frozen=True)
class Outcome(RunMetrics, RunKey):
    """One row of outcomes.csv. Its fields are the file's columns in order: `RunKey`'s, then
    `RunMetrics`', then the controller (None, and no column, in a blinded study), the finish time, and
    the settings the run was made with (`trials.run_settings`; None in a row written before they were
    recorded, and noise, dropout and timeout None for a trial played from a robot log)."""

    controller: str | None = field(default=None, kw_only=True)
    finished_utc: str
    noise_std_m: float | None = field(default=None, kw_only=True)
    dropout: float | None = field(default=None, kw_only=True)
    timeout_s: float | None = field(default=None, kw_only=True)
    weights: str | None = field(default=None, kw_only=True)


@dataclass(frozen=True)
class HumanScore:
    """One evaluator's 1-2-3 score of a run (a row of scores.csv)."""

    run_code: str
    score: int
    scorer: str
    note: str
    recorded_utc: str


@dataclass(frozen=True)
class Response:
    """One participant's judgment of a run (a row of responses.csv); `seed` only when simulated."""

    run_code: str
    participant: str
    compliant: bool
    source: str
    recorded_utc: str
    seed: int | None = None


@dataclass(frozen=True)
class StudyRun:
    """A planned run: its plan row, the arm it belongs to as the report may name it, its results and how it was made."""

    order: int
    code: str
    values: dict[str, str]
    arm: str
    outcome: Outcome | None
    log: Path | None
    origin: str = SIMULATED_RUN

    @property
    def finished(self) -> bool:
        return self.outcome is not None


@dataclass(frozen=True)
class Look:
    """One interim look at a blinded study's arms: when, how complete the study was, and why."""

    utc: str
    completeness: str
    reason: str


@dataclass(frozen=True)
class Blinding:
    """How the report may name arms.

    `factor` is the plan column that holds a run's arm (None when the study compares no
    controllers); `labels` maps its plan values to what the report shows: arm labels while
    blind, controller names once unblinded. `revealed` says this report opened the key, and
    `check` which check of the key it made; `unblinded_utc` lists every verified unblinding of
    the study so far.
    """

    blinded: bool
    factor: str | None
    labels: dict[str, str]
    revealed: bool = False
    commitment: str | None = None
    unblinded_utc: tuple[str, ...] = ()
    check: str = ""
    #: This opening, or this interim look at the blinded arms: how complete the study was (e.g. "4 of 18 runs finished")
    #: and, for an interim one, why.
    completeness: str = ""
    interim: str | None = None
    #: `recorded_key` of every human score and judgment recorded when the key was first opened (None: not known, for a key
    #: opened by an earlier release, or never opened): what was recorded blind.
    recorded_before: frozenset[str] | None = None
    #: Every interim look at the blinded arms (`trials report --interim` without `--unblind`), this one included, oldest first.
    looks: tuple[Look, ...] = ()

    @property
    def looking(self) -> bool:
        """Whether this report is an interim look at the blinded arms (compared by label, the key closed)."""
        return self.blinded and not self.revealed and self.interim is not None

    @property
    def open(self) -> bool:
        """Whether the report may name controllers."""
        return not self.blinded or self.revealed

    @property
    def arm_word(self) -> str:
        return "Controller" if self.open else "Arm"


def recorded_key(record: HumanScore | Response) -> str:
    """A score or judgment as the record of the key's first opening lists it: run, who, and when it was recorded."""
    who = record.scorer if isinstance(record, HumanScore) else record.participant
    return f"{type(record).__name__}|{record.run_code}|{who}|{record.recorded_utc}"


@dataclass(frozen=True)
class LiveCheck:
    """A live run's latest check (`trials.live_checks`): how it ended, the people its row asked for and the most tracked at
    once, why it is flagged (empty: it went as planned), and the operator's decision on a flagged run (stands or rerun,
    with a reason; empty: undecided)."""

    run_code: str
    recorded_utc: str
    ending: str
    asked: int | None
    seen: int | None
    seen_at_s: float | None
    #: Whether the row's condition was met (None: the run recorded no count, e.g. its worker died).
    condition_met: bool | None
    flag: str
    decision: str = ""
    reason: str = ""

    @property
    def undecided(self) -> bool:
        return bool(self.flag) and not self.decision


#: What a pre-registration binds (`trials.preregistration`), by the names its Bindings section gives them.
DESIGN_BINDING, PLAN_BINDING, KEY_BINDING = "design", "analysis plan", "sealed key"


@dataclass(frozen=True)
class Registration:
    """A study's pre-registration (`trials.preregistration`): its file, the file's SHA-256, and which of what it binds
    (DESIGN_BINDING, PLAN_BINDING, KEY_BINDING) the study's files no longer match."""

    file: str
    digest: str
    differs: tuple[str, ...]
    #: Whether the digest matches the one recorded outside the study (`--commitment`); None when none was given.
    recorded: bool | None = None


@dataclass(frozen=True)
class StudyData:
    """Everything the report needs from a study folder."""

    root: Path
    spec: StudySpec
    model: Model
    seed: int | None
    runs: list[StudyRun]
    scores: list[HumanScore]
    responses: list[Response]
    blinding: Blinding
    correlations: tuple[list[str], list[list[float | None]]]
    #: design.json's "diagnostics": efficiencies, the bound, power (empty when the file has none).
    diagnostics: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: The analysis plan and its standing against design.json's commitment (None: the report's defaults for the spec).
    analysis_plan: PlanStatus | None = None
    #: Every live run's manipulation checks, each with the operator's decision on it, in the order they were made.
    checks: list[LiveCheck] = field(default_factory=list)
    #: The pre-registration and how the study stands against it (None: a study designed before pre-registrations).
    registration: Registration | None = None

    @property
    def finished(self) -> list[StudyRun]:
        return [run for run in self.runs if run.finished]

    @property
    def compared(self) -> list[StudyRun]:
        """The finished runs that the toolkit drove: those whose results count for their arm in comparisons and fits."""
        return [run for run in self.finished if run.origin != EXTERNAL_LOG]

    @property
    def unfinished(self) -> list[StudyRun]:
        return [run for run in self.runs if not run.finished]
