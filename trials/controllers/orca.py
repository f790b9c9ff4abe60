"""ORCA as a controller: optimal reciprocal collision avoidance (van den Berg, Guy, Lin & Manocha, "Reciprocal n-Body
Collision Avoidance", Robotics Research, 2011), the reactive baseline CrowdNav and most crowd-navigation studies use.

Each neighbour (a tracked person, or a near point of the static world) forbids the robot's velocities that would
bring the two discs into contact within the time horizon: the truncated cone of relative velocities, its apex at the
origin, its axis toward the neighbour. With u the smallest change of the relative velocity that leaves the cone and n
the cone's outward normal where u ends, the robot keeps the half-plane {v : (v - (v_robot + c u)) . n >= 0}, taking
the share c = 1/2 of the avoidance from a person (the paper's reciprocity: people step aside too) and all of it from
a wall. The new velocity is the one in every half-plane and within the robot's speed nearest to the preferred velocity
(full speed toward the goal): a two-dimensional program solved exactly by adding the half-planes one at a time (the
optimum moves only when a half-plane cuts it off, and then onto that half-plane's line). When no velocity satisfies
them all, the one that least violates the worst of them is taken (a linear program, `scipy.optimize.linprog`).
The way-points follow that velocity for the prediction horizon; the path follower turns the robot onto it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.physical import ROBOT_SPEED_M_S, STEP_S, T_PRED
from trials.controllers.base import Observation, Plan
from trials.controllers.crowd_now import PERSON_RADIUS_M, ROBOT_RADIUS_M, along, crowd_now
from trials.controllers.registry import ORCA

#: Time horizons (s): how far ahead contact with a person (CrowdNav's 5 s) and with the static world is avoided.
PERSON_HORIZON_S, WALL_HORIZON_S = 5.0, 2.0
#: Neighbours considered: the nearest this many people within this distance (m), as RVO2's defaults in CrowdNav.
NEIGHBOURS, NEIGHBOUR_RANGE_M = 10, 10.0
#: The robot's share of avoiding a person (the paper's reciprocal 1/2) and a wall (all of it).
PERSON_SHARE, WALL_SHARE = 0.5, 1.0
#: Sides of the polygon standing for the speed disc in the least-violation program.
_DISC_SIDES = 64
_EPS = 1e-9


@dataclass(frozen=True)
class HalfPlane:
    """The velocities v with (v - point) . normal >= 0; `normal` is a unit vector."""

    point: np.ndarray
    normal: np.ndarray

    def violation(self, velocity: np.ndarray) -> float:
        """How far `velocity` lies outside the half-plane (<= 0 inside)."""
        return float((self.point - velocity) @ self.normal)


def half_plane(offset: np.ndarray, relative_velocity: np.ndarray, radius: float, horizon_s: float, velocity: np.ndarray,
               share: float, step_s: float = STEP_S) -> HalfPlane:
    """The ORCA half-plane of a robot with `velocity` for a neighbour at `offset` (neighbour minus robot) moving with
    `relative_velocity` (robot minus neighbour) relative to it, the two discs' radii summing to `radius`. Discs already
    in contact are pushed apart within `step_s`."""
    p, v = np.asarray(offset, dtype=float), np.asarray(relative_velocity, dtype=float)
    distance2, radius2 = float(p @ p), radius * radius
    if distance2 > radius2:
        w = v - p / horizon_s  # from the centre of the cone's truncating disc to the relative velocity
        along_axis = float(w @ p)
        if along_axis < 0.0 and along_axis * along_axis > radius2 * float(w @ w):
            length = math.sqrt(float(w @ w))
            normal = w / length
            change = (radius / horizon_s - length) * normal
        else:
            leg = math.sqrt(distance2 - radius2)
            if p[0] * w[1] - p[1] * w[0] > 0.0:  # w left of the axis: the left leg, p turned anticlockwise
                side = np.array([p[0] * leg - p[1] * radius, p[0] * radius + p[1] * leg]) / distance2
                normal = np.array([-side[1], side[0]])
            else:
                side = np.array([p[0] * leg + p[1] * radius, -p[0] * radius + p[1] * leg]) / distance2
                normal = np.array([side[1], -side[0]])
            change = float(v @ side) * side - v
    else:
        w = v - p / step_s
        length = max(math.sqrt(float(w @ w)), _EPS)
        normal = w / length
        change = (radius / step_s - length) * normal
    return HalfPlane(np.asarray(velocity, dtype=float) + share * change, normal)


def best_velocity(planes: list[HalfPlane], preferred: np.ndarray, max_speed: float) -> tuple[np.ndarray, bool]:
    """The velocity of speed at most `max_speed` in every half-plane nearest to `preferred`, and True; when there is
    none, the one whose largest violation is least, and False."""
    preferred = np.asarray(preferred, dtype=float)
    speed = float(np.hypot(*preferred))
    result = preferred * (max_speed / speed) if speed > max_speed else preferred.copy()
    for i, plane in enumerate(planes):
        if plane.violation(result) > _EPS:
            found = _on_line(planes[:i], plane, preferred, max_speed)
            if found is None:
                return _least_violation(planes, max_speed), False
            result = found
    return result, True


def _on_line(earlier: list[HalfPlane], plane: HalfPlane, preferred: np.ndarray, max_speed: float) -> np.ndarray | None:
    """The point of `plane`'s boundary line inside the speed disc and every earlier half-plane nearest `preferred`."""
    direction = np.array([plane.normal[1], -plane.normal[0]])
    along_line = float(plane.point @ direction)
    room = along_line * along_line - float(plane.point @ plane.point) + max_speed * max_speed
    if room < 0.0:
        return None
    low, high = -along_line - math.sqrt(room), -along_line + math.sqrt(room)
    for other in earlier:
        facing = float(direction @ other.normal)
        needed = float((other.point - plane.point) @ other.normal)
        if abs(facing) < _EPS:
            if needed > _EPS:
                return None
            continue
        if facing > 0.0:
            low = max(low, needed / facing)
        else:
            high = min(high, needed / facing)
        if low > high + _EPS:
            return None
    t = min(max(float(direction @ (preferred - plane.point)), low), high)
    return plane.point + t * direction


