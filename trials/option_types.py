"""argparse types for the `trials` options: bounded whole numbers and finite numbers, seeds, and paths
that must be (or may become) a folder or a file.

A value outside its range is an argparse usage error, so every command answers it the same way:
one `error: argument --NAME: expected ..., got '...'` line and exit 2, before any work starts.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: Seeds are recorded in JSON and CSV files and fed to numpy's SeedSequence: whole numbers 0 .. 2^53 - 1, which
#: a spreadsheet, R or JMP (reading every number as a double) keeps exact.
SEED_MAX = 2**53 - 1
#: Torch threads a command may ask for.
MAX_THREADS = 256


def whole(minimum: int, maximum: int | None = None) -> Callable[[str], int]:
    """A whole number in [minimum, maximum]."""
    expected = f"a whole number from {minimum} to {maximum}" if maximum is not None else f"a whole number >= {minimum}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value

    return parse


seed = whole(0, SEED_MAX)


def listed(item: Callable[[str], Any], what: str) -> Callable[[str], list[Any]]:
    """A comma-separated list of items, each checked by `item`."""

    def parse(text: str) -> list[Any]:
        parts = [p.strip() for p in text.split(",")]
        if not all(parts):
            raise argparse.ArgumentTypeError(f"expected a comma-separated list of {what}, got {text!r}")
        return [item(p) for p in parts]

    return parse


def add_dpi(parser: argparse.ArgumentParser) -> None:
    """The --dpi option of a command that saves figures (PNG resolution; the SVG beside each has none)."""
    from robot_logs.figure_files import DEFAULT_DPI, MAX_DPI, MIN_DPI

    parser.add_argument("--dpi", type=whole(MIN_DPI, MAX_DPI), default=DEFAULT_DPI, metavar="N",
                        help=f"resolution of the PNG figures, dots per inch (default {DEFAULT_DPI}); each is also written as SVG")


def add_map(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """--map and --map-frame of a command that tracks people in logs: a ROS map_server map whose occupied
    cells are not people (`robot_logs.occupancy_map`)."""
    from robot_logs.occupancy_map import MAP_FRAME

    parser.add_argument("--map", type=input_file, metavar="YAML",
                        help="a ROS map_server map.yaml (and its image): legs on its occupied cells are not people; "
                             "needs odometry, and tf linking the map's frame to it")
    parser.add_argument("--map-frame", default=MAP_FRAME, metavar="FRAME",
                        help=f"the frame the map is drawn in (default {MAP_FRAME}, map_server's; the odometry frame's name "
                             "for a map drawn in it)")


def number(minimum: float, maximum: float, *, above: bool = False, below: bool = False) -> Callable[[str], float]:
    """A finite number in the range, its ends open where `above` / `below` say."""
    expected = f"a finite number in {'(' if above else '['}{minimum:g}, {maximum:g}{')' if below else ']'}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        low_ok = value > minimum if above else value >= minimum
        high_ok = value < maximum if below else value <= maximum
        if not (math.isfinite(value) and low_ok and high_ok):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value + 0.0  # -0 is 0: numpy refuses a negative zero scale ("scale < 0")

    return parse


def folder(text: str) -> Path:
    """A folder to read or write: it may not exist yet, but must not be a file."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder")
    return path


def input_file(text: str) -> Path:
    """A file to read: it must exist and be a file."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no file {text}")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a file")
    return path


def output_file(text: str) -> Path:
    """A file to write: its folder must exist (nothing creates folders the user mistyped), and it must not be a folder."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a file")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: the folder {path.parent} does not exist")
    return path
