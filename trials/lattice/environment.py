"""The planning environment: a cost grid with SBPL's thresholds and discretisation, read from nav3d `.cfg` files.

The conversions below follow SBPL's own (`CONTXY2DISC`, `ContTheta2Disc`, ...) operation for operation,
so that costs computed from them match SBPL's to the last integer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trials.lattice.tokens import Tokens

TWO_PI = 2.0 * math.pi
DEFAULT_NUM_THETAS = 16
MAX_CELL_COST = 255


def cont_to_cell(value: float, cell_size: float) -> int:
    """Metres to cell index; negative values go one cell further, as SBPL's CONTXY2DISC."""
    if value >= 0:
        return int(value / cell_size)
    return int(value / cell_size) - 1


def cell_to_cont(index: int, cell_size: float) -> float:
    """Cell index to the metres of its centre."""
    return index * cell_size + cell_size / 2.0


def normalize_angle(angle: float) -> float:
    """An angle in [0, 2 pi], computed as SBPL's normalizeAngle (which keeps its rounding)."""
    if abs(angle) > TWO_PI:
        angle = angle - (int(angle / TWO_PI) * 2) * math.pi
    if angle < 0:
        angle += TWO_PI
    return angle


def cont_to_heading(theta: float, num_thetas: int) -> int:
    """Radians to heading index: bins centred on multiples of 2 pi / N."""
    bin_size = TWO_PI / num_thetas
    return int(normalize_angle(theta + bin_size / 2.0) / TWO_PI * num_thetas) % num_thetas


def heading_to_cont(index: int, num_thetas: int) -> float:
    """Heading index to radians."""
    return index * (TWO_PI / num_thetas)


def min_angle_diff(a: float, b: float) -> float:
    """The unsigned smallest difference of two angles, in [0, pi]."""
    diff = abs(normalize_angle(a) - normalize_angle(b))
    if diff > math.pi:
        diff = abs(diff - TWO_PI)
    return diff


@dataclass(frozen=True)
class Environment:
    """An (x, y, theta) lattice problem: the grid, its thresholds and the robot's speeds.

    Attributes:
        grid: (height, width) uint8 cell values, row 0 at y = 0 (indexed `grid[y, x]`).
        cell_size: metres per cell.
        num_thetas: heading bins.
        obsthresh: cells at or above it are obstacles for the footprint.
        cost_inscribed_thresh: cells at or above it cannot hold the robot's centre.
        cost_possibly_circumscribed_thresh: from this centre cost on, the footprint is checked.
        nominal_vel: m/s; time_to_turn_45: seconds to turn 45 degrees in place.
        start, goal: (x, y, theta) in metres and radians.
    """

    grid: np.ndarray
    cell_size: float
    num_thetas: int = DEFAULT_NUM_THETAS
    obsthresh: int = 254
    cost_inscribed_thresh: int = 253
    cost_possibly_circumscribed_thresh: int = -1
    nominal_vel: float = 1.0
    time_to_turn_45: float = 2.0
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    goal: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def width(self) -> int:
        return int(self.grid.shape[1])

    @property
    def height(self) -> int:
        return int(self.grid.shape[0])

    def to_state(self, pose: tuple[float, float, float]) -> tuple[int, int, int]:
        """A continuous pose to its lattice state (x cell, y cell, heading)."""
        x, y, theta = pose
        return (cont_to_cell(x, self.cell_size), cont_to_cell(y, self.cell_size),
                cont_to_heading(theta, self.num_thetas))

    def to_pose(self, state: tuple[int, int, int]) -> tuple[float, float, float]:
        """A lattice state to the continuous pose of its cell centre and heading."""
        x, y, t = state
        return (cell_to_cont(x, self.cell_size), cell_to_cont(y, self.cell_size), heading_to_cont(t, self.num_thetas))

    def on_map(self, x: int, y: int) -> bool:
        return 0 <= x < self.width and 0 <= y < self.height


def read_cfg(path: Path) -> Environment:
    """Read an SBPL nav3d environment `.cfg` (the layout SBPL's ReadConfiguration accepts).

    Raises:
        LatticeError: naming the file, the line and what was expected there.
    """
    tok = Tokens(path)
    tok.label("discretization(cells):")
    width = tok.integer("the map width in cells", 1)
    height = tok.integer("the map height in cells", 1)
    num_thetas = DEFAULT_NUM_THETAS
    if tok.peek() == "NumThetaDirs:":
        tok.next("NumThetaDirs:")
        num_thetas = tok.integer("the number of headings", 1)
    tok.label("obsthresh:")
    obsthresh = tok.integer("the obstacle threshold", 0, MAX_CELL_COST)
    tok.label("cost_inscribed_thresh:")
    inscribed = tok.integer("the inscribed cost threshold", 0, MAX_CELL_COST)
    tok.label("cost_possibly_circumscribed_thresh:")
    circumscribed = tok.integer("the possibly-circumscribed cost threshold", -1, MAX_CELL_COST)
    tok.label("cellsize(meters):")
    cell_size = tok.number("the cell size in metres", positive=True)
    tok.label("nominalvel(mpersecs):")
    nominal_vel = tok.number("the nominal velocity in m/s", positive=True)
    tok.label("timetoturn45degsinplace(secs):")
    turn45 = tok.number("the time to turn 45 degrees in place", positive=True)
    poses = []
    for which in ("start", "end"):
        tok.next(f'the {which} label "{which}(meters,rads):"')
        poses.append(tuple(tok.number(f"the {which} {axis}") for axis in ("x", "y", "theta")))
    tok.next('the map label "environment:"')
    values = tok.integers(width * height, lambda i: f"value {i % width} of map row {i // width} "
                          f"({height} rows of {width} cell values)", 0, MAX_CELL_COST)
    tok.end(f"{height} map rows of {width} values")
    return Environment(
        grid=values.astype(np.uint8).reshape(height, width), cell_size=cell_size, num_thetas=num_thetas,
        obsthresh=obsthresh, cost_inscribed_thresh=inscribed, cost_possibly_circumscribed_thresh=circumscribed,
        nominal_vel=nominal_vel, time_to_turn_45=turn45, start=poses[0], goal=poses[1],
    )
