"""The paper's 1-2-3 rubric applied automatically to a finished run, from its outcome row and log.

1: a collision. 2: no collision, but unnatural behaviour: turning in place, backing up, stopping,
hesitating, passing within intimate distance, or not reaching the goal in time. 3: natural and
comfortable. The thresholds are a `Rubric`; a study overrides them in `rubric.toml`:

    [rubric]
    intimate_distance_m = 0.5
    turn_in_place_s = 1.0
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from numbers import Real
from pathlib import Path

import numpy as np

from analysis.errors import AnalysisError
from analysis.records import Outcome
from analysis.run_log import RunLog
from robot_logs.physical import INTIMATE_M

#: Below this speed (m/s) the robot stands still (the outcome row's definition).
STANDSTILL_MPS = 0.05


@dataclass(frozen=True)
class Rubric:
    """Thresholds of the automatic score; a run breaking any of them scores 2 (see `unnatural_rules`)."""

    intimate_distance_m: float = INTIMATE_M
    turn_in_place_s: float = 1.0
    backing_up_s: float = 0.5
    stopped_s: float = 1.0
    hesitation_speed_fraction: float = 0.4
    hesitation_min_s: float = 1.0
    hesitations: int = 1

    def unnatural_rules(self) -> list[str]:
        """The score-2 rules in words, with this rubric's numbers."""
        return [
            f"passed within {self.intimate_distance_m:g} m of a pedestrian (minimum gap between footprint and body: intimate distance);",
            f"turned in place for more than {self.turn_in_place_s:g} s (|v| < 0.05 m/s, |w| > 0.3 rad/s);",
            f"backed up for more than {self.backing_up_s:g} s (v < -0.05 m/s);",
            f"stood still for more than {self.stopped_s:g} s after the first second (|v| < 0.05 m/s);",
            f"hesitated {self.hesitations} time(s) or more (from the log): its speed fell below {self.hesitation_speed_fraction:g} of its "
            f"cruising speed (90th percentile of v) for at least {self.hesitation_min_s:g} s without standing still, then picked up again;",
            "did not reach the goal in time (status `timeout`).",
        ]


@dataclass(frozen=True)
class AutoScore:
    """The rubric's score of one run and the reasons for anything below 3."""

    score: int
    reasons: tuple[str, ...]


def read_rubric(path: Path) -> Rubric:
    """A Rubric from the `[rubric]` table of a TOML file; AnalysisError names a bad key or value."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise AnalysisError(f"no rubric file at {path}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise AnalysisError(f"malformed {path.name}: {exc}") from None
    table = data.get("rubric")
    if not isinstance(table, dict):
        raise AnalysisError(f"{path.name}: expected a [rubric] table")
    known = {f.name: f.type for f in fields(Rubric)}
    values = {}
    for key, value in table.items():
        if key not in known:
            raise AnalysisError(f"{path.name}: unknown rubric key {key!r} (expected {', '.join(known)})")
        if isinstance(value, bool) or not isinstance(value, Real) or value < 0:
            raise AnalysisError(f"{path.name}: {key} must be a number >= 0, got {value!r}")
        values[key] = int(value) if key == "hesitations" else float(value)
    return replace(Rubric(), **values)


def hesitations(log: RunLog, rubric: Rubric) -> int:
    """Slow-downs from cruising speed that begin after the first second, last `hesitation_min_s` or more
    without coming to a standstill (|v| < 0.05 m/s: the stopping rule's job), and end with the robot
    picking up speed again; the start and the final approach do not count."""
    t, v = log.robot[:, 0], log.robot[:, 4]
    cruise = float(np.percentile(v, 90))
    if cruise < 0.1:
        return 0
    below = (v < rubric.hesitation_speed_fraction * cruise).astype(int)
    starts = np.flatnonzero(np.diff(below) == 1) + 1
    ends = np.flatnonzero(np.diff(below) == -1) + 1
    count = 0
    for start in starts[t[starts] >= 1.0]:
        later = ends[ends > start]
        if len(later) and t[later[0]] - t[start] >= rubric.hesitation_min_s and np.abs(v[start : later[0]]).min() >= STANDSTILL_MPS:
            count += 1
    return count


def score_run(outcome: Outcome, log: RunLog | None, rubric: Rubric) -> AutoScore:
    """Apply the rubric to one finished run; without a log the hesitation rule is skipped."""
    gap = math.inf if outcome.min_distance_m is None else outcome.min_distance_m
    if outcome.status == "collision" or outcome.collisions > 0 or gap <= 0.0:
        return AutoScore(1, ("collision",))
    reasons = []
    if gap < rubric.intimate_distance_m:
        reasons.append(f"passed within {outcome.min_distance_m:.2f} m")
    if outcome.turn_in_place_s > rubric.turn_in_place_s:
        reasons.append(f"turned in place {outcome.turn_in_place_s:.1f} s")
    if outcome.backing_up_s > rubric.backing_up_s:
        reasons.append(f"backed up {outcome.backing_up_s:.1f} s")
    if outcome.stopped_s > rubric.stopped_s:
        reasons.append(f"stood still {outcome.stopped_s:.1f} s")
    if log is not None:
        count = hesitations(log, rubric)
        if count >= rubric.hesitations:
            reasons.append(f"hesitated {count}x")
    if outcome.status == "timeout":
        reasons.append("timed out")
    return AutoScore(2 if reasons else 3, tuple(reasons))
