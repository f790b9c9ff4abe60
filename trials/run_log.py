"""The MCAP log of one simulated run (`runs/<code>.mcap`), topic by topic as docs/study_folder.md lists,
and reading it back (`read_run`).

The log opens in Foxglove as a 3-D scene in frame `map`. Times are simulated seconds since the
start (log times count from 0), never wall-clock time. A blinded run's log names no controller:
the controller's own records (`Plan.record`) are kept back in `records` for the sealed part of the
study instead of going to `/controller/record`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from robot_logs.errors import LogError
from robot_logs.foxglove_log import FoxgloveReader, FoxgloveWriter, color, cylinder, entity, frame_transform, pose, poses_in_frame, scene_update, text
from robot_logs.frames import Pose2D
from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M, STEP_S
from trials.controllers.base import Plan
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotLimits, RobotState

FRAME = "map"
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


def _ns(time: float) -> int:
    return int(round(time * 1e9))


def _r(values: np.ndarray) -> list[float]:
    return [round(float(v), 4) for v in np.asarray(values).ravel()]


class RunLog:
    """Writes one run's MCAP as the simulation reports to it (a `RunSink`).

    Args:
        path: runs/<code>.mcap; the file appears there only when the log is closed normally.
        metadata: the `run` metadata record (strings).
        goal, cone: where they stand (m); a logged trial has no cone (None).
        blind: keep controller records out of the log (they collect in `records`).
        limits: the robot's footprint, for the scene.
    """

    def __init__(self, path: Path, metadata: Mapping[str, str], goal: tuple[float, float], cone: tuple[float, float] | None,
                 blind: bool, limits: RobotLimits = RobotLimits()) -> None:
        self.writer = FoxgloveWriter(path, metadata={"run": metadata})
        self.blind = blind
        self.records: list[dict[str, Any]] = []
        self._limits = limits
        self._fixed = [entity(0, FRAME, "goal", cylinders=[cylinder(*goal, GOAL_TOLERANCE_M, 0.02, GOAL_COLOUR)])]
        if cone is not None:
            self._fixed.append(entity(0, FRAME, "cone", cylinders=[{**cylinder(*cone, 0.15, 0.5, CONE_COLOUR), "top_scale": 0.0}]))

    def state(self, time: float, robot: RobotState, command: tuple[float, float], crowd: Crowd) -> None:
        stamp = _ns(time)
        w = self.writer
        w.write("/tf", "foxglove.FrameTransform", frame_transform(stamp, FRAME, "base_link", Pose2D(robot.x, robot.y, robot.theta)), stamp)
        w.write("/scene", "foxglove.SceneUpdate", scene_update([*self._fixed, self._robot(stamp, robot), self._people(stamp, crowd)]), stamp)
        w.write("/robot/state", "navtrials.RobotState", {
            "t": round(time, 4), "x": round(robot.x, 4), "y": round(robot.y, 4), "theta": round(robot.theta, 4),
            "v": round(robot.v, 4), "w": round(robot.w, 4), "v_cmd": round(command[0], 4), "w_cmd": round(command[1], 4),
        }, stamp)
        w.write("/pedestrians/state", "navtrials.Pedestrians", self._pedestrians(time, crowd.ids, crowd.position, crowd.velocity), stamp)

    def perceived(self, time: float, ids: tuple[int, ...], history: np.ndarray) -> None:
        newest = history[:, -1, :] if len(ids) else np.zeros((0, 2))
        previous = history[:, -2, :] if len(ids) else np.zeros((0, 2))
        velocity = np.nan_to_num((newest - previous) / STEP_S)
        self.writer.write("/perception/pedestrians", "navtrials.Pedestrians", self._pedestrians(time, ids, newest, velocity), _ns(time))

    def planned(self, time: float, plan: Plan) -> None:
        stamp = _ns(time)
        points = np.asarray(plan.waypoints, dtype=float).reshape(-1, 2)
        self.writer.write("/controller/plan", "navtrials.Plan", {"t": round(time, 4), "waypoints": [_r(p) for p in points]}, stamp)
        self.writer.write("/controller/plan_poses", "foxglove.PosesInFrame", poses_in_frame(stamp, FRAME, points), stamp)
        entry = {"t": round(time, 4), "record": jsonable(plan.record)}
        if self.blind:
            self.records.append(entry)
        else:
            self.writer.write("/controller/record", "navtrials.ControllerRecord", entry, stamp)

    def compared(self, time: float, recorded: np.ndarray, figures: Mapping[str, float | None]) -> None:
        """A logged trial's plan against the log: the robot's recorded positions at the way-points' times."""
        stamp = _ns(time)
        points = np.asarray(recorded, dtype=float).reshape(-1, 2)
        self.writer.write("/replay/comparison", "navtrials.ReplayComparison",
                          {"t": round(time, 4), "recorded": [_r(p) for p in points], **jsonable(figures)}, stamp)
        self.writer.write("/replay/recorded_poses", "foxglove.PosesInFrame", poses_in_frame(stamp, FRAME, points), stamp)

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        """Another metadata record (e.g. a logged trial's `replay` summary, known only at the end)."""
        self.writer.add_metadata(name, values)

    def event(self, time: float, name: str, detail: str) -> None:
        self.writer.write("/events", "navtrials.Event", {"t": round(time, 4), "event": name, "detail": detail}, _ns(time))

    def _robot(self, stamp: int, robot: RobotState) -> dict[str, Any]:
        size = {"x": 2.0 * self._limits.half_length, "y": 2.0 * self._limits.half_width, "z": 0.4}
        body = {"pose": pose(robot.x, robot.y, robot.theta, z=0.2), "size": size, "color": color(*ROBOT_COLOUR)}
        return entity(stamp, FRAME, "robot", cubes=[body])

    def _people(self, stamp: int, crowd: Crowd) -> dict[str, Any]:
        bodies = [cylinder(x, y, PEDESTRIAN_RADIUS_M, 1.7, PEDESTRIAN_COLOUR) for x, y in crowd.position]
        labels = [text(x, y, str(i), z=1.9) for i, (x, y) in zip(crowd.ids, crowd.position)]
        return entity(stamp, FRAME, "pedestrians", cylinders=bodies, texts=labels)

    @staticmethod
    def _pedestrians(time: float, ids: tuple[int, ...], positions: np.ndarray, velocities: np.ndarray) -> dict[str, Any]:
        positions, velocities = np.asarray(positions).reshape(-1, 2), np.asarray(velocities).reshape(-1, 2)
        return {"t": round(time, 4), "ids": [int(i) for i in ids], "x": _r(positions[:, 0]), "y": _r(positions[:, 1]),
                "vx": _r(velocities[:, 0]), "vy": _r(velocities[:, 1])}

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


