"""The run-log format (`runs/<code>.mcap` of a study): its topics, schemas, metadata records, the
layout of its own messages, and the one reader of it (`read_run`).

`trials` writes these logs (simulated and logged trials) and `analysis` reads them back for the
report; both take the format from here, so it has one owner. docs/run_logs.md describes it.
Times are the run's own seconds (each message's `t`); log times count from 0, or from the wall-clock
start the `clock` metadata records; values are rounded to 0.1 mm.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from robot_logs.errors import LogError
from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.foxglove_schemas import Schema

#: A Foxglove layout for run logs (scene, robot velocity plot, events), built by scripts/foxglove_layout.py.
LAYOUT = Path(__file__).with_name("run_log_layout.json")
#: The fixed frame of every run log's 3-D scene.
FRAME = "map"
#: Metadata records: the run's settings, a logged trial's plans against the log, and the log times' origin.
RUN_METADATA = "run"
REPLAY_METADATA = "replay"
CLOCK_METADATA = "clock"


class Topic(NamedTuple):
    """A channel of the run log: its name and schema (`FoxgloveWriter.write(*topic, message, stamp)`)."""

    name: str
    schema: str


TRANSFORM = Topic("/tf", "foxglove.FrameTransform")
SCENE = Topic("/scene", "foxglove.SceneUpdate")
ROBOT_STATE = Topic("/robot/state", "navtrials.RobotState")
PEDESTRIANS = Topic("/pedestrians/state", "navtrials.Pedestrians")
PERCEIVED = Topic("/perception/pedestrians", "navtrials.Pedestrians")
PLAN = Topic("/controller/plan", "navtrials.Plan")
PLAN_POSES = Topic("/controller/plan_poses", "foxglove.PosesInFrame")
CONTROLLER_RECORD = Topic("/controller/record", "navtrials.ControllerRecord")
COMPARISON = Topic("/replay/comparison", "navtrials.ReplayComparison")
RECORDED_POSES = Topic("/replay/recorded_poses", "foxglove.PosesInFrame")
EVENTS = Topic("/events", "navtrials.Event")
#: A live run's own sensors: every scan (placed in the run's frame at its stamp) and the robot's tf as it sent it.
SCAN = Topic("/scan", "foxglove.LaserScan")
ROBOT_TF = Topic("/robot/tf", "foxglove.FrameTransform")
#: What the controller computed (its plans, its own record, a logged trial's plans against the log):
#: a blinded run keeps these out of its public log, in its sealed record, with the `replay` metadata.
CONTROLLER_TOPICS = (PLAN, PLAN_POSES, CONTROLLER_RECORD, COMPARISON, RECORDED_POSES)



def _number(description: str) -> Schema:
    return {"type": "number", "description": description}


def _numbers(description: str) -> Schema:
    return {"type": "array", "items": {"type": "number"}, "description": description}


def _points(description: str) -> Schema:
    return {"type": "array", "items": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}, "description": description}


def _optional(description: str) -> Schema:
    return {"type": ["number", "null"], "description": description}


def _record(name: str, description: str, required: tuple[str, ...], properties: Schema, closed: bool = True) -> Schema:
    """A message type's JSON schema; `closed`: no fields beyond `properties`."""
    return {"title": name, "description": description, "type": "object", "properties": properties,
            "required": list(required), "additionalProperties": not closed}


