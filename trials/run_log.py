"""Writing the MCAP log of one run (`runs/<code>.mcap`) in the format `robot_logs.run_log` owns
(topics, schemas, message layout; it also reads the log back).

The log opens in Foxglove as a 3-D scene in its frame. Log times are simulated seconds since the
start, counted from 0 (1970-01-01 in Foxglove) unless the log is given a wall-clock start
(`start_ns`, `trials run --wall-clock`); the messages' own `t` is always the run's seconds. A blinded run's log holds only what an
observer of the trial could see (the motion, the scene, the events): what the controller computed
(`fmt.CONTROLLER_TOPICS`, the `replay` metadata, and the commanded velocity the path follower took
from its plan) is kept back (`withheld`, `withheld_metadata`, `withheld_commands`) for the run's
sealed record instead.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from robot_logs import run_log as fmt
from robot_logs.foxglove_log import (
    FoxgloveWriter,
    color,
    cylinder,
    entity,
    frame_transform,
    pose,
    poses_in_frame,
    scene_update,
    text,
)
from robot_logs.frames import Pose2D
from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M, STEP_S
from trials.controllers.base import Plan
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotLimits, RobotState

FRAME = fmt.FRAME
ROBOT_COLOUR = (0.95, 0.75, 0.1, 1.0)
PEDESTRIAN_COLOUR = (0.2, 0.45, 0.9, 1.0)
GOAL_COLOUR = (0.1, 0.8, 0.3, 0.35)
CONE_COLOUR = (1.0, 0.45, 0.0, 1.0)


def jsonable(value: Any) -> Any:
    """`value` as plain JSON: arrays to lists, tuples to lists, NaN and infinities to None."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


