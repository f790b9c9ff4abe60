"""The heuristic: a 2-D Dijkstra from the goal cell over 16 moves, scaled to time, as SBPL's nav3d.

Moves are the 8 neighbours and the 8 knight moves; a move costs (1 + the largest value of the cells
it touches) times its length in millimetres, truncated as SBPL truncates (for 5 cm cells: 50, 70
and 111 mm). Cells at or above the inscribed threshold block. Like SBPL, the search stops once it
has settled every cell up to twice the start's cost; cells beyond get that bound. The state's
heuristic is max(2-D cost, straight-line millimetres) / nominal speed, so it never overestimates
the lattice cost and stays consistent.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from trials.lattice.grid import PaddedGrid
from trials.lattice.heap import Heap, pop_min, push_or_update

INFINITE_COST = 1_000_000_000
#: (dx, dy) of the 16 moves; moves 8..15 pass through the two cells listed in KNIGHT_CELLS.
MOVES = np.array([(1, 1), (1, 0), (1, -1), (0, 1), (0, -1), (-1, 1), (-1, 0), (-1, -1),
                  (2, 1), (1, 2), (-1, 2), (-2, 1), (-2, -1), (-1, -2), (1, -2), (2, -1)], dtype=np.int64)
KNIGHT_CELLS = np.array([[(1, 0), (1, 1)], [(0, 1), (1, 1)], [(0, 1), (-1, 1)], [(-1, 0), (-1, 1)],
                         [(-1, 0), (-1, -1)], [(0, -1), (-1, -1)], [(0, -1), (1, -1)], [(1, 0), (1, -1)]],
                        dtype=np.int64)


def move_lengths_mm(cell_size: float) -> np.ndarray:
    """Millimetres per move, computed in single precision as SBPL's 2-D search does."""
    cs = np.float32(cell_size)
    straight, diagonal, knight = (int(cs * np.float32(m)) for m in (1000, 1414, 2236))
    return np.array([diagonal if dx and dy else straight for dx, dy in MOVES[:8]] + [knight] * 8, dtype=np.int64)


class Moves(NamedTuple):
    """The 16 moves on one padded grid, as the compiled Dijkstra reads them."""

    offsets: np.ndarray  # (16,) flat-index offset of each move
    through: np.ndarray  # (8, 2) flat-index offsets of the two cells each knight move passes through
    lengths: np.ndarray  # (16,) millimetres (`move_lengths_mm`)


@njit(cache=True)
def _dijkstra(values, source, target, block, moves, g):
    """Costs from `source` into `g`; returns the bound given to cells it did not settle."""
    n = values.size
    heap = Heap(np.zeros(n + 1, np.int64), np.zeros(n + 1, np.int32), np.zeros(n, np.int32), np.zeros(1, np.int64))
    closed = np.zeros(n, np.bool_)
    offsets, through, lengths = moves.offsets, moves.through, moves.lengths
    g[:] = INFINITE_COST
    g[source] = 0
    push_or_update(heap, source, 0)
    while heap.size[0] > 0 and g[target] > 0.5 * heap.keys[1]:
        cell = pop_min(heap)
        closed[cell] = True
        here = values[cell]
        for m in range(16):
            nxt = cell + offsets[m]
            if closed[nxt]:
                continue
            cost = max(values[nxt], here)
            if m >= 8:
                cost = max(cost, values[cell + through[m - 8, 0]], values[cell + through[m - 8, 1]])
            if cost >= block:
                continue
            new = g[cell] + (cost + 1) * lengths[m]
            if new < g[nxt]:
                g[nxt] = new
                push_or_update(heap, nxt, new)
    return heap.keys[1] if heap.size[0] > 0 else INFINITE_COST


def grid_heuristic(grid: PaddedGrid, goal: tuple[int, int], start: tuple[int, int], cell_size: float,
                   inscribed: int, nominal_vel: float) -> np.ndarray:
    """The heuristic of every cell of the padded grid towards `goal` (cells), for a search from `start`."""
    row = grid.row
    moves = Moves(grid.offsets(MOVES), grid.offsets(KNIGHT_CELLS.reshape(-1, 2)).reshape(8, 2),
                  move_lengths_mm(cell_size))
    g = np.empty(grid.values.size, dtype=np.int64)
    bound = _dijkstra(grid.values, grid.index(*goal), grid.index(*start), inscribed, moves, g)
    h2d = np.minimum(g, bound)
    ys, xs = np.divmod(np.arange(grid.values.size, dtype=np.int64), row)
    dx, dy = xs - grid.pad - goal[0], ys - grid.pad - goal[1]
    euclid_mm = (1000 * (cell_size * np.sqrt((dx * dx + dy * dy).astype(np.float64)))).astype(np.int64)
    return (np.maximum(h2d, euclid_mm).astype(np.float64) / nominal_vel).astype(np.int64)
