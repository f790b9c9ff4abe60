"""A live run's MCAP log (`runs/<code>.mcap`): the run log of a simulated run, plus the robot's own scans and tf.

The log opens when the run starts (its first scan's stamp is t = 0) and holds what really happened: each
scan at its header stamp, placed where tf put the laser in the odometry frame (the run's `map`), the
robot's tf messages as it sent them, the robot's pose and velocity from its odometry, the tracked people,
the events, and (open studies only; sealed otherwise, as `trials.run_log.RunLog` keeps them) the plans
and the commands. Stamps are the robot's own; a blinded run's start is moved back to its minute, as every
time a blinded study records, and every later stamp by the same amount; the messages' own `t` is always
the run's seconds.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from robot_logs import run_log as fmt
from robot_logs.foxglove_log import frame_transform, laser_scan, pose
from robot_logs.frames import Pose2D
from robot_logs.records import Scan, Transform
from trials.controllers.base import Plan
from trials.log_trial import People
from trials.run_log import RunLog
from trials.sim.robot import RobotLimits, RobotState
from trials.study import minute_ns

#: A live log's MCAP chunk (bytes): about a second of scans, so a worker killed mid-run loses at most that much of its
#: log (`robot_logs.foxglove_log.recover` keeps the rest).
LIVE_CHUNK_BYTES = 64 * 1024


class LiveLog:
    """Writes a live run's log as the loop reports it (a `trials.robot.live.LiveSink`); nothing is written
    until `started`, and `close` ends it, however the run ended (what was recorded is always kept)."""

    def __init__(self, path: Path, metadata: Mapping[str, str], blind: bool, limits: RobotLimits) -> None:
        self.path, self.metadata, self.blind, self.limits = path, dict(metadata), blind, limits
        self.log: RunLog | None = None

    def started(self, start_ns: int, goal: np.ndarray, perception: str) -> None:
        origin = minute_ns(start_ns) if self.blind else start_ns
        self.metadata["perception"] = perception
        self.log = RunLog(self.path, {**self.metadata, "robot_start_stamp_ns": str(origin)}, (float(goal[0]), float(goal[1])),
                          None, self.blind, self.limits, start_ns=origin, chunk_size=LIVE_CHUNK_BYTES)

    def scan(self, time: float, scan: Scan, sensor: Pose2D) -> None:
        assert self.log is not None
        stamp = self.log.stamp(time)
        message = {**laser_scan(replace(scan, stamp_ns=stamp)), "frame_id": fmt.FRAME, "pose": pose(sensor.x, sensor.y, sensor.yaw)}
        self.log.writer.write(*fmt.SCAN, message, stamp)

    def transforms(self, time: float, transforms: list[Transform]) -> None:
        assert self.log is not None
        stamp = self.log.stamp(time)
        for t in transforms:
            self.log.writer.write(*fmt.ROBOT_TF, frame_transform(stamp, t.parent, t.child, t.pose), stamp)

    def state(self, time: float, robot: RobotState, command: tuple[float, float], people: People) -> None:
        assert self.log is not None
        self.log.state(time, robot, command, people)  # type: ignore[arg-type]

    def perceived(self, time: float, ids: tuple[int, ...], history: np.ndarray) -> None:
        assert self.log is not None
        self.log.perceived(time, ids, history)

    def planned(self, time: float, plan: Plan) -> None:
        assert self.log is not None
        self.log.planned(time, plan)

    def event(self, time: float, name: str, detail: str) -> None:
        if self.log is not None:
            self.log.event(time, name, detail)

    def close(self) -> None:
        if self.log is not None:
            self.log.close()
