"""Helbing & Molnar's social force model (Phys. Rev. E 51, 4282, 1995), with a robot among the people.

Each pedestrian a feels

    F_a = (v0_a e_a - v_a) / tau                       driving force toward its goal
        + sum_b w(e_a, -f_ab) f_ab                     repulsion from every other pedestrian b
        + w(e_a, -f_aR) f_aR                           repulsion from the robot R
        + xi                                           a small seeded fluctuation

with f_ab = -grad_r V(b(r)), V(b) = V0 exp(-b / sigma), where b is the semi-minor axis of the ellipse
through a's position with foci at b's position and at b's next step (so people keep more room in
front of someone walking than behind): 2b = sqrt((|r| + |r - s e_b|)^2 - s^2), r = r_a - r_b,
s = |v_b| lookahead. Forces from behind (outside the view cone of half-angle phi about a's desired
direction) count with weight c < 1. For the robot, r runs from the nearest point of its footprint,
so its size counts, and its step can be shortened per pedestrian (see `social_acceleration`).
Speeds are capped at 1.3 times each pedestrian's preferred speed.

One addition: with these forces alone two bodies meeting exactly head-on stop face to face (the
repulsion has no sideways part), where people step aside early. So the part of each repulsion
that opposes a pedestrian's desired direction is also applied sideways (times `evasion`), toward
the side of the source the pedestrian already is on (more than `TIE_M` off its line), else to
the right, much as later models turn an encounter sideways (compare the angular interaction of
Moussaid et al., Proc. R. Soc. B 276, 2009).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Within this distance (m) of a source's line a pedestrian steps aside to the right.
TIE_M = 0.1


@dataclass(frozen=True)
class SocialForceParams:
    """The model's constants; defaults are Helbing & Molnar's, the robot's repulsion is stronger.

    Attributes:
        relaxation_s: tau, how fast a pedestrian returns to its desired velocity (s).
        strength: V0, pedestrian-pedestrian potential at zero distance (m^2/s^2).
        range_m: sigma, the potential's decay length (m).
        robot_strength, robot_range_m: the same for the robot (people keep clear of machines).
        lookahead_s: the step (s) of the other's motion that stretches its ellipse.
        view_angle_rad: 2 phi, the field of view in which forces count fully.
        behind_weight: c, the weight of forces from outside the field of view.
        max_speed_factor: the cap on speed, as a multiple of the preferred speed.
        fluctuation: standard deviation of the random acceleration (m/s^2).
        evasion: the sideways step-aside force per unit of repulsion opposing the desired direction.
    """

    relaxation_s: float = 0.5
    strength: float = 2.1
    range_m: float = 0.3
    robot_strength: float = 6.0
    robot_range_m: float = 0.4
    lookahead_s: float = 2.0
    view_angle_rad: float = math.radians(200.0)
    behind_weight: float = 0.5
    max_speed_factor: float = 1.3
    fluctuation: float = 0.1
    evasion: float = 1.0


def ellipse_repulsion(r: np.ndarray, step: np.ndarray, strength: float, range_m: float) -> np.ndarray:
    """(..., 2) force -grad_r V(b) for relative positions r and the others' steps s e_b (both (..., 2))."""
    shifted = r - step
    d1 = np.linalg.norm(r, axis=-1)
    d2 = np.linalg.norm(shifted, axis=-1)
    s = np.linalg.norm(step, axis=-1)
    b = 0.5 * np.sqrt(np.maximum((d1 + d2) ** 2 - s**2, 1e-12))
    b = np.maximum(b, 1e-3)
    grad_b = ((d1 + d2) / (4.0 * b))[..., None] * (
        r / np.maximum(d1, 1e-9)[..., None] + shifted / np.maximum(d2, 1e-9)[..., None]
    )
    return (strength / range_m) * np.exp(-b / range_m)[..., None] * grad_b


def view_weight(direction: np.ndarray, force: np.ndarray, params: SocialForceParams) -> np.ndarray:
    """(...,) 1 where the source of `force` lies within the view cone about `direction`, else c."""
    toward_source = -force
    norm = np.linalg.norm(force, axis=-1)
    in_view = np.einsum("...d,...d->...", direction, toward_source) >= norm * math.cos(params.view_angle_rad / 2.0)
    return np.where(in_view, 1.0, params.behind_weight)


def evasion(force: np.ndarray, direction: np.ndarray, offset: np.ndarray, params: SocialForceParams) -> np.ndarray:
    """(..., 2) the sideways part added to repulsions `force` on walkers heading `direction`, whose
    positions relative to the sources' centres are `offset`."""
    opposing = np.maximum(-np.einsum("...d,...d->...", force, direction), 0.0)
    left = np.stack([-direction[..., 1], direction[..., 0]], axis=-1)
    side = np.where(np.einsum("...d,...d->...", left, offset) > TIE_M, 1.0, -1.0)
    return (params.evasion * opposing * side)[..., None] * left


def social_acceleration(
    positions: np.ndarray,
    velocities: np.ndarray,
    desired: np.ndarray,
    robot_points: np.ndarray | None,
    robot_centre: np.ndarray,
    robot_velocity: np.ndarray,
    robot_lookahead_s: np.ndarray,
    params: SocialForceParams,
) -> np.ndarray:
    """(N, 2) the repulsive accelerations (pedestrians and robot) on each pedestrian.

    Args:
        positions, velocities: (N, 2) the pedestrians' state.
        desired: (N, 2) each one's desired direction e_a (unit, or zero when standing).
        robot_points: (N, 2) the nearest point of the robot's footprint to each pedestrian, or
            None for no robot.
        robot_centre: (2,) the robot's position (which side of it a pedestrian is on).
        robot_velocity: (2,) the robot's velocity.
        robot_lookahead_s: (N,) how far ahead in time each pedestrian keeps clear of the robot's
            path (the lookahead, or 0 for someone who only keeps clear of its body).
    """
    n = len(positions)
    total = np.zeros((n, 2))
    if n > 1:
        r = positions[:, None, :] - positions[None, :, :]
        step = np.broadcast_to(velocities[None, :, :] * params.lookahead_s, r.shape)
        forces = ellipse_repulsion(r, step, params.strength, params.range_m)
        forces *= view_weight(desired[:, None, :], forces, params)[..., None]
        forces += evasion(forces, np.broadcast_to(desired[:, None, :], r.shape), r, params)
        forces[np.arange(n), np.arange(n)] = 0.0
        total += forces.sum(axis=1)
    if robot_points is not None and n:
        r = positions - robot_points
        step = np.asarray(robot_velocity, dtype=float)[None, :] * np.asarray(robot_lookahead_s, dtype=float)[:, None]
        forces = ellipse_repulsion(r, step, params.robot_strength, params.robot_range_m)
        forces *= view_weight(desired, forces, params)[:, None]
        total += forces + evasion(forces, desired, positions - robot_centre, params)
    return total


def driving_acceleration(velocities: np.ndarray, desired: np.ndarray, speeds: np.ndarray, params: SocialForceParams) -> np.ndarray:
    """(N, 2) (v0 e - v) / tau: the pull toward each pedestrian's desired velocity."""
    return (speeds[:, None] * desired - velocities) / params.relaxation_s


def cap_speed(velocities: np.ndarray, preferred: np.ndarray, params: SocialForceParams) -> np.ndarray:
    """Velocities scaled down to at most max_speed_factor times each preferred speed."""
    speed = np.linalg.norm(velocities, axis=-1)
    limit = params.max_speed_factor * preferred
    scale = np.where(speed > limit, limit / np.maximum(speed, 1e-12), 1.0)
    return velocities * scale[:, None]
