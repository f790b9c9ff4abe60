"""Pedestrians to a cost grid: the crowd planner's only picture of the world.

Each pedestrian is a disc of its body radius plus a comfort margin that the robot's footprint must
not touch (LETHAL); the disc grown by the robot's inscribed radius is where the robot's centre cannot
be in any orientation (INSCRIBED). Nothing else costs anything: the planner keeps clear, no more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FREE, INSCRIBED, LETHAL = 0, 1, 2
#: The thresholds that give these values their meaning in the planner (obstacle, inscribed, always
#: check the footprint).
OBSTHRESH, INSCRIBED_THRESH, CIRCUMSCRIBED_THRESH = LETHAL, INSCRIBED, 0


@dataclass(frozen=True)
class Window:
    """A grid of `width` x `height` cells of `cell_size` metres whose cell (0, 0) has its corner at `origin`."""

    origin: tuple[float, float]
    cell_size: float
    width: int
    height: int

    @classmethod
    def around(cls, points: np.ndarray, margin: float, cell_size: float) -> Window:
        """The smallest window on the world's cell lattice holding `points` (k, 2) with `margin` around them."""
        low = np.floor((points.min(axis=0) - margin) / cell_size).astype(int)
        high = np.ceil((points.max(axis=0) + margin) / cell_size).astype(int)
        return cls((float(low[0] * cell_size), float(low[1] * cell_size)), cell_size,
                   int(high[0] - low[0]), int(high[1] - low[1]))

    def to_local(self, xy: np.ndarray) -> np.ndarray:
        """World metres to window metres (cell (0, 0)'s corner at 0)."""
        return np.asarray(xy, dtype=np.float64) - np.asarray(self.origin)

    def to_world(self, xy: np.ndarray) -> np.ndarray:
        return np.asarray(xy, dtype=np.float64) + np.asarray(self.origin)

    def contains(self, xy: np.ndarray, border: float = 0.0) -> bool:
        x, y = self.to_local(xy)
        width, height = self.width * self.cell_size, self.height * self.cell_size
        return border <= x < width - border and border <= y < height - border


def predicted_centres(history: np.ndarray, horizon_s: float, step: float) -> np.ndarray:
    """(k, 2) the pedestrians' newest positions and, up to `horizon_s` ahead, their constant-velocity
    predictions every `step` seconds (velocity from the two newest positions). `history` is
    (N, T, 2), positions `step` seconds apart, oldest first, NaN before a track was seen."""
    centres = []
    for track in np.asarray(history, dtype=np.float64):
        if not np.isfinite(track[-1]).all():
            continue
        centres.append(track[-1])
        if horizon_s > 0 and len(track) >= 2 and np.isfinite(track[-2]).all():
            velocity = (track[-1] - track[-2]) / step
            centres.extend(track[-1] + velocity * k * step for k in range(1, math.ceil(horizon_s / step - 1e-9) + 1))
    return np.array(centres, dtype=np.float64).reshape(-1, 2)


def pedestrian_costmap(window: Window, centres: np.ndarray, lethal_radius: float,
                       inscribed_radius: float) -> np.ndarray:
    """A (height, width) uint8 grid: LETHAL within `lethal_radius` of any centre, INSCRIBED within
    `lethal_radius + inscribed_radius`, FREE elsewhere (distances from cell centres)."""
    grid = np.zeros((window.height, window.width), dtype=np.uint8)
    cs, reach = window.cell_size, lethal_radius + inscribed_radius
    for cx, cy in window.to_local(centres).reshape(-1, 2):
        x0, x1 = max(int((cx - reach) / cs) - 1, 0), min(int((cx + reach) / cs) + 2, window.width)
        y0, y1 = max(int((cy - reach) / cs) - 1, 0), min(int((cy + reach) / cs) + 2, window.height)
        if x0 >= x1 or y0 >= y1:
            continue
        xs = (np.arange(x0, x1) + 0.5) * cs - cx
        ys = (np.arange(y0, y1) + 0.5) * cs - cy
        dist = np.hypot(xs[None, :], ys[:, None])
        block = grid[y0:y1, x0:x1]
        np.maximum(block, np.where(dist <= lethal_radius, LETHAL, np.where(dist <= reach, INSCRIBED, FREE))
                   .astype(np.uint8), out=block)
    return grid
