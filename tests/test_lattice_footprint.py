"""Footprint cells, swept cells and the collision rule of an edge, against cases worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from trials.lattice.environment import Environment
from trials.lattice.footprint import footprint_cells, motion_cells
from trials.lattice.planner import make_planner
from trials.lattice.primitives import MotionPrimitive, PrimitiveSet

SQUARE = [(-0.16, -0.16), (0.16, -0.16), (0.16, 0.16), (-0.16, 0.16)]  # 0.32 m square


def box(x0, x1, y0, y1):
    return {(x, y) for x in range(x0, x1 + 1) for y in range(y0, y1 + 1)}


def test_point_robot_is_the_cell_under_the_pose():
    assert footprint_cells([], (0.0, 0.0, 1.0), 0.1) == {(0, 0)}
    assert footprint_cells([(0.3, 0.3)], (0.26, -0.04, 0.0), 0.1) == {(2, -1)}  # floor, not round


def test_square_corners_round_half_away_from_zero():
    # corners at +-1.6 cells round to +-2: a 5 x 5 block centred on the pose's cell
    assert footprint_cells(SQUARE, (0.0, 0.0, 0.0), 0.1) == box(-2, 2, -2, 2)


def test_rectangle_turned_and_moved():
    rect = [(-0.52, -0.33), (0.52, -0.33), (0.52, 0.33), (-0.52, 0.33)]  # corners at 5.2 and 3.3 cells
    assert footprint_cells(rect, (0.0, 0.0, 0.0), 0.1) == box(-5, 5, -3, 3)
    assert footprint_cells(rect, (0.0, 0.0, math.pi / 2), 0.1) == box(-3, 3, -5, 5)
    assert footprint_cells(rect, (0.1, 0.0, 0.0), 0.1) == box(-4, 6, -3, 3)  # 0.1 m along x: one cell


def test_rectangle_corners_in_floating_point():
    # the sample problems' 1.0 x 0.7 m: 0.35 / 0.1 is 3.4999999999999996 in doubles, so the +-0.35
    # corners round to +-3 cells (not 4) while 0.5 / 0.1 is exactly 5
    rect = [(-0.5, -0.35), (0.5, -0.35), (0.5, 0.35), (-0.5, 0.35)]
    assert footprint_cells(rect, (0.0, 0.0, 0.0), 0.1) == box(-5, 5, -3, 3)


def test_diamond_outline_is_thickened_on_the_left():
    """A 0.4 m square turned 45 degrees: corners (+-3, 0), (0, +-3). Bresenham from the lower x end
    steps diagonally; the cell added to make each step 4-connected falls inside the diamond on the
    right-hand edges and outside it on the left-hand ones (worked through in the module's rule)."""
    square = [(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)]
    cells = footprint_cells(square, (0.0, 0.0, math.pi / 4), 0.1)
    diamond = {(x, y) for x in range(-3, 4) for y in range(-3, 4) if abs(x) + abs(y) <= 3}
    assert cells == diamond | {(-3, 1), (-2, 2), (-1, 3), (-3, -1), (-2, -2), (-1, -3)}


def test_motion_cells_leave_out_the_start_footprint():
    poses = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]])
    # the square's x corners: -1.6 and 1.6 cells at the start (-2..2), -1.1 and 2.1 after 0.05 m
    # (-1..2), -0.6 and 2.6 after 0.1 m (-1..3): only column 3 is new
    assert {tuple(c) for c in motion_cells(SQUARE, poses, 0.1)} == box(3, 3, -2, 2)
    # a point robot: the centre cells after the first
    assert motion_cells([], poses + [0.05, 0.05, 0.0], 0.1).tolist() == [[1, 0]]


def _one_step_planner(grid: np.ndarray, polygon, circumscribed: int = 0):
    """A planner whose only primitive, for every heading, is one cell along +x through (0.05, 0):
    centre cells (0, 0) and (1, 0), sweep of the 0.32 m square: column x = 3, y in -2..2."""
    poses = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]])
    prims = tuple(MotionPrimitive(t, (1, 0, t), 1, poses) for t in range(16))
    env = Environment(grid=grid, cell_size=0.1, obsthresh=10, cost_inscribed_thresh=8,
                      cost_possibly_circumscribed_thresh=circumscribed, nominal_vel=1.0, time_to_turn_45=2.0)
    return make_planner(env, PrimitiveSet(0.1, 16, prims), polygon)


@pytest.mark.parametrize("cell, value, cost", [
    (None, 0, 100),          # free: 100 ms for 0.1 m at 1 m/s
    ((13, 12), 10, -1),      # an obstacle on a swept cell (x = 13, y in 8..12) blocks
    ((13, 13), 10, 100),     # one cell outside the sweep does not
    ((8, 10), 10, 100),      # under the start footprint: not checked, as in SBPL
    ((11, 10), 8, -1),       # the end cell at the inscribed threshold blocks
    ((11, 10), 7, 800),      # below it the end cell's value multiplies the cost: 100 * (1 + 7)
    ((10, 10), 3, 400),      # the source cell's value counts too: 100 * (1 + 3)
    ((13, 12), 9, 100),      # a swept cell below the obstacle threshold is no collision
])
def test_edge_collision_and_cost(cell, value, cost):
    grid = np.zeros((20, 20), np.uint8)
    if cell is not None:
        grid[cell[1], cell[0]] = value
    planner = _one_step_planner(grid, SQUARE)
    assert planner.edge((10, 10, 0), (11, 10, 0)) == ((0, cost) if cost >= 0 else (-1, -1))


def test_footprint_is_checked_only_from_the_circumscribed_threshold():
    grid = np.zeros((20, 20), np.uint8)
    grid[12, 13] = 10  # an obstacle on the sweep
    assert _one_step_planner(grid, SQUARE, circumscribed=0).edge((10, 10, 0), (11, 10, 0)) == (-1, -1)
    # with threshold 1 the centre cells (all 0) do not call for the footprint check: the edge passes
    assert _one_step_planner(grid, SQUARE, circumscribed=1).edge((10, 10, 0), (11, 10, 0)) == (0, 100)
    grid[10, 10] = 1  # now the source cell reaches it, and the obstacle counts again
    assert _one_step_planner(grid, SQUARE, circumscribed=1).edge((10, 10, 0), (11, 10, 0)) == (-1, -1)


def test_sweep_off_the_map_blocks():
    planner = _one_step_planner(np.zeros((20, 20), np.uint8), SQUARE)
    assert planner.edge((16, 10, 0), (17, 10, 0)) == (0, 100)   # sweep column x = 19: on the map
    assert planner.edge((17, 10, 0), (18, 10, 0)) == (-1, -1)   # x = 20: off the map
    assert planner.edge((10, 17, 0), (11, 17, 0)) == (0, 100)   # y up to 19
    assert planner.edge((10, 18, 0), (11, 18, 0)) == (-1, -1)