@dataclass(frozen=True)
class LoggedRun:
    """A run read back from its MCAP: metadata, the physics-rate trace and the events.

    Attributes:
        metadata: the `run` metadata record.
        time: (K,) s; pose: (K, 3); velocity: (K, 2) linear, angular.
        ids: pedestrian ids; pedestrians: (K, N, 2) their true positions (NaN while a logged
            trial's person is not tracked).
        events: (t, event, detail) in time order.
        plans: number of planning steps.
        replay: a logged trial's `replay` metadata record (its plans against the log); empty otherwise.
    """

    metadata: dict[str, str]
    time: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray
    ids: tuple[int, ...]
    pedestrians: np.ndarray
    events: list[tuple[float, str, str]]
    plans: int
    replay: dict[str, str] = field(default_factory=dict)

    @property
    def status(self) -> str | None:
        """How the run ended (the last event), None if the log has no ending."""
        endings = [name for _, name, _ in self.events if name != "start"]
        return endings[-1] if endings else None


def read_run(path: Path) -> LoggedRun:
    """Read a run log written by `RunLog`.

    Raises:
        LogError: missing, damaged, unfinished, or not a trials run log.
    """
    reader = FoxgloveReader(path)
    if "run" not in reader.metadata or "/robot/state" not in reader.topics:
        raise LogError(f"{path} is not a trials run log (no `run` metadata or /robot/state topic)")
    robot: list[list[float]] = []
    people: list[tuple[list[int], list[float], list[float]]] = []
    events: list[tuple[float, str, str]] = []
    plans = 0
    try:
        for message in reader.messages(["/robot/state", "/pedestrians/state", "/events", "/controller/plan"]):
            data = message.data
            if message.topic == "/robot/state":
                robot.append([float(data[k]) for k in ("t", "x", "y", "theta", "v", "w")])
            elif message.topic == "/pedestrians/state":
                people.append(([int(i) for i in data["ids"]], data["x"], data["y"]))
            elif message.topic == "/events":
                events.append((float(data["t"]), str(data["event"]), str(data["detail"])))
            else:
                plans += 1
    except (KeyError, TypeError, ValueError) as exc:
        raise LogError(f"{path}: a message breaks the run log format ({exc!r})") from None
    if len(people) != len(robot):
        raise LogError(f"{path}: pedestrian states do not match the robot states one to one")
    ids = tuple(dict.fromkeys(i for present, _, _ in people for i in present))
    column = {i: n for n, i in enumerate(ids)}
    positions = np.full((len(robot), len(ids), 2), np.nan)
    for k, (present, x, y) in enumerate(people):
        positions[k, [column[i] for i in present]] = np.column_stack([x, y]).reshape(-1, 2)
    table = np.array(robot, dtype=float).reshape(-1, 6)
    return LoggedRun(reader.metadata["run"], table[:, 0], table[:, 1:4], table[:, 4:6], ids, positions, events, plans,
                     reader.metadata.get("replay", {}))
