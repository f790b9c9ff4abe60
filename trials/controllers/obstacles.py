"""The static world in a controller's plan: the walls and furniture of `Observation.obstacles`, as points.

The lattice planner draws them into its cost grid and plans around them. NaviGAN-R was trained on people only, so it
is given the nearest of them as people standing still (as a social force model gives walls a repulsion), and its
way-points are then cut where they would bring the robot within `clearance` of a wall: the robot holds at the last clear
one rather than be sent through it.
"""

from __future__ import annotations

import numpy as np

#: How far from the robot the static world is given to a controller (m): beyond a plan's reach at 1 m/s over 4.8 s.
OBSTACLE_RANGE_M = 6.0
#: Spacing (m) of the points a controller is given: finer than a footprint, coarse enough to stay a few hundred.
OBSTACLE_SPACING_M = 0.2


def thinned(points: np.ndarray, spacing: float = OBSTACLE_SPACING_M) -> np.ndarray:
    """(K, 2) one point per `spacing`-sided square that holds any of `points`, the first of each, in their order."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(points):
        return points
    _, first = np.unique(np.floor(points / spacing).astype(np.int64), axis=0, return_index=True)
    return points[np.sort(first)]


def nearest(points: np.ndarray, position: np.ndarray, count: int, spacing: float) -> np.ndarray:
    """(k <= count, 2) the points nearest `position`, no two within `spacing` of each other (greedy, nearest first)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    order = np.argsort(np.hypot(*(points - position[:2]).T), kind="stable")
    chosen: list[np.ndarray] = []
    for point in points[order]:
        if len(chosen) == count:
            break
        if all(np.hypot(*(point - other)) >= spacing for other in chosen):
            chosen.append(point)
    return np.array(chosen).reshape(-1, 2)


def clear_prefix(waypoints: np.ndarray, position: np.ndarray, obstacles: np.ndarray, clearance: float) -> tuple[np.ndarray, int]:
    """The way-points with every one from the first that comes within `clearance` of an obstacle, nearer than the robot
    at `position` stands now, replaced by the last clear one (by `position` when the first is not clear: the robot holds),
    and how many were replaced. A robot already near a wall may move along it or away, never closer."""
    waypoints = np.asarray(waypoints, dtype=float)
    obstacles = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    if not len(obstacles) or not len(waypoints):
        return waypoints, 0
    gaps = np.hypot(*(waypoints[:, None, :] - obstacles[None, :, :]).transpose(2, 0, 1)).min(axis=1)
    now = float(np.hypot(*(obstacles - np.asarray(position, dtype=float)[:2]).T).min())
    blocked = (gaps < clearance) & (gaps < now)
    if not blocked.any():
        return waypoints, 0
    first = int(np.argmax(blocked))
    out = waypoints.copy()
    out[first:] = out[first - 1] if first else np.asarray(position, dtype=float)[:2]
    return out, len(waypoints) - first
