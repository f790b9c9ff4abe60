"""A ROS map_server map (map.yaml and its image) as occupied cells, for static-world rejection.

The one reader of that format. map.yaml's fields are read as map_server reads them:

- `image`: the picture (PGM, PNG, ... anything Pillow opens), relative to the YAML's folder;
- `resolution`: metres per pixel;
- `origin`: [x, y, yaw], the pose of the image's lower-left corner in the map frame;
- `negate` (0): 1 swaps white and black; `occupied_thresh` (0.65) and `free_thresh` (0.196);
- `mode` (trinary): trinary and scale turn a pixel's grey value v (the mean of its colour channels,
  255 - v when negated) into an occupancy p = (255 - v) / 255; raw takes v itself as the occupancy in
  percent (0-100; above 100, such as 255, is unknown).

A cell is occupied where its occupancy exceeds occupied_thresh: black in a usual map, the cells
map_server publishes as 100. The YAML names no frame; map_server publishes in `map` unless told
otherwise, so the frame is the caller's (`--map-frame`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from robot_logs.errors import LogError
from robot_logs.frames import Pose2D

#: The frame map_server publishes in by default.
MAP_FRAME = "map"
MODES = ("trinary", "scale", "raw")
#: map_server's values for the optional fields.
DEFAULTS: dict[str, Any] = {"negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
#: Pillow's image modes a map may be in: grey, grey with alpha, bilevel, palette and colour.
IMAGE_MODES = ("L", "LA", "1", "P", "PA", "RGB", "RGBA")


@dataclass(frozen=True)
class OccupancyMap:
    """Occupied cells of a map in its frame.

    Attributes:
        occupied: (rows, columns) True where a cell is occupied; row 0 is the image's bottom row,
            so row i, column j covers [j, j + 1) x [i, i + 1) cells from the origin.
        resolution: cell side (m).
        origin: pose of the grid's lower-left corner in the map frame.
        frame: the map frame's name.
        source: the map.yaml it was read from.
    """

    occupied: np.ndarray
    resolution: float
    origin: Pose2D
    frame: str
    source: Path

    def is_occupied(self, points: np.ndarray) -> np.ndarray:
        """(N,) True where a map-frame point lies on an occupied cell (never outside the image)."""
        local = self.origin.inverse().apply(points)
        cell = np.floor(local / self.resolution).astype(np.int64)
        rows, columns = self.occupied.shape
        inside = (cell[:, 0] >= 0) & (cell[:, 0] < columns) & (cell[:, 1] >= 0) & (cell[:, 1] < rows)
        found = np.zeros(len(cell), dtype=bool)
        found[inside] = self.occupied[cell[inside, 1], cell[inside, 0]]
        return found

    def placed(self, pose: Pose2D) -> PlacedMap:
        """The map seen from a frame whose pose in the map frame is `pose` (at one scan's time)."""
        return PlacedMap(self, pose)


@dataclass(frozen=True)
class PlacedMap:
    """A map and the pose of another frame in it: call it with that frame's points to learn which are on
    occupied cells (a `robot_logs.static_world.KnownStatic`)."""

    map: OccupancyMap
    pose: Pose2D

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.map.is_occupied(self.pose.apply(points))


def read_map(path: Path, frame: str = MAP_FRAME) -> OccupancyMap:
    """The occupied cells of the map a map.yaml describes, in `frame`.

    Raises:
        LogError: the YAML is unreadable or not a mapping, a field is missing or out of range (the
            message names the file and the field), or the image is missing or cannot be read.
    """
    from ruamel.yaml import YAML, YAMLError

    path = Path(path)
    try:
        fields = YAML(typ="safe").load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LogError(f"{path}: cannot read the map file ({exc.strerror or exc})") from None
    except (YAMLError, UnicodeDecodeError) as exc:
        mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
        where = f"line {mark.line + 1}: {problem}" if mark is not None and problem else " ".join(str(exc).split())
        raise LogError(f"{path}: not a map_server YAML file ({where})") from None
    if not isinstance(fields, dict):
        raise LogError(f"{path}: expected a map_server YAML mapping (image, resolution, origin, ...), got {type(fields).__name__}")
    fields = DEFAULTS | fields
    missing = [name for name in ("image", "resolution", "origin") if name not in fields]
    if missing:
        raise LogError(f"{path}: missing field {', '.join(missing)} (a map_server map.yaml needs image, resolution and origin)")

    def number(name: str, low: float, high: float, text: str) -> float:
        value = fields[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and low <= value <= high):
            raise LogError(f"{path}: field {name}: expected {text}, got {value!r}")
        return float(value)

    resolution = number("resolution", 1e-6, 1e3, "a cell size in metres above 0")
    origin = fields["origin"]
    if not (isinstance(origin, list) and len(origin) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in origin)):
        raise LogError(f"{path}: field origin: expected [x, y, yaw] in metres and radians, got {origin!r}")
    negate = fields["negate"]
    if negate not in (0, 1):
        raise LogError(f"{path}: field negate: expected 0 or 1, got {negate!r}")
    occupied_thresh = number("occupied_thresh", 0.0, 1.0, "an occupancy from 0 to 1")
    free_thresh = number("free_thresh", 0.0, 1.0, "an occupancy from 0 to 1")
    if free_thresh > occupied_thresh:
        raise LogError(f"{path}: field free_thresh: expected at most occupied_thresh ({occupied_thresh:g}), got {free_thresh:g}")
    mode = fields["mode"]
    if mode not in MODES:
        raise LogError(f"{path}: field mode: expected {', '.join(MODES)}, got {mode!r}")
    image = fields["image"]
    if not isinstance(image, str) or not image:
        raise LogError(f"{path}: field image: expected the image file's name, got {image!r}")
    grey = _grey(path, path.parent / image)
    if negate:
        grey = 255.0 - grey
    if mode == "raw":
        occupied = (grey <= 100.0) & (grey > 100.0 * occupied_thresh)
    else:
        occupied = (255.0 - grey) / 255.0 > occupied_thresh
    return OccupancyMap(occupied[::-1].copy(), resolution, Pose2D(*map(float, origin)), frame, path)


def _grey(source: Path, image: Path) -> np.ndarray:
    """(rows, columns) the mean of each pixel's colour channels (alpha left out), top row first."""
    from PIL import Image, UnidentifiedImageError

    if not image.is_file():
        raise LogError(f"{source}: field image: no file {image}")
    try:
        with Image.open(image) as picture:
            picture.load()
            mode = picture.mode
            colour = picture.convert("RGB") if mode in ("P", "PA") else picture.convert("L") if mode == "1" else picture.copy()
    except (OSError, ValueError, UnidentifiedImageError) as exc:  # Pillow's ValueError: a malformed header
        raise LogError(f"{source}: cannot read image {image} ({exc})") from None
    if mode not in IMAGE_MODES:
        raise LogError(f"{source}: image {image} has pixel mode {mode}; expected 8-bit grey or colour")
    bands = colour.getbands()
    pixels = np.asarray(colour, dtype=np.float64)
    if pixels.ndim == 2:
        return pixels
    channels = [i for i, band in enumerate(bands) if band != "A"]
    return pixels[:, :, channels].mean(axis=2)
