"""Successor tables: every primitive of every heading precomputed once into flat arrays.

For each (heading, action): the end cell offset and heading, the base cost (SBPL's milliseconds at
nominal speed times the multiplier), the distinct cells under the robot's centre along the motion,
and the cells the footprint sweeps (less those under it at the start), as SBPL precomputes them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trials.lattice.environment import (
    Environment,
    cell_to_cont,
    cont_to_cell,
    heading_to_cont,
    min_angle_diff,
)
from trials.lattice.errors import LatticeError
from trials.lattice.footprint import Polygon, motion_cells
from trials.lattice.primitives import MotionPrimitive, PrimitiveSet

COST_MULT_MTOMM = 1000  # SBPL's costs are milliseconds at nominal speed
RESOLUTION_TOLERANCE = 1e-6


def action_seconds(prim: MotionPrimitive, env: Environment) -> float:
    """Time to drive a primitive: the longer of its path at nominal speed and its turn at turning speed."""
    steps = np.diff(prim.poses[:, :2], axis=0)
    length = 0.0
    for dx, dy in steps:  # summed in order, as SBPL does, so the ceil below sees the same double
        length += math.sqrt(dx * dx + dy * dy)
    turn = abs(min_angle_diff(heading_to_cont(prim.end[2], env.num_thetas),
                              heading_to_cont(prim.start_heading, env.num_thetas)))
    return max(length / env.nominal_vel, turn / ((math.pi / 4.0) / env.time_to_turn_45))


def base_cost(prim: MotionPrimitive, env: Environment) -> int:
    """SBPL's action cost before the cell-cost factor."""
    return int(math.ceil(COST_MULT_MTOMM * action_seconds(prim, env))) * prim.cost_mult


def centre_cells(prim: MotionPrimitive, cell_size: float) -> np.ndarray:
    """(K, 2) cells under the robot's centre along the motion, consecutive repeats dropped."""
    half = cell_to_cont(0, cell_size)
    cells: list[tuple[int, int]] = []
    for x, y, _ in prim.poses:
        cell = (cont_to_cell(x + half, cell_size), cont_to_cell(y + half, cell_size))
        if not cells or cells[-1] != cell:
            cells.append(cell)
    return np.array(cells, dtype=np.int64)


def _csr(blocks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate (k, 2) blocks into one array and its row pointers."""
    ptr = np.zeros(len(blocks) + 1, dtype=np.int64)
    ptr[1:] = np.cumsum([len(b) for b in blocks])
    flat = np.concatenate(blocks) if blocks else np.zeros((0, 2), dtype=np.int64)
    return flat.reshape(-1, 2), ptr


@dataclass(frozen=True)
class ActionTable:
    """Flat successor tables, indexed [heading, action] or, flattened, heading * per_heading + action.

    Attributes:
        end: (N, A, 3) end cell dx, dy and end heading.
        cost: (N, A) base cost; the edge cost multiplies it by 1 + the largest cell value met.
        seconds: (N, A) driving time of each action.
        centre, centre_ptr: cells under the centre (N*A blocks of (k, 2) cell offsets).
        swept, swept_ptr: footprint cells swept beyond the start footprint (N*A blocks).
        reach2: (N, A) largest squared distance (cells^2) of a swept or centre cell from the start cell.
        polygon: the footprint the swept cells were computed for (fewer than two points: a point robot).
        primitives: the primitives in the same [heading][action] order, for paths.
    """

    end: np.ndarray
    cost: np.ndarray
    seconds: np.ndarray
    centre: np.ndarray
    centre_ptr: np.ndarray
    swept: np.ndarray
    swept_ptr: np.ndarray
    reach2: np.ndarray
    polygon: tuple[tuple[float, float], ...]
    primitives: tuple[tuple[MotionPrimitive, ...], ...]

    @property
    def num_thetas(self) -> int:
        return int(self.cost.shape[0])

    @property
    def per_heading(self) -> int:
        return int(self.cost.shape[1])

    @property
    def use_footprint(self) -> bool:
        return len(self.polygon) > 1

    @property
    def reach(self) -> int:
        """The largest |dx| or |dy| of any cell an action touches: the border a grid needs."""
        cells = np.concatenate([self.centre, self.swept, self.end[..., :2].reshape(-1, 2)])
        return int(np.abs(cells).max())


def build_actions(prims: PrimitiveSet, env: Environment, polygon: Polygon) -> ActionTable:
    """Precompute the successor tables of `prims` in `env` for the footprint `polygon`.

    Raises:
        LatticeError: when the primitives' resolution or number of angles does not fit the environment.
    """
    if abs(prims.resolution - env.cell_size) > RESOLUTION_TOLERANCE:
        raise LatticeError(f"the primitives' resolution {prims.resolution:g} m does not match the "
                           f"environment's cell size {env.cell_size:g} m")
    if prims.num_angles != env.num_thetas:
        raise LatticeError(f"the primitives have {prims.num_angles} angles but the environment "
                           f"has {env.num_thetas} headings")
    n, a = env.num_thetas, prims.per_heading
    table = tuple(tuple(prims.for_heading(t)) for t in range(n))
    flat = [p for row in table for p in row]
    centre, centre_ptr = _csr([centre_cells(p, env.cell_size) for p in flat])
    swept, swept_ptr = _csr([motion_cells(polygon, p.poses, env.cell_size) for p in flat])
    reach2 = np.zeros(n * a, dtype=np.int64)
    for i in range(n * a):
        cells = np.concatenate([centre[centre_ptr[i]:centre_ptr[i + 1]], swept[swept_ptr[i]:swept_ptr[i + 1]]])
        reach2[i] = int((cells ** 2).sum(axis=1).max())
    return ActionTable(
        end=np.array([[p.end for p in row] for row in table], dtype=np.int64),
        cost=np.array([[base_cost(p, env) for p in row] for row in table], dtype=np.int64),
        seconds=np.array([[action_seconds(p, env) for p in row] for row in table], dtype=np.float64),
        centre=centre, centre_ptr=centre_ptr, swept=swept, swept_ptr=swept_ptr,
        reach2=reach2.reshape(n, a), polygon=tuple((float(x), float(y)) for x, y in polygon), primitives=table,
    )
