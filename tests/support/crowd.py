"""Synthetic walkers with known positions: ground truth for testing detection and tracking.

Each pedestrian walks at its own speed toward a random way-point in a rectangle and picks a
new one on arrival. People do not avoid each other, so crossings and occlusions happen as
they do in real crowds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Crowd:
    """Ground truth of a walk: (T,) times (s), (T, N, 2) positions and velocities."""

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    seed: int


def walking_crowd(
    people: int,
    duration: float,
    rate_hz: float = 10.0,
    area: tuple[float, float, float, float] = (1.0, 8.0, -3.5, 3.5),
    speed: tuple[float, float] = (0.8, 1.5),
    seed: int = 0,
) -> Crowd:
    """Walk `people` pedestrians for `duration` seconds, sampled at `rate_hz`.

    Args:
        people: number of pedestrians.
        duration: seconds to simulate.
        rate_hz: samples per second (the lidar's scan rate).
        area: (x_min, x_max, y_min, y_max) rectangle they walk in (m).
        speed: (min, max) walking speed (m/s), drawn once per person.
        seed: seeds start points, way-points and speeds.
    """
    rng = np.random.default_rng(seed)
    low, high = np.array([area[0], area[2]]), np.array([area[1], area[3]])
    position = rng.uniform(low, high, (people, 2))
    goal = rng.uniform(low, high, (people, 2))
    pace = rng.uniform(*speed, people)
    steps = int(round(duration * rate_hz))
    dt = 1.0 / rate_hz
    positions, velocities = np.empty((steps, people, 2)), np.empty((steps, people, 2))
    for k in range(steps):
        to_goal = goal - position
        distance = np.hypot(to_goal[:, 0], to_goal[:, 1])
        arrived = distance < pace * dt
        goal[arrived] = rng.uniform(low, high, (int(arrived.sum()), 2))
        to_goal = goal - position
        distance = np.maximum(np.hypot(to_goal[:, 0], to_goal[:, 1]), 1e-9)
        velocity = to_goal / distance[:, None] * pace[:, None]
        positions[k], velocities[k] = position, velocity
        position = position + velocity * dt
    return Crowd(np.arange(steps) * dt, positions, velocities, seed)