class RunLog:
    """Writes one run's MCAP as the simulation reports to it (a `RunSink`).

    Args:
        path: runs/<code>.mcap; the file appears there only when the log is closed normally.
        metadata: the `run` metadata record (strings).
        goal, cone: where they stand (m); a logged trial has no cone (None).
        blind: keep what the controller computed out of the log (it collects in `withheld`).
        limits: the robot's footprint, for the scene.
        start_ns: the log time of the run's start, ns since 1970 (0: log times are the run's own seconds).
        chunk_size: the MCAP chunk size (bytes): a live run's log takes small ones, so that little is lost if its
            process is killed.
    """

    def __init__(self, path: Path, metadata: Mapping[str, str], goal: tuple[float, float], cone: tuple[float, float] | None,
                 blind: bool, limits: RobotLimits = RobotLimits(), start_ns: int = 0, chunk_size: int = 1024 * 1024) -> None:
        self.writer = FoxgloveWriter(path, metadata={fmt.RUN_METADATA: metadata, fmt.CLOCK_METADATA: fmt.clock(start_ns)},
                                     schemas=fmt.SCHEMAS, chunk_size=chunk_size)
        self._start_ns = start_ns
        self.blind = blind
        #: A blinded run's controller output: topic name -> its messages; metadata name -> record.
        self.withheld: dict[str, list[dict[str, Any]]] = {}
        self.withheld_metadata: dict[str, dict[str, str]] = {}
        #: The velocity commanded at each state, which the path follower takes from the plan.
        self.withheld_commands: list[dict[str, float]] = []
        self._limits = limits
        self._fixed = [entity(0, FRAME, "goal", cylinders=[cylinder(*goal, GOAL_TOLERANCE_M, 0.02, GOAL_COLOUR)])]
        if cone is not None:
            self._fixed.append(entity(0, FRAME, "cone", cylinders=[{**cylinder(*cone, 0.15, 0.5, CONE_COLOUR), "top_scale": 0.0}]))

    def stamp(self, time: float) -> int:
        """The log time (ns) of a run time (s)."""
        return self._start_ns + fmt.stamp_ns(time)

    def state(self, time: float, robot: RobotState, command: tuple[float, float], crowd: Crowd) -> None:
        stamp = self.stamp(time)
        w = self.writer
        w.write(*fmt.TRANSFORM, frame_transform(stamp, FRAME, "base_link", Pose2D(robot.x, robot.y, robot.theta)), stamp)
        w.write(*fmt.SCENE, scene_update([*self._fixed, self._robot(stamp, robot), self._people(stamp, crowd)]), stamp)
        if self.blind:
            self.withheld_commands.append({"t": round(time, 4), **fmt.robot_command(command)})
        public_command = None if self.blind else command
        w.write(*fmt.ROBOT_STATE, fmt.robot_state(time, (robot.x, robot.y, robot.theta), (robot.v, robot.w), public_command), stamp)
        w.write(*fmt.PEDESTRIANS, fmt.pedestrians(time, crowd.ids, crowd.position, crowd.velocity), stamp)

    def perceived(self, time: float, ids: tuple[int, ...], history: np.ndarray) -> None:
        newest = history[:, -1, :] if len(ids) else np.zeros((0, 2))
        previous = history[:, -2, :] if len(ids) else np.zeros((0, 2))
        velocity = np.nan_to_num((newest - previous) / STEP_S)
        self.writer.write(*fmt.PERCEIVED, fmt.pedestrians(time, ids, newest, velocity), self.stamp(time))

    def planned(self, time: float, plan: Plan) -> None:
        stamp = self.stamp(time)
        points = np.asarray(plan.waypoints, dtype=float).reshape(-1, 2)
        self._controller_output(fmt.PLAN, fmt.plan(time, points), stamp)
        self._controller_output(fmt.PLAN_POSES, poses_in_frame(stamp, FRAME, points), stamp)
        self._controller_output(fmt.CONTROLLER_RECORD, fmt.controller_record(time, jsonable(plan.record)), stamp)

    def compared(self, time: float, recorded: np.ndarray, figures: Mapping[str, float | None]) -> None:
        """A logged trial's plan against the log: the robot's recorded positions at the way-points' times."""
        stamp = self.stamp(time)
        points = np.asarray(recorded, dtype=float).reshape(-1, 2)
        self._controller_output(fmt.COMPARISON, fmt.comparison(time, points, jsonable(figures)), stamp)
        self._controller_output(fmt.RECORDED_POSES, poses_in_frame(stamp, FRAME, points), stamp)

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        """Another metadata record (e.g. a logged trial's `replay` summary, known only at the end;
        figures of the controller's plans, so a blinded run keeps it in `withheld`)."""
        if self.blind and name == fmt.REPLAY_METADATA:
            self.withheld_metadata[name] = dict(values)
        else:
            self.writer.add_metadata(name, values)

    def _controller_output(self, topic: fmt.Topic, message: dict[str, Any], stamp: int) -> None:
        """Log a message the controller's output made; a blinded run keeps it (but the poses, which
        only redraw the plan for Foxglove) for its sealed record."""
        if not self.blind:
            self.writer.write(*topic, message, stamp)
        elif topic not in (fmt.PLAN_POSES, fmt.RECORDED_POSES):
            self.withheld.setdefault(topic.name, []).append(message)

    def event(self, time: float, name: str, detail: str) -> None:
        self.writer.write(*fmt.EVENTS, fmt.event(time, name, detail), self.stamp(time))

    def _robot(self, stamp: int, robot: RobotState) -> dict[str, Any]:
        size = {"x": 2.0 * self._limits.half_length, "y": 2.0 * self._limits.half_width, "z": 0.4}
        body = {"pose": pose(robot.x, robot.y, robot.theta, z=0.2), "size": size, "color": color(*ROBOT_COLOUR)}
        return entity(stamp, FRAME, "robot", cubes=[body])

    def _people(self, stamp: int, crowd: Crowd) -> dict[str, Any]:
        bodies = [cylinder(x, y, PEDESTRIAN_RADIUS_M, 1.7, PEDESTRIAN_COLOUR) for x, y in crowd.position]
        labels = [text(x, y, str(i), z=1.9) for i, (x, y) in zip(crowd.ids, crowd.position)]
        return entity(stamp, FRAME, "pedestrians", cylinders=bodies, texts=labels)

    def close(self) -> None:
        self.writer.close()

    def abort(self) -> None:
        self.writer.abort()

    def __enter__(self) -> RunLog:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