def _least_violation(planes: list[HalfPlane], max_speed: float) -> np.ndarray:
    """The velocity in the speed disc (as a polygon of `_DISC_SIDES` sides) whose largest violation is least."""
    from scipy.optimize import linprog

    normals = np.array([plane.normal for plane in planes])
    points = np.array([plane.point for plane in planes])
    angles = np.linspace(0.0, 2.0 * math.pi, _DISC_SIDES, endpoint=False)
    # variables vx, vy, s: minimise s with (p_i - v) . n_i <= s and the disc's sides
    rows = np.vstack([np.column_stack([-normals, -np.ones(len(planes))]),
                      np.column_stack([np.cos(angles), np.sin(angles), np.zeros(_DISC_SIDES)])])
    bounds = np.concatenate([-(points * normals).sum(axis=1), np.full(_DISC_SIDES, max_speed * math.cos(math.pi / _DISC_SIDES))])
    found = linprog([0.0, 0.0, 1.0], A_ub=rows, b_ub=bounds, bounds=[(None, None)] * 3, method="highs")
    return np.asarray(found.x[:2], dtype=float) if found.status == 0 else np.zeros(2)


class OrcaController:
    """ORCA for the robot as a disc (the `Controller` protocol).

    Args:
        max_speed: the robot's speed, preferred toward the goal and never exceeded (m/s).
        radius: the robot's disc (m), by default the Husky's circumscribed circle.
    """

    name = ORCA

    def __init__(self, max_speed: float = ROBOT_SPEED_M_S, radius: float = ROBOT_RADIUS_M) -> None:
        self.max_speed, self.radius = max_speed, radius

    def details(self) -> dict[str, str]:
        return {"orca": f"horizons {PERSON_HORIZON_S:g} s (people) and {WALL_HORIZON_S:g} s (walls), radius {self.radius:.2f} m"}

    def half_planes(self, position: np.ndarray, velocity: np.ndarray, people: np.ndarray, people_velocity: np.ndarray,
                    walls: np.ndarray) -> list[HalfPlane]:
        """The half-planes of the nearest people, then of the wall points."""
        offsets = people - position
        near = np.argsort(np.hypot(*offsets.T), kind="stable")[:NEIGHBOURS]
        near = [i for i in near if math.hypot(*offsets[i]) <= NEIGHBOUR_RANGE_M]
        planes = [half_plane(offsets[i], velocity - people_velocity[i], self.radius + PERSON_RADIUS_M, PERSON_HORIZON_S,
                             velocity, PERSON_SHARE) for i in near]
        return planes + [half_plane(wall - position, velocity, self.radius, WALL_HORIZON_S, velocity, WALL_SHARE) for wall in walls]

    def plan(self, observation: Observation) -> Plan:
        now = crowd_now(observation)
        to_goal = now.goal - now.position
        distance = float(np.hypot(*to_goal))
        preferred = to_goal * (self.max_speed / distance) if distance > _EPS else np.zeros(2)
        planes = self.half_planes(now.position, now.velocity, now.people, now.people_velocity, now.walls)
        velocity, feasible = best_velocity(planes, preferred, self.max_speed)
        record = {"controller": self.name, "velocity": velocity.tolist(), "preferred": preferred.tolist(),
                  "half_planes": len(planes), "feasible": feasible}
        return Plan(along(now.position, np.repeat(velocity[None], T_PRED, axis=0)), STEP_S, record)