TIME_S = _number("run time, s since the start")
#: The JSON schema of each of the run log's own message types, so Foxglove's panels know their fields.
SCHEMAS: dict[str, Schema] = {
    ROBOT_STATE.schema: _record(ROBOT_STATE.schema, "the robot's pose and velocity at each physics step", ("t", "x", "y", "theta", "v", "w"), {
        "t": TIME_S, "x": _number("m, map frame"), "y": _number("m, map frame"), "theta": _number("heading, rad"),
        "v": _number("linear velocity, m/s"), "w": _number("angular velocity, rad/s"),
        "v_cmd": _number("commanded linear velocity, m/s (absent from a blinded run's log)"),
        "w_cmd": _number("commanded angular velocity, rad/s (absent from a blinded run's log)")}),
    PEDESTRIANS.schema: _record(PEDESTRIANS.schema, "pedestrians' positions and velocities; index i of each array is person ids[i]",
                                ("t", "ids", "x", "y", "vx", "vy"), {
        "t": TIME_S, "ids": {"type": "array", "items": {"type": "integer"}, "description": "pedestrian ids"},
        "x": _numbers("m, map frame"), "y": _numbers("m, map frame"), "vx": _numbers("m/s"), "vy": _numbers("m/s")}),
    PLAN.schema: _record(PLAN.schema, "the way-points a controller planned, one every 0.4 s", ("t", "waypoints"), {
        "t": TIME_S, "waypoints": _points("[x, y] in m, map frame")}),
    CONTROLLER_RECORD.schema: _record(CONTROLLER_RECORD.schema, "what a controller logged with a plan; fields depend on the controller",
                                      ("t", "record"), {
        "t": TIME_S,
        "record": {"type": "object", "additionalProperties": True, "properties": {
            "controller": {"type": "string"}, "plan_seconds": _number("time the controller took to plan, s"),
            "subgoal": _numbers("NaviGAN-R: [x, y] it steered to, m"), "intention": _points("NaviGAN-R: intended way-points, m"),
            "forces": _points("NaviGAN-R: social-force corrections, m"), "status": {"type": "string", "description": "lattice: search result"},
            "holding": {"type": "boolean", "description": "lattice: standing still"}, "pedestrians": {"type": "integer"},
            "margin": _number("lattice: comfort margin, m"), "rung": {"type": "string", "description": "lattice: recovery rung"}}}}),
    COMPARISON.schema: _record(COMPARISON.schema, "a logged trial's plan against the robot's recorded positions", ("t", "recorded"), {
        "t": TIME_S, "recorded": _points("[x, y] recorded at the way-points' times, m"),
        "deviation_m": _optional("mean distance from the plan, m"), "final_deviation_m": _optional("last way-point's distance, m"),
        "min_clearance_m": _optional("smallest predicted gap to a person, m (null: nobody there)")}),
    EVENTS.schema: _record(EVENTS.schema, "the run's start and how it ended", ("t", "event", "detail"), {
        "t": TIME_S, "event": {"type": "string", "enum": ["start", "goal", "collision", "timeout"]},
        "detail": {"type": "string"}}),
}

#: The fields of a /robot/state message the reader uses, in the order of `LoggedRun`'s arrays.
ROBOT_FIELDS = ("t", "x", "y", "theta", "v", "w")


def stamp_ns(time: float) -> int:
    """A run time (s) as a log time (ns)."""
    return round(time * 1e9)


def clock(start_ns: int) -> dict[str, str]:
    """The `clock` metadata: the log time (ns since 1970) of the run's start, and that instant in UTC when
    it is a wall-clock time (empty when log times are the run's own seconds)."""
    from datetime import UTC, datetime

    utc = datetime.fromtimestamp(start_ns / 1e9, UTC).isoformat() if start_ns else ""
    return {"start_ns": str(start_ns), "start_utc": utc}


def rounded(values: Any) -> list[float]:
    """Values flattened to a list, rounded as the log stores them."""
    return [round(float(v), 4) for v in np.asarray(values).ravel()]


def robot_state(time: float, pose: tuple[float, float, float], velocity: tuple[float, float],
                command: tuple[float, float] | None) -> dict[str, float]:
    """/robot/state: the robot's pose (m, rad), velocity (m/s, rad/s) and the commanded velocity
    (left out when None: a blinded run's command follows its controller's plan)."""
    (x, y, theta), (v, w) = pose, velocity
    state = {"t": round(time, 4), "x": round(x, 4), "y": round(y, 4), "theta": round(theta, 4), "v": round(v, 4), "w": round(w, 4)}
    return state if command is None else {**state, **robot_command(command)}


def robot_command(command: tuple[float, float]) -> dict[str, float]:
    """The commanded velocity of /robot/state (m/s, rad/s); a blinded run's sealed record keeps it."""
    return {"v_cmd": round(command[0], 4), "w_cmd": round(command[1], 4)}


def pedestrians(time: float, ids: tuple[int, ...], positions: np.ndarray, velocities: np.ndarray) -> dict[str, Any]:
    """/pedestrians/state and /perception/pedestrians: ids with their (N, 2) positions and velocities."""
    positions, velocities = np.asarray(positions).reshape(-1, 2), np.asarray(velocities).reshape(-1, 2)
    return {"t": round(time, 4), "ids": [int(i) for i in ids], "x": rounded(positions[:, 0]), "y": rounded(positions[:, 1]),
            "vx": rounded(velocities[:, 0]), "vy": rounded(velocities[:, 1])}


