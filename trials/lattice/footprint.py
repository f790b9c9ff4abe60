"""Cells covered by the robot's footprint polygon at a pose, and swept by it along a motion.

Follows SBPL's get_2d_footprint_cells: the rotated corners are rounded to cells (the pose is relative
to a cell centre), the outline is drawn with Bresenham lines thickened to 4-connected, and every cell
that an 8-connected flood fill from outside the outline cannot reach belongs to the footprint.
A polygon of fewer than two points is a point robot: the one cell under the pose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import ndimage

from trials.lattice.environment import cont_to_cell

Polygon = Sequence[tuple[float, float]]


def _round_cell(value: float, res: float) -> int:
    """SBPL's corner rounding: to the nearest cell, halves away from zero."""
    return int(value / res + 0.5) if value > 0 else int(value / res - 0.5)


def _outline(corners: list[tuple[int, int]]) -> set[tuple[int, int]]:
    """Bresenham lines around the closed polygon, with a corner cell added at every diagonal step."""
    cells: set[tuple[int, int]] = set()
    for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1]):
        steep = abs(y1 - y0) > abs(x1 - x0)
        if steep:
            x0, y0, x1, y1 = y0, x0, y1, x1
        if x0 > x1:
            x0, y0, x1, y1 = x1, y1, x0, y0
        dx, dy = x1 - x0, abs(y1 - y0)
        error, ystep, y = dx // 2, (1 if y0 < y1 else -1), y0
        for x in range(x0, x1 + 1):
            cells.add((y, x) if steep else (x, y))
            last_error = error
            error -= dy
            if error < 0 and x != x1:
                extra = (x, y + ystep) if last_error < -error else (x + 1, y)
                cells.add((extra[1], extra[0]) if steep else extra)
                y += ystep
                error += dx
    return cells


def footprint_cells(polygon: Polygon, pose: tuple[float, float, float], res: float) -> set[tuple[int, int]]:
    """Cells (x, y) covered by the polygon (robot frame, metres) at `pose` (relative to a cell centre)."""
    x, y, theta = pose
    if len(polygon) <= 1:
        return {(cont_to_cell(x, res), cont_to_cell(y, res))}
    cth, sth = math.cos(theta), math.sin(theta)
    corners = [(_round_cell(cth * px - sth * py + x, res), _round_cell(sth * px + cth * py + y, res))
               for px, py in polygon]
    outline = _outline(corners)
    xs, ys = zip(*corners)
    minx, miny = min(xs), min(ys)
    walls = np.zeros((max(xs) - minx + 3, max(ys) - miny + 3), dtype=bool)  # one free cell of border
    for cx, cy in outline:
        walls[cx - minx + 1, cy - miny + 1] = True
    labels, _ = ndimage.label(~walls, structure=np.ones((3, 3), dtype=bool))
    inside = labels != labels[0, 0]
    return {(int(i) + minx - 1, int(j) + miny - 1) for i, j in zip(*np.nonzero(inside))}


def motion_cells(polygon: Polygon, poses: np.ndarray, res: float) -> np.ndarray:
    """(M, 2) cells swept over `poses` but not under the first pose, sorted (SBPL's get_2d_motion_cells)."""
    first = footprint_cells(polygon, tuple(poses[0]), res)
    swept: set[tuple[int, int]] = set()
    for pose in poses[1:]:
        swept |= footprint_cells(polygon, tuple(pose), res)
    return np.array(sorted(swept - first), dtype=np.int64).reshape(-1, 2)
