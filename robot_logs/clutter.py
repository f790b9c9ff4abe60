"""Seeded clutter for the simulated lidar: furniture legs, pillars and walls, so a tracking
benchmark on simulated scans measures the rejection of things that look like legs.

Tables stand on four legs at the corners of their top, chairs on four thinner ones, benches and
trestles on pairs; pillars are wide round posts; walls close the room and stick out into it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Clutter:
    """Static objects in the world frame: (K, 2) post centres with (K,) radii, (W, 2, 2) walls."""

    centres: np.ndarray
    radii: np.ndarray
    walls: np.ndarray


def _legs(corner: np.ndarray, size: tuple[float, float], yaw: float, count: int) -> np.ndarray:
    """Leg positions of a piece of furniture: `count` 4 at the corners, 2 at one side's ends."""
    length, depth = size
    local = np.array([[0.0, 0.0], [length, 0.0], [0.0, depth], [length, depth]])[:count]
    rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    return corner + local @ rotation.T


def furnished_room(
    seed: int,
    area: tuple[float, float, float, float] = (1.0, 8.0, -3.5, 3.5),
    tables: int = 3,
    chairs: int = 6,
    benches: int = 2,
    pillars: int = 2,
) -> Clutter:
    """A room around `area` (x_min, x_max, y_min, y_max, m) with furniture placed at random in it.

    Table legs are 5 cm across on a 1.2 x 0.8 m top, chair legs 3 cm on 0.45 m, bench legs
    6 cm in pairs 0.5 m apart, pillars 0.3-0.5 m across; three walls close the room 1 m
    beyond the area and two wall pieces stick out into it. `seed` decides the layout.
    """
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = area
    centres, radii = [], []
    kinds = [((1.2, 0.8), 4, 0.025)] * tables + [((0.45, 0.45), 4, 0.015)] * chairs + [((0.5, 0.0), 2, 0.03)] * benches
    for size, count, radius in kinds:
        corner = rng.uniform([x0, y0], [x1 - 1.0, y1 - 1.0])
        legs = _legs(corner, size, float(rng.uniform(0.0, math.pi)), count)
        centres.append(legs)
        radii.append(np.full(count, radius))
    centres.append(rng.uniform([x0, y0], [x1, y1], (pillars, 2)))
    radii.append(rng.uniform(0.15, 0.25, pillars))
    far, left, right = x1 + 1.0, y1 + 1.0, y0 - 1.0
    walls = [
        [[far, right], [far, left]],
        [[0.0, left], [far, left]],
        [[0.0, right], [far, right]],
    ]
    for _ in range(2):
        x = float(rng.uniform(x0 + 1.0, x1))
        side = left if rng.random() < 0.5 else right
        walls.append([[x, side], [x, side - math.copysign(float(rng.uniform(0.5, 1.5)), side)]])
    return Clutter(np.concatenate(centres), np.concatenate(radii), np.array(walls, dtype=float))
