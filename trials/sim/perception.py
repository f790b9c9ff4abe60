"""What the controller is told about the pedestrians, sampled at its 2.5 Hz step.

`PositionPerception` hands over the true positions with Gaussian noise, random dropouts and a
range limit. `LidarPerception` simulates the robot's laser scans (robot_logs.lidar_sim), runs the
real detector and tracker on them (robot_logs.pipeline) and resamples the tracks at 0.4 s
(robot_logs.tracks.history_at), as on the robot. Both give (ids, (N, T_OBS, 2) histories) with NaN
before a pedestrian was first perceived; a pedestrian missed at the newest step is left out.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.physical import STEP_S, T_OBS
from robot_logs.pipeline import PersonTracker
from robot_logs.tracks import TrackRow, TrackTable, history_at
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotState


class Perception(Protocol):
    """Sensing at every physics step, and the controller's view at each planning step."""

    name: str

    def sense(self, time: float, robot: RobotState, crowd: Crowd) -> None: ...

    def observe(self, time: float, robot: RobotState, crowd: Crowd) -> tuple[tuple[int, ...], np.ndarray]: ...


@dataclass(frozen=True)
class PositionNoise:
    """Noise of the `positions` perception: position error (m, per axis), chance a pedestrian is
    missed at a step, and the range (m) beyond which nobody is seen."""

    std_m: float = 0.05
    dropout: float = 0.05
    range_m: float = 10.0


def fill_gaps(history: np.ndarray) -> np.ndarray:
    """(T, 2) history with inner gaps linearly interpolated; NaN before the first sample stays."""
    known = np.isfinite(history).all(axis=1)
    if known.sum() < 2:
        return history
    steps = np.arange(len(history))
    filled = history.copy()
    inner = ~known & (steps > steps[known][0])
    for k in (0, 1):
        filled[inner, k] = np.interp(steps[inner], steps[known], history[known, k])
    return filled


class PositionPerception:
    """True positions plus seeded noise and dropouts, kept as one history per pedestrian."""

    name = "positions"

    def __init__(self, noise: PositionNoise, seed: int) -> None:
        self.noise = noise
        self._rng = np.random.default_rng(seed)
        self._samples: dict[int, deque[np.ndarray]] = {}

    def sense(self, time: float, robot: RobotState, crowd: Crowd) -> None:
        """Nothing to do between planning steps."""

    def observe(self, time: float, robot: RobotState, crowd: Crowd) -> tuple[tuple[int, ...], np.ndarray]:
        noisy = crowd.position + self._rng.normal(0.0, self.noise.std_m, crowd.position.shape)
        missed = self._rng.random(len(crowd)) < self.noise.dropout
        in_range = np.hypot(*(crowd.position - robot.position).T) <= self.noise.range_m
        ids, histories = [], []
        for i, pid in enumerate(crowd.ids):
            samples = self._samples.setdefault(pid, deque([np.full(2, np.nan)] * T_OBS, maxlen=T_OBS))
            seen = in_range[i] and not missed[i]
            samples.append(noisy[i] if seen else np.full(2, np.nan))
            if seen:
                ids.append(pid)
                histories.append(fill_gaps(np.array(samples)))
        return tuple(ids), np.array(histories, dtype=float).reshape(len(ids), T_OBS, 2)


class LidarPerception:
    """Simulated scans from a lidar on the robot, tracked by robot_logs' person tracker.

    Args:
        seed: seeds the range noise.
        mount: the lidar's pose on the robot (default: 0.35 m ahead of the centre, facing forward).
        spec, body: the sensor and how people look to it.
    """

    name = "lidar"

    def __init__(self, seed: int, mount: Pose2D = Pose2D(0.35, 0.0, 0.0), spec: LidarSpec = LidarSpec(),
                 body: BodyModel = BodyModel()) -> None:
        self.mount = mount
        self._lidar = LidarSimulator(spec, body, seed=seed)
        self._tracker = PersonTracker()
        self._rows: deque[TrackRow] = deque()
        self._scans = 0

    def sense(self, time: float, robot: RobotState, crowd: Crowd) -> None:
        sensor = Pose2D(robot.x, robot.y, robot.theta).compose(self.mount)
        scan = self._lidar.scan(time, sensor, crowd.position, crowd.velocity)
        result = self._tracker.process(scan, sensor_pose=sensor, frame="map", scan_index=self._scans)
        self._scans += 1
        for track in result.tracks:
            self._rows.append(TrackRow(scan.stamp_ns, result.scan_index, track.track_id, track.x, track.y, track.vx, track.vy, "map"))
        oldest_ns = int((time - STEP_S * T_OBS) * 1e9)
        while self._rows and self._rows[0].stamp_ns < oldest_ns:
            self._rows.popleft()

    def observe(self, time: float, robot: RobotState, crowd: Crowd) -> tuple[tuple[int, ...], np.ndarray]:
        return history_at(TrackTable(self._rows), time)
