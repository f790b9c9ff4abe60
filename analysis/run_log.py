"""A finished run's MCAP log (runs/<code>.mcap) as arrays: the robot's state, each pedestrian's path, events.

Topics as in docs/study_folder.md: /robot/state (t, x, y, theta, v, w), /pedestrians/state
(t, ids, x, y: true positions) and /events (t, event, detail).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_logs.errors import LogError
from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.physical import PEDESTRIAN_RADIUS_M, ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M

ROBOT_TOPIC = "/robot/state"
PEDESTRIAN_TOPIC = "/pedestrians/state"
EVENT_TOPIC = "/events"

ROBOT_HALF_SIZE = (ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M)


@dataclass(frozen=True)
class RunLog:
    """`robot`: (n, 6) rows t, x, y, theta, v, w; `pedestrians`: id -> (m, 3) rows t, x, y."""

    robot: np.ndarray
    pedestrians: dict[str, np.ndarray]
    events: list[tuple[float, str, str]]
    metadata: dict[str, str]

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


def read_run_log(path: Path) -> RunLog:
    """Read a run log; LogError when it is missing, damaged or lacks the robot's state."""
    reader = FoxgloveReader(path)
    robot: list[list[float]] = []
    tracks: dict[str, list[list[float]]] = {}
    events: list[tuple[float, str, str]] = []
    try:
        for message in reader.messages([ROBOT_TOPIC, PEDESTRIAN_TOPIC, EVENT_TOPIC]):
            data = message.data
            if message.topic == ROBOT_TOPIC:
                robot.append([float(data[key]) for key in ("t", "x", "y", "theta", "v", "w")])
            elif message.topic == PEDESTRIAN_TOPIC:
                for ident, x, y in zip(data["ids"], data["x"], data["y"]):
                    tracks.setdefault(str(ident), []).append([float(data["t"]), float(x), float(y)])
            else:
                events.append((float(data["t"]), str(data["event"]), str(data.get("detail", ""))))
    except KeyError as exc:
        raise LogError(f"{path}: a message lacks field {exc} of the run-log contract (docs/study_folder.md)") from None
    except (TypeError, ValueError) as exc:
        raise LogError(f"{path}: a message breaks the run-log contract (docs/study_folder.md): {exc}") from None
    if not robot:
        raise LogError(f"{path}: no {ROBOT_TOPIC} messages")
    return RunLog(
        robot=np.asarray(robot),
        pedestrians={ident: np.asarray(rows) for ident, rows in sorted(tracks.items())},
        events=events,
        metadata=reader.metadata.get("run", {}),
    )
