"""The social force model as a controller: the robot walks to its goal as a pedestrian of Helbing & Molnar (Phys. Rev. E
51, 4282, 1995) would, the baseline CrowdNav and SocNavBench compare against.

Each plan integrates, over the prediction horizon, the robot's acceleration

    a = (v0 e - v) / tau                          pull toward the goal at the robot's speed v0
      + sum_p w(e, -f_p) f_p + evasion            each tracked person's elliptical repulsion (`trials.sim.social_force`),
                                                  the person walking on at its tracked velocity
      + sum_w (U0 / R) exp(-(d_w - r) / R) n_w    each near wall point's exponential repulsion

with the people's repulsion the gradient of their potential taken from the robot's surface (its circumscribed disc and
the person's, so the ellipse's semi-minor axis b is of the gap between the two) and the
pedestrian constants the simulator's crowd uses, so the robot keeps the room people keep from each other; the walls'
U0 = 10 m^2/s^2 and R = 0.2 m are Helbing & Molnar's. The way-points are where the robot is every 0.4 s.
"""

from __future__ import annotations

import numpy as np

from robot_logs.physical import ROBOT_SPEED_M_S, STEP_S, T_PRED
from trials.controllers.base import Observation, Plan
from trials.controllers.crowd_now import PERSON_RADIUS_M, ROBOT_RADIUS_M, CrowdNow, crowd_now
from trials.controllers.registry import SOCIAL_FORCE
from trials.sim.social_force import SocialForceParams, ellipse_repulsion, evasion, view_weight

#: Helbing & Molnar's wall potential: strength U0 (m^2/s^2) and range R (m).
WALL_STRENGTH, WALL_RANGE_M = 10.0, 0.2
#: The closest two surfaces are taken to be (m), so a repulsion stays finite when they touch.
MIN_GAP_M = 0.01


class SocialForceController:
    """The robot as a social-force walker (the `Controller` protocol).

    Args:
        params: the pedestrian constants (tau, V0, sigma, the lookahead, the view cone, the evasion).
        speed: v0, the robot's desired speed (m/s), also its cap.
        dt: the integration step (s); a step of 0.4 s is split into whole steps of about this.
    """

    name = SOCIAL_FORCE

    def __init__(self, params: SocialForceParams | None = None, speed: float = ROBOT_SPEED_M_S, dt: float = 0.05) -> None:
        self.params, self.speed = params or SocialForceParams(), speed
        self.substeps = max(1, round(STEP_S / dt))

    def details(self) -> dict[str, str]:
        p = self.params
        return {"social_force": f"tau {p.relaxation_s:g} s, V0 {p.strength:g}, sigma {p.range_m:g} m, v0 {self.speed:g} m/s"}

    def plan(self, observation: Observation) -> Plan:
        now = crowd_now(observation)
        dt = STEP_S / self.substeps
        position, velocity = now.position.copy(), now.velocity.copy()
        waypoints, first = [], None
        for k in range(T_PRED * self.substeps):
            people = now.people + now.people_velocity * (k * dt)
            forces = self.forces(position, velocity, now, people)
            first = forces if first is None else first
            velocity = velocity + sum(forces.values()) * dt
            norm = float(np.hypot(*velocity))
            velocity = velocity * min(1.0, self.speed / norm) if norm > 0 else velocity
            position = position + velocity * dt
            if (k + 1) % self.substeps == 0:
                waypoints.append(position.copy())
        assert first is not None
        record = {"controller": self.name, **{name: force.tolist() for name, force in first.items()}}
        return Plan(np.array(waypoints), STEP_S, record)

    def forces(self, position: np.ndarray, velocity: np.ndarray, now: CrowdNow, people: np.ndarray) -> dict[str, np.ndarray]:
        """The accelerations on the robot at `position` with `velocity`, the people at `people`: driving, people, walls."""
        p = self.params
        to_goal = now.goal - position
        distance = float(np.hypot(*to_goal))
        desired = to_goal / distance if distance > 1e-9 else np.zeros(2)
        driving = (self.speed * desired - velocity) / p.relaxation_s
        social = np.zeros(2)
        if len(people):
            r = position - people
            centres = np.maximum(np.hypot(*r.T), 1e-9)
            gaps = centres - ROBOT_RADIUS_M - PERSON_RADIUS_M
            scale = np.maximum(gaps, MIN_GAP_M) / centres
            pushes = ellipse_repulsion(r * scale[:, None], now.people_velocity * p.lookahead_s, p.strength, p.range_m)
            # minus the gradient with respect to the robot's position: the surface vector r (|r| - radii) / |r| keeps
            # the radial part of a change of r and scales its tangential part by (|r| - radii) / |r|
            radial = r / centres[:, None]
            along = np.where(gaps > MIN_GAP_M, 1.0, scale)[:, None] * (pushes * radial).sum(axis=1, keepdims=True) * radial
            pushes = along + scale[:, None] * (pushes - (pushes * radial).sum(axis=1, keepdims=True) * radial)
            pushes *= view_weight(np.broadcast_to(desired, pushes.shape), pushes, p)[:, None]
            pushes += evasion(pushes, np.broadcast_to(desired, pushes.shape), r, p)
            social = pushes.sum(axis=0)
        walls = np.zeros(2)
        if len(now.walls):
            r = position - now.walls
            centres = np.maximum(np.hypot(*r.T), 1e-9)
            size = (WALL_STRENGTH / WALL_RANGE_M) * np.exp(-np.maximum(centres - ROBOT_RADIUS_M, MIN_GAP_M) / WALL_RANGE_M)
            walls = (size / centres) @ r
        return {"driving": driving, "people": social, "walls": walls}
