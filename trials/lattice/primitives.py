"""Motion primitives: the lattice's edges, read from SBPL's `.mprim` files (or built by `husky`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trials.lattice.environment import cell_to_cont, cont_to_cell, cont_to_heading, normalize_angle
from trials.lattice.errors import LatticeError
from trials.lattice.tokens import Tokens


@dataclass(frozen=True)
class MotionPrimitive:
    """One primitive for one start heading.

    Attributes:
        start_heading: the heading index it starts from.
        end: (dx, dy, end heading) in cells, world frame; the end heading is absolute.
        cost_mult: SBPL's additional action cost multiplier.
        poses: (K, 3) x, y (metres, relative to the start cell's centre) and theta in [0, 2 pi].
    """

    start_heading: int
    end: tuple[int, int, int]
    cost_mult: int
    poses: np.ndarray


@dataclass(frozen=True)
class PrimitiveSet:
    """A complete set: the same number of primitives for every heading."""

    resolution: float
    num_angles: int
    primitives: tuple[MotionPrimitive, ...]

    @property
    def per_heading(self) -> int:
        return len(self.primitives) // self.num_angles

    def for_heading(self, heading: int) -> list[MotionPrimitive]:
        """The primitives of one start heading, in file order (SBPL's action order)."""
        return [p for p in self.primitives if p.start_heading == heading]


def end_mismatch(prim: MotionPrimitive, resolution: float, num_angles: int) -> str | None:
    """Why the last pose does not discretise to the end pose (SBPL's own check), or None."""
    x, y, theta = prim.poses[-1]
    got = (cont_to_cell(cell_to_cont(0, resolution) + x, resolution),
           cont_to_cell(cell_to_cont(0, resolution) + y, resolution), cont_to_heading(theta, num_angles))
    if got != tuple(prim.end):
        return f"its last pose ({x:g}, {y:g}, {theta:g}) lies in cell {got}, not in its end pose {tuple(prim.end)}"
    return None


def check_uniform(prims: tuple[MotionPrimitive, ...], num_angles: int, where: str) -> None:
    """Require the same positive number of primitives for every start heading, as SBPL does."""
    counts = np.bincount([p.start_heading for p in prims], minlength=num_angles)
    if len(prims) == 0 or counts.min() != counts.max():
        raise LatticeError(f"{where}: every heading needs the same number of primitives, got {counts.tolist()} "
                           f"for headings 0..{num_angles - 1}")


def read_mprim(path: Path) -> PrimitiveSet:
    """Read an SBPL `.mprim` file (the uniform-angle format of SBPL's ReadMotionPrimitives).

    Raises:
        LatticeError: naming the file, the line and what was expected there.
    """
    tok = Tokens(path)
    tok.label("resolution_m:")
    resolution = tok.number("the resolution in metres", positive=True)
    if tok.peek() == "min_turning_radius_m:" or tok.peek() == "number_of_angles:":
        raise tok.error('"numberofangles:" (non-uniform angle primitives are not supported)', tok.peek())
    tok.label("numberofangles:")
    num_angles = tok.integer("the number of angles", 1)
    tok.label("totalnumberofprimitives:")
    total = tok.integer("the total number of primitives", 1)
    prims = []
    for _ in range(total):
        tok.label("primID:")
        prim_id = tok.integer("the primitive id")
        tok.label("startangle_c:")
        start = tok.integer("the start angle index", 0, num_angles - 1)
        line = tok.line
        tok.label("endpose_c:")
        dx, dy = tok.integer("the end cell dx"), tok.integer("the end cell dy")
        end_theta = tok.integer("the end angle index") % num_angles
        tok.label("additionalactioncostmult:")
        mult = tok.integer("the cost multiplier", 1)
        tok.label("intermediateposes:")
        count = tok.integer("the number of intermediate poses", 1)
        poses = np.array([[tok.number(f"intermediate pose {i} {axis}") for axis in ("x", "y", "theta")]
                          for i in range(count)], dtype=np.float64)
        poses[:, 2] = [normalize_angle(t) for t in poses[:, 2]]
        prim = MotionPrimitive(start, (dx, dy, end_theta), mult, poses)
        problem = end_mismatch(prim, resolution, num_angles)
        if problem is not None:
            raise LatticeError(f"{tok.path.name}, line {line}: primitive {prim_id} of angle {start}: {problem}")
        prims.append(prim)
    tok.end(f"{total} primitives")
    check_uniform(tuple(prims), num_angles, tok.path.name)
    return PrimitiveSet(resolution, num_angles, tuple(prims))
