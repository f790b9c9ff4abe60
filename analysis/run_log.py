"""A finished run's log as the report scores it: the robot's state, each pedestrian's own path, the events.

`robot_logs.run_log` owns the log's format and reads it (`read_run`); `RunLog.of` rearranges what
it read per pedestrian.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_logs.physical import PEDESTRIAN_RADIUS_M, ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M
from robot_logs.run_log import LoggedRun

ROBOT_HALF_SIZE = (ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M)


@dataclass(frozen=True)
class RunLog:
    """`robot`: (n, 6) rows t, x, y, theta, v, w; `pedestrians`: id -> (m, 3) rows t, x, y."""

    robot: np.ndarray
    pedestrians: dict[str, np.ndarray]
    events: list[tuple[float, str, str]]
    metadata: dict[str, str]

    @classmethod
    def of(cls, run: LoggedRun) -> RunLog:
        """The report's view of a run read by `read_run`: each pedestrian's samples while present."""
        tracks = {}
        for n, ident in enumerate(run.ids):
            present = np.isfinite(run.pedestrians[:, n]).all(axis=1)
            tracks[str(ident)] = np.column_stack([run.time[present], run.pedestrians[present, n]])
        robot = np.column_stack([run.time, run.pose, run.velocity])
        return cls(robot, dict(sorted(tracks.items())), list(run.events), dict(run.metadata))

    def pedestrian_at_robot_times(self, ident: str) -> tuple[np.ndarray, np.ndarray]:
        """Mask of robot samples within the pedestrian's logged span, and its (n, 2) positions there."""
        track = self.pedestrians[ident]
        t = self.robot[:, 0]
        inside = (t >= track[0, 0]) & (t <= track[-1, 0])
        xy = np.column_stack([np.interp(t, track[:, 0], track[:, 1]), np.interp(t, track[:, 0], track[:, 2])])
        return inside, xy

    def gaps(self, ident: str) -> np.ndarray:
        """Gap (m) between the robot's footprint and the pedestrian's body at each robot sample (inf outside its span)."""
        inside, xy = self.pedestrian_at_robot_times(ident)
        gap = footprint_gap(self.robot[:, 1:4], xy)
        return np.where(inside, gap, np.inf)


def footprint_gap(
    robot_pose: np.ndarray, points: np.ndarray, half_size: tuple[float, float] = ROBOT_HALF_SIZE, radius: float = PEDESTRIAN_RADIUS_M
) -> np.ndarray:
    """Distance from the robot's rectangle at (n, 3) poses to discs of `radius` at (n, 2) points, 0 on contact."""
    dx = points[:, 0] - robot_pose[:, 0]
    dy = points[:, 1] - robot_pose[:, 1]
    cos, sin = np.cos(robot_pose[:, 2]), np.sin(robot_pose[:, 2])
    forward = np.abs(cos * dx + sin * dy) - half_size[0]
    left = np.abs(-sin * dx + cos * dy) - half_size[1]
    outside = np.hypot(np.maximum(forward, 0.0), np.maximum(left, 0.0))
    return np.maximum(outside - radius, 0.0)
