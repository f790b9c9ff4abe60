"""The search's view of the map: flat cell values with a border of off-map cells, and obstacle distances.

A border as wide as the longest action reaches means no bounds checks in the inner loop: off-map
cells hold a value above every threshold, so any action touching them is invalid, as in SBPL.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import ndimage

OFF_MAP = 1 << 20  # above any cell value and threshold


class PaddedGrid(NamedTuple):
    """Cell values in a flat array of (height + 2 pad) rows of (width + 2 pad); cell (x, y) at `index(x, y)`.
    A named tuple, so that the compiled search takes it as one argument.

    Attributes:
        values: int32 cell values, OFF_MAP on the border.
        clear2: int64 squared distance (in cells) from each cell to the nearest cell at or above the
            obstacle threshold or off the map: footprint checks can be skipped within it.
    """

    values: np.ndarray
    clear2: np.ndarray
    width: int
    height: int
    pad: int

    @property
    def row(self) -> int:
        return self.width + 2 * self.pad

    def index(self, x: int, y: int) -> int:
        return (y + self.pad) * self.row + (x + self.pad)

    def xy(self, index: int) -> tuple[int, int]:
        y, x = divmod(int(index), self.row)
        return x - self.pad, y - self.pad

    def offsets(self, cells: np.ndarray) -> np.ndarray:
        """(k, 2) cell offsets (dx, dy) as offsets of the flat index."""
        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        return cells[:, 0] + cells[:, 1] * self.row


def pad_grid(grid: np.ndarray, pad: int, obsthresh: int) -> PaddedGrid:
    """Embed a (height, width) grid in a border of `pad` off-map cells (at least 2, for knight moves)."""
    pad = max(int(pad), 2)
    height, width = grid.shape
    values = np.full((height + 2 * pad, width + 2 * pad), OFF_MAP, dtype=np.int32)
    values[pad:pad + height, pad:pad + width] = grid
    blocked = values >= obsthresh
    clear2 = np.rint(ndimage.distance_transform_edt(~blocked) ** 2).astype(np.int64)
    return PaddedGrid(values.ravel(), clear2.ravel(), width, height, pad)
