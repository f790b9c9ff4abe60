"""The default primitive set: a differential-drive robot the size of a ClearPath Husky, 16 headings.

Per heading: one cell forward, a long straight (0.8 m), one cell backward (cost x5), long and short
arcs to each neighbouring heading (cost x2), and a turn in place each way (cost x3). The base
end poses are given for start headings 0, 22.5 and 45 degrees in 0.1 m cells (long moves scale with
the cell size, so 0.05 m cells get the same metres); the other 13 headings are their rotations by
90 degrees and mirror images in the diagonal. A turning primitive is a straight segment and a
circular arc (or an arc and a straight) that end exactly on the end cell's centre and heading,
sampled at most a cell apart.
"""

from __future__ import annotations

import math

import numpy as np

from trials.lattice.environment import heading_to_cont, normalize_angle
from trials.lattice.errors import LatticeError
from trials.lattice.primitives import MotionPrimitive, PrimitiveSet, check_uniform, end_mismatch

HUSKY_TURN_45_S = 0.8        # s to turn 45 degrees in place (about 1 rad/s)
NUM_ANGLES = 16
BASE_CELL = 0.1              # the cell size the base table is written for
MIN_POSES = 10

#: Start heading -> (dx, dy, heading change, cost multiplier, scales with the cell size).
BASE = {
    0: ((1, 0, 0, 1, False), (8, 0, 0, 1, True), (-1, 0, 0, 5, False),
        (8, 1, 1, 2, True), (8, -1, -1, 2, True), (4, 1, 1, 2, True), (4, -1, -1, 2, True),
        (0, 0, 1, 3, False), (0, 0, -1, 3, False)),
    1: ((2, 1, 0, 1, False), (6, 3, 0, 1, True), (-2, -1, 0, 5, False),
        (5, 4, 1, 2, True), (7, 2, -1, 2, True), (3, 2, 1, 2, True), (4, 1, -1, 2, True),
        (0, 0, 1, 3, False), (0, 0, -1, 3, False)),
    2: ((1, 1, 0, 1, False), (6, 6, 0, 1, True), (-1, -1, 0, 5, False),
        (5, 7, 1, 2, True), (7, 5, -1, 2, True), (2, 3, 1, 2, True), (3, 2, -1, 2, True),
        (0, 0, 1, 3, False), (0, 0, -1, 3, False)),
}


def _turn_path(theta0: float, end: tuple[float, float], theta1: float) -> tuple[float, float, bool]:
    """A straight of length l and an arc of signed radius r (straight first, else arc first) from the
    origin at heading theta0 to `end` at heading theta1: returns (l, r, straight_first)."""
    s0, c0, s1, c1 = math.sin(theta0), math.cos(theta0), math.sin(theta1), math.cos(theta1)
    turn = math.remainder(theta1 - theta0, 2 * math.pi)
    for straight_first, (sx, sy) in ((True, (c0, s0)), (False, (c1, s1))):
        length, radius = np.linalg.solve([[sx, s1 - s0], [sy, c0 - c1]], end)
        if length >= -1e-9 and radius * turn > 0:
            return max(float(length), 0.0), float(radius), straight_first
    raise LatticeError(f"no straight-and-arc path from heading {theta0:.3f} to {end} at {theta1:.3f}")


def _poses(theta0: float, end: tuple[float, float], theta1: float, count: int) -> np.ndarray:
    """`count` poses from (0, 0, theta0) to (end, theta1), evenly spaced along the path."""
    fractions = np.linspace(0.0, 1.0, count)
    turn = math.remainder(theta1 - theta0, 2 * math.pi)
    if end == (0.0, 0.0) or turn == 0.0:  # turn in place, or straight (a slight side-slip off the 4 axes)
        return np.column_stack([fractions * end[0], fractions * end[1], theta0 + fractions * turn])
    length, radius, straight_first = _turn_path(theta0, end, theta1)
    arc = abs(radius * turn)
    poses = []
    for s in fractions * (length + arc):
        straight = min(s, length) if straight_first else max(s - arc, 0.0)
        angle = theta0 + turn * (max(s - length, 0.0) if straight_first else min(s, arc)) / arc
        along = theta0 if straight_first else theta1
        x = radius * (math.sin(angle) - math.sin(theta0)) + straight * math.cos(along)
        y = -radius * (math.cos(angle) - math.cos(theta0)) + straight * math.sin(along)
        poses.append((x, y, angle))
    return np.array(poses)


def _transformed(start: int) -> list[tuple[int, int, int, int, bool]]:
    """The base entries for any of the 16 start headings, by rotation and diagonal mirroring."""
    quarter, rest = divmod(start, 4)
    if rest == 3:  # the mirror image of heading 1 in the line y = x
        entries = [(dy, dx, -dt, mult, scaled) for dx, dy, dt, mult, scaled in BASE[1]]
    else:
        entries = list(BASE[rest])
    for _ in range(quarter):
        entries = [(-dy, dx, dt, mult, scaled) for dx, dy, dt, mult, scaled in entries]
    return entries


def husky_primitives(cell_size: float = BASE_CELL) -> PrimitiveSet:
    """The default Husky primitive set for `cell_size` metre cells (0.05 or 0.1 m work best)."""
    scale = max(1, round(BASE_CELL / cell_size))
    prims = []
    for start in range(NUM_ANGLES):
        theta0 = heading_to_cont(start, NUM_ANGLES)
        for dx, dy, dt, mult, scaled in _transformed(start):
            if scaled:
                dx, dy = dx * scale, dy * scale
            end_heading = (start + dt) % NUM_ANGLES
            end = (dx * cell_size, dy * cell_size)
            count = max(MIN_POSES, math.ceil(math.hypot(*end) / cell_size) + 1)
            poses = _poses(theta0, end, theta0 + dt * 2 * math.pi / NUM_ANGLES, count)
            poses[-1] = (*end, heading_to_cont(end_heading, NUM_ANGLES))
            poses[:, 2] = [normalize_angle(t) for t in poses[:, 2]]
            prim = MotionPrimitive(start, (dx, dy, end_heading), mult, poses)
            problem = end_mismatch(prim, cell_size, NUM_ANGLES)
            if problem is not None:
                raise LatticeError(f"Husky primitive ({dx}, {dy}, {end_heading}) from heading {start}: {problem}")
            prims.append(prim)
    check_uniform(tuple(prims), NUM_ANGLES, "the Husky primitives")
    return PrimitiveSet(cell_size, NUM_ANGLES, tuple(prims))