def plan(time: float, waypoints: np.ndarray) -> dict[str, Any]:
    """/controller/plan: the way-points a controller planned, (M, 2)."""
    return {"t": round(time, 4), "waypoints": [rounded(p) for p in np.asarray(waypoints, dtype=float).reshape(-1, 2)]}


def controller_record(time: float, record: Any) -> dict[str, Any]:
    """/controller/record (or a blinded run's sealed steps): a controller's own record of a plan, as JSON."""
    return {"t": round(time, 4), "record": record}


def comparison(time: float, recorded: np.ndarray, figures: Mapping[str, Any]) -> dict[str, Any]:
    """/replay/comparison: a logged trial's plan against the recorded positions at the way-points' times."""
    return {"t": round(time, 4), "recorded": [rounded(p) for p in np.asarray(recorded, dtype=float).reshape(-1, 2)], **figures}


def event(time: float, name: str, detail: str) -> dict[str, Any]:
    """/events: "start", then how the run ended ("goal", "collision", "timeout")."""
    return {"t": round(time, 4), "event": name, "detail": detail}


@dataclass(frozen=True)
class LoggedRun:
    """A run read back from its MCAP: metadata, the physics-rate trace and the events.

    Attributes:
        metadata: the `run` metadata record.
        time: (K,) s; pose: (K, 3); velocity: (K, 2) linear, angular.
        ids: pedestrian ids; pedestrians: (K, N, 2) their true positions (NaN while a pedestrian
            is absent, e.g. a logged trial's person not tracked then).
        events: (t, event, detail) in time order.
        plans: number of planning steps (0 in a blinded run's public log: its plans are sealed).
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
    """Read a run log.

    Raises:
        LogError: missing, damaged, not a run log (no `run` metadata or no robot states), a message
            without a field of the format, or pedestrian states that do not pair with robot states.
    """
    reader = FoxgloveReader(path)
    if RUN_METADATA not in reader.metadata or ROBOT_STATE.name not in reader.topics:
        raise LogError(f"{path} is not a trials run log (no `{RUN_METADATA}` metadata or {ROBOT_STATE.name} topic)")
    robot: list[list[float]] = []
    people: list[tuple[list[int], list[float], list[float]]] = []
    events: list[tuple[float, str, str]] = []
    plans = 0
    topic = ""
    try:
        for message in reader.messages([ROBOT_STATE.name, PEDESTRIANS.name, EVENTS.name, PLAN.name]):
            data, topic = message.data, message.topic
            if topic == ROBOT_STATE.name:
                robot.append([float(data[k]) for k in ROBOT_FIELDS])
            elif topic == PEDESTRIANS.name:
                people.append(([int(i) for i in data["ids"]], [float(x) for x in data["x"]], [float(y) for y in data["y"]]))
            elif topic == EVENTS.name:
                events.append((float(data["t"]), str(data["event"]), str(data["detail"])))
            else:
                plans += 1
    except LogError:
        raise  # a damaged file, said as such: not a message of the wrong form
    except KeyError as exc:
        raise LogError(f"{path}: a {topic} message lacks field {exc} of the run-log format (docs/run_logs.md)") from None
    except (TypeError, ValueError) as exc:
        raise LogError(f"{path}: a {topic} message breaks the run-log format (docs/run_logs.md): {exc}") from None
    if not robot:
        raise LogError(f"{path}: no {ROBOT_STATE.name} messages")
    if len(people) != len(robot):
        raise LogError(f"{path}: pedestrian states do not match the robot states one to one")
    ids = tuple(dict.fromkeys(i for present, _, _ in people for i in present))
    column = {i: n for n, i in enumerate(ids)}
    positions = np.full((len(robot), len(ids), 2), np.nan)
    for k, (present, x, y) in enumerate(people):
        positions[k, [column[i] for i in present]] = np.column_stack([x, y]).reshape(-1, 2)
    table = np.array(robot, dtype=float).reshape(-1, len(ROBOT_FIELDS))
    return LoggedRun(reader.metadata[RUN_METADATA], table[:, 0], table[:, 1:4], table[:, 4:6], ids, positions, events, plans,
                     reader.metadata.get(REPLAY_METADATA, {}))
