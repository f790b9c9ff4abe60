"""Track tables: one row per confirmed track per scan, their CSV file, and resampling at the
controllers' 2.5 Hz step (`history_at`, the shape of `Observation.pedestrian_history`).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TextIO

import numpy as np

from robot_logs.errors import LogError
from robot_logs.physical import STEP_S, T_OBS
from robot_logs.records import seconds, stamp_text

#: Columns of a tracks CSV, in order.
COLUMNS = ("stamp", "scan_index", "track_id", "x", "y", "vx", "vy", "frame")



@dataclass(frozen=True)
class TrackRow:
    """One confirmed track at one scan (stamp: the scan's header stamp in ns)."""

    stamp_ns: int
    scan_index: int
    track_id: int
    x: float
    y: float
    vx: float
    vy: float
    frame: str

    def csv_fields(self) -> list[str]:
        """The row as CSV fields: exact stamp seconds, millimetre positions."""
        numbers = (f"{v:.4f}" for v in (self.x, self.y, self.vx, self.vy))
        return [stamp_text(self.stamp_ns), str(self.scan_index), str(self.track_id), *numbers, self.frame]


class TrackTable:
    """Track rows with per-track views for resampling; rows keep their scan order."""

    def __init__(self, rows: Iterable[TrackRow]) -> None:
        self.rows = list(rows)

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def ids(self) -> list[int]:
        """Every track id, ascending."""
        return sorted(self._by_track)

    @cached_property
    def _by_track(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        grouped: dict[int, list[TrackRow]] = {}
        for row in self.rows:
            grouped.setdefault(row.track_id, []).append(row)
        views = {}
        for track_id, rows in grouped.items():
            rows.sort(key=lambda r: r.stamp_ns)
            stamps = np.array([seconds(r.stamp_ns) for r in rows])
            views[track_id] = (stamps, np.array([[r.x, r.y] for r in rows]))
        return views

    def track(self, track_id: int) -> tuple[np.ndarray, np.ndarray]:
        """(T,) stamps in seconds and (T, 2) positions of one track, in time order."""
        return self._by_track[track_id]

    def write_csv(self, path: Path) -> None:
        """Write the table as CSV (header row first); the file appears complete or not at all."""
        path = Path(path)
        partial = path.with_name(f".{path.name}.partial")
        with partial.open("w", newline="", encoding="utf-8") as stream:
            write_rows(stream, self.rows)
        os.replace(partial, path)

    @classmethod
    def read_csv(cls, path: Path) -> TrackTable:
        """A table from a tracks CSV written by `write_csv` or `trials log track`.

        Raises:
            LogError: missing columns or a malformed line (the message gives its number).
        """
        path = Path(path)
        with path.open(newline="", encoding="utf-8") as stream:
            reader = csv.DictReader(stream)
            if reader.fieldnames is None or set(COLUMNS) - set(reader.fieldnames):
                raise LogError(f"{path}: expected the columns {','.join(COLUMNS)}")
            rows = []
            for line, record in enumerate(reader, start=2):
                try:
                    rows.append(
                        TrackRow(
                            stamp_ns=_stamp_ns(record["stamp"]),
                            scan_index=int(record["scan_index"]),
                            track_id=int(record["track_id"]),
                            x=float(record["x"]),
                            y=float(record["y"]),
                            vx=float(record["vx"]),
                            vy=float(record["vy"]),
                            frame=record["frame"],
                        )
                    )
                except (TypeError, ValueError):
                    raise LogError(f"malformed line {line} of {path}: expected {','.join(COLUMNS)}") from None
        return cls(rows)


def _stamp_ns(text: str) -> int:
    whole, _, part = text.strip().partition(".")
    sign = -1 if whole.startswith("-") else 1
    return sign * (abs(int(whole)) * 1_000_000_000 + int((part + "000000000")[:9]))


def write_rows(stream: TextIO, rows: Iterable[TrackRow]) -> None:
    """Tracks CSV (header row, then one row per track per scan) on an open text stream."""
    writer = csv.writer(stream, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows(row.csv_fields() for row in rows)


def history_at(
    tracks: TrackTable, time: float, steps: int = T_OBS, step: float = STEP_S
) -> tuple[tuple[int, ...], np.ndarray]:
    """The tracks alive at `time`, each resampled at `steps` instants `step` seconds apart.

    Matches `Observation.pedestrian_ids` and `Observation.pedestrian_history`: positions
    are linearly interpolated between scans at time - (steps - 1 - k) * step, k = 0..steps-1
    (oldest first, the newest at `time`), and NaN before the track was first seen.

    Args:
        tracks: the tracked people.
        time: the instant, in seconds on the tracks' clock (header stamps).
        steps: samples per history.
        step: seconds between samples.

    Returns:
        ids (ascending) of the tracks whose span covers `time`, and their (N, steps, 2) history.
    """
    instants = time - step * np.arange(steps - 1, -1, -1)
    ids, histories = [], []
    for track_id in tracks.ids:
        stamps, xy = tracks.track(track_id)
        if not stamps[0] - 1e-9 <= time <= stamps[-1] + 1e-9:
            continue
        history = np.column_stack([np.interp(instants, stamps, xy[:, k]) for k in range(2)])
        history[instants < stamps[0] - 1e-9] = math.nan
        ids.append(track_id)
        histories.append(history)
    return tuple(ids), np.array(histories, dtype=float).reshape(len(ids), steps, 2)
