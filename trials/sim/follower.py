"""From a controller's timed way-points to velocity commands: a time-indexed pure-pursuit follower.

The plan is a path in time (the robot's position when the plan arrived, then one way-point every
`plan.step` seconds). At each physics step the follower aims at the plan's point `lookahead_s`
ahead in time and picks the motion that reaches it:

- the point is (almost) where the robot stands: stop (a plan that holds still, or a turn in place
  the way-points cannot show);
- it lies close behind: back up toward it (the lattice's backward moves);
- it lies far to the side or behind: turn in place toward it;
- otherwise: pure pursuit, at the speed that reaches the point in time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trials.controllers.base import Plan
from trials.sim.robot import RobotLimits, RobotState


@dataclass(frozen=True)
class FollowerParams:
    """Follower constants (s, m, rad).

    Attributes:
        lookahead_s: how far ahead along the plan's time the follower aims.
        stop_radius_m: a target nearer than this means standing still.
        turn_in_place_rad: bearings beyond this turn the robot on the spot first.
        reverse_bearing_rad: targets beyond this bearing and within `reverse_reach_m` are backed up to.
        heading_gain: turn rate per radian of bearing when turning in place (1/s).
    """

    lookahead_s: float = 0.6
    stop_radius_m: float = 0.05
    turn_in_place_rad: float = math.radians(60.0)
    reverse_bearing_rad: float = math.radians(130.0)
    reverse_reach_m: float = 0.6
    heading_gain: float = 2.5


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class WaypointFollower:
    """Tracks the latest plan; `command` gives (v, w) for the robot's current state."""

    def __init__(self, limits: RobotLimits, params: FollowerParams = FollowerParams()) -> None:
        self.limits = limits
        self.params = params
        self._times = np.zeros(1)
        self._path = np.zeros((1, 2))
        self._start = 0.0

    def follow(self, time: float, position: np.ndarray, plan: Plan) -> None:
        """Start following `plan`, received at `time` with the robot at `position`."""
        waypoints = np.asarray(plan.waypoints, dtype=float).reshape(-1, 2)
        self._path = np.vstack([np.asarray(position, dtype=float)[None, :2], waypoints])
        self._times = plan.step * np.arange(len(self._path))
        self._start = time

    def target(self, time: float) -> np.ndarray:
        """(2,) the plan's point `lookahead_s` after `time` (its last point once the plan runs out)."""
        ahead = time - self._start + self.params.lookahead_s
        return np.array([np.interp(ahead, self._times, self._path[:, k]) for k in (0, 1)])

    def command(self, time: float, state: RobotState) -> tuple[float, float]:
        """Linear and angular velocity toward the current target."""
        p, limits = self.params, self.limits
        offset = self.target(time) - state.position
        distance = float(np.hypot(*offset))
        if distance < p.stop_radius_m:
            return 0.0, 0.0
        bearing = _wrap(math.atan2(offset[1], offset[0]) - state.theta)
        speed = distance / p.lookahead_s
        if abs(bearing) > p.reverse_bearing_rad and distance < p.reverse_reach_m:
            v = min(speed, limits.max_reverse_speed)
            return -v, 2.0 * v * math.sin(_wrap(bearing - math.pi)) / distance
        if abs(bearing) > p.turn_in_place_rad:
            return 0.0, float(np.clip(p.heading_gain * bearing, -limits.max_turn_rate, limits.max_turn_rate))
        v = min(speed, limits.max_speed) * math.cos(bearing)
        return v, 2.0 * v * math.sin(bearing) / distance
