"""Tracks resampled at the controllers' 2.5 Hz: `history_at` and the tracks CSV."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_logs.errors import LogError
from robot_logs.tracks import TrackRow, TrackTable, history_at


def walking_table() -> TrackTable:
    """Track 1 walks x = t from t = 100 s to 103 s at 10 Hz; track 2 stands at (5, 5) from 102 s."""
    rows = []
    for k in range(31):
        stamp = 100_000_000_000 + k * 100_000_000
        rows.append(TrackRow(stamp, k, 1, 0.1 * k, 0.0, 1.0, 0.0, "odom"))
        if k >= 20:
            rows.append(TrackRow(stamp, k, 2, 5.0, 5.0, 0.0, 0.0, "odom"))
    return TrackTable(rows)


def test_history_matches_the_observation_shape() -> None:
    ids, history = history_at(walking_table(), 103.0)
    assert ids == (1, 2) and history.shape == (2, 8, 2)
    assert history[0, :, 0] == pytest.approx([0.2, 0.6, 1.0, 1.4, 1.8, 2.2, 2.6, 3.0])
    assert np.isnan(history[1, :5]).all()  # before track 2 was first seen
    assert history[1, 5:] == pytest.approx(np.full((3, 2), 5.0))


def test_history_interpolates_between_scans_and_skips_dead_tracks() -> None:
    ids, history = history_at(walking_table(), 101.05, steps=3, step=0.4)
    assert ids == (1,)
    assert history[0, :, 0] == pytest.approx([0.25, 0.65, 1.05])
    ids, history = history_at(walking_table(), 99.0)
    assert ids == () and history.shape == (0, 8, 2)


def test_csv_round_trip_keeps_exact_stamps(tmp_path: Path) -> None:
    table = walking_table()
    table.write_csv(tmp_path / "tracks.csv")
    again = TrackTable.read_csv(tmp_path / "tracks.csv")
    assert again.rows == [TrackRow(r.stamp_ns, r.scan_index, r.track_id, round(r.x, 4), r.y, r.vx, r.vy, r.frame) for r in table.rows]
    assert (tmp_path / "tracks.csv").read_text().splitlines()[1] == "100.000000000,0,1,0.0000,0.0000,1.0000,0.0000,odom"


def test_a_malformed_csv_line_is_named(tmp_path: Path) -> None:
    path = tmp_path / "tracks.csv"
    path.write_text("stamp,scan_index,track_id,x,y,vx,vy,frame\n1.0,0,1,0,0,0,0,odom\n1.1,1,one,0,0,0,0,odom\n")
    with pytest.raises(LogError, match=r"malformed line 3 of .*tracks.csv"):
        TrackTable.read_csv(path)
