"""The protective field: a safety scanner's rule, computed from the robot's own laser for every live run.

Each valid return of a scan (a finite range within the laser's limits) is placed in the base frame. A return inside the
footprint grown by `margin` stops the robot, turning included; a return inside the footprint itself is ignored, since
only the robot's own body can be there (as a laser filter's box would drop it). Ahead of the footprint in the
direction of travel, within its width grown by the margin, the nearest return limits the speed to the one from which
the base, after `reaction_time` at that speed and then braking at `deceleration`, stops `margin` short of it:

    v_max(d) = -a t + sqrt((a t)^2 + 2 a (d - margin)),   d = the return's distance ahead of the footprint's edge

so the robot slows as it nears a wall, a stall or a person and stops before touching, whatever the controller plans.
Below `CREEP_M_S` the allowed speed is taken as zero: the robot stops cleanly about a centimetre beyond the margin
rather than creeping toward it, and a controller held there is told so (`blocks`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.records import Scan
from trials.sim.robot import RobotLimits

#: Allowed speeds under this (m/s) are zero.
CREEP_M_S = 0.05

def valid_returns(scan: Scan) -> np.ndarray:
    """(B,) whether each beam returned a range: finite and within [range_min, range_max] (REP 117: +inf is no return, NaN a
    failed beam); a scan whose limits are not a finite positive interval has none."""
    ranges = np.asarray(scan.ranges, dtype=float)
    if not (math.isfinite(scan.range_min) and math.isfinite(scan.range_max) and 0.0 <= scan.range_min < scan.range_max):
        return np.zeros(len(ranges), dtype=bool)
    with np.errstate(invalid="ignore"):
        return np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)


def returns_in(scan: Scan, laser: Pose2D) -> np.ndarray:
    """(N, 2) the scan's valid returns in the frame where the laser stands at `laser`."""
    valid = valid_returns(scan)
    ranges = np.asarray(scan.ranges, dtype=float)[valid]
    bearings = scan.angle_min + scan.angle_increment * np.flatnonzero(valid)
    local = np.column_stack((ranges * np.cos(bearings), ranges * np.sin(bearings)))
    return laser.apply(local).reshape(-1, 2)


@dataclass(frozen=True)
class FieldReading:
    """What one scan allows: the highest forward and backward speeds (m/s, both >= 0), whether a return lies in the margin
    around the footprint (then nothing may move), and the nearest returns' distances ahead of and behind the footprint (m)."""

    forward: float
    backward: float
    inside: bool
    ahead_m: float
    behind_m: float

    def limit(self, linear: float, angular: float) -> tuple[float, float]:
        """A velocity command held within what the field allows."""
        if self.inside:
            return 0.0, 0.0
        return float(np.clip(linear, -self.backward, self.forward)), angular

    def blocks(self, linear: float) -> bool:
        """Whether the field holds the robot still against a wanted linear speed."""
        return self.inside or (linear > 0.0 and self.forward <= 0.0) or (linear < 0.0 and self.backward <= 0.0)

    def describe(self) -> str:
        if self.inside:
            return "a laser return within the protective margin of the footprint"
        return f"a laser return {min(self.ahead_m, self.behind_m):.2f} m from the footprint in the direction of travel"


#: What a scan with no return near the robot allows.
OPEN = FieldReading(math.inf, math.inf, False, math.inf, math.inf)


@dataclass(frozen=True)
class ProtectiveField:
    """The field of a rectangular base (`limits`' footprint, centred on the base frame) with its margin (m), the time it
    travels before braking (s) and its braking deceleration (m/s^2)."""

    limits: RobotLimits
    margin: float
    reaction_time: float
    deceleration: float

    def read(self, points: np.ndarray) -> FieldReading:
        """The field for (N, 2) returns in the base frame."""
        half_length, half_width, margin = self.limits.half_length, self.limits.half_width, self.margin
        x, y = np.asarray(points, dtype=float).reshape(-1, 2).T
        body = (np.abs(x) <= half_length) & (np.abs(y) <= half_width)
        lane = (np.abs(y) <= half_width + margin) & ~body
        ahead = np.min(x[lane & (x > 0.0)] - half_length, initial=math.inf)
        behind = np.min(-x[lane & (x < 0.0)] - half_length, initial=math.inf)
        grown = (np.abs(x) <= half_length + margin) & (np.abs(y) <= half_width + margin) & ~body
        return FieldReading(self.speed(ahead), self.speed(behind), bool(grown.any()), float(ahead), float(behind))

    def speed(self, distance: float) -> float:
        """The highest speed from which the base stops `margin` short of a return `distance` m ahead of its edge."""
        free = distance - self.margin
        if free <= 0.0:
            return 0.0
        if math.isinf(free):
            return math.inf
        reach = self.deceleration * self.reaction_time
        speed = -reach + math.sqrt(reach * reach + 2.0 * self.deceleration * free)
        return speed if speed >= CREEP_M_S else 0.0
