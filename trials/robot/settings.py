"""The `[robot]` table of study.toml: how a live run reaches and drives the robot, checked when read.

Every key is optional; the defaults fit a Husky- or TurtleBot-class base running stock ROS drivers:

    [robot]
    uri = "ros1://127.0.0.1:11311"  # or "ros2://0" (a ROS 2 domain id); `--robot` overrides it
    scan_topic = "/scan"            # sensor_msgs/LaserScan
    odometry_topic = "/odom"        # nav_msgs/Odometry; "" reads the base's pose from tf instead
    cmd_vel_topic = "/cmd_vel"      # the base's velocity command
    cmd_vel_type = "Twist"          # geometry_msgs/Twist, or "TwistStamped" (e.g. Nav2 on Jazzy with stamped velocities)
    cmd_vel_frame = "base_link"     # a TwistStamped command's header frame
    estop_topic = "/e_stop"         # std_msgs/Bool: true stops the run at once
    odometry_frame = "odom"
    base_frame = "base_link"
    goal_frame = "mark"             # the frame of start and goal: "mark" (the start mark measured by `trials run --robot URI
                                    # --mark`), "map" or any frame tf connects to the odometry frame, the odometry frame, or
                                    # "start" (wherever the robot stands when its run begins: rehearsals only, nothing staged)
    start = [0.0, 0.0, 0.0]         # x, y, yaw of every run's start in goal_frame
    start_tolerance = [0.3, 0.35]   # m and rad: a run starts only with the robot this near its start
    goal = [10.0, 0.0]              # x, y (and optionally yaw) in goal_frame
    max_speed = 1.0                 # m/s forward (backwards at most half of it)
    max_turn_rate = 2.0             # rad/s
    max_acceleration = 1.5          # m/s^2
    max_angular_acceleration = 3.0  # rad/s^2
    footprint = [0.99, 0.67]        # m: length and width of the base's rectangle, centred on base_frame
    protective_margin = 0.1         # m around the footprint: a laser return inside it stops the robot
    reaction_time = 0.2             # s the robot travels before braking begins, in the protective field's braking distance
    protective_hold = 3.0           # s: a protective stop held this long ends the run
    stall_time = 2.0                # s of commanded motion without motion in odometry that end the run (a stall, a deaf base)
    watchdog = 0.5                  # s: valid scans or odometry older than this stop the robot
    plan_timeout = 1.0              # s: a plan the controller has not answered within this stops the robot and ends the run
    min_valid_share = 0.05          # share of a scan's beams that must return a range; a scan with fewer counts as missing
    sensor_wait = 20.0              # s to wait for scans, odometry, the laser's transform and the robot at its start
    people_radius = 8.0             # m: people tracked this near the robot count for the run's manipulation check
    min_people_share = 0.5          # the row's condition is met when this share of its Pedestrians was tracked at once
    timeout = 60.0                  # s of driving before the run ends as a timeout
    command_rate = 20.0             # Hz of velocity commands
    nav_stack_action = ""           # the robot's own navigation stack, for a NavStack arm: its action ("" = move_base on
                                    # ROS 1, navigate_to_pose on ROS 2)
    nav_stack_cmd_vel_topic = "/cmd_vel_nav"  # where the stack's velocity commands go (remapped from the base's): the run
                                    # relays them to cmd_vel_topic through the same limits and protective field
    nav_stack_cmd_vel_type = "Twist"  # Twist or TwistStamped

    [robot.goals]                   # a goal per level of the plan's Direction factor, in goal_frame
    Crossing = [10.0, 0.0]

`designs.spec` leaves this table to this module, as it leaves `[run]` to `trials.run_settings`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from robot_logs.physical import STEP_S
from trials.errors import StudyError
from trials.robot.transport import ROS1, TWIST_TYPES, RobotUri
from trials.scenario import DIRECTION, GOAL
from trials.sim.robot import RobotLimits
from trials.study import study_table

#: The study.toml table this module reads.
TABLE = "robot"
#: The goal frames that are not tf frames: the robot's pose as its run begins, and the study's start mark.
START_FRAME, MARK_FRAME = "start", "mark"
DEFAULT_URI = "ros1://127.0.0.1:11311"


@dataclass(frozen=True)
class RobotSettings:
    """How a live run reaches the robot, what it reads and commands, its limits and its safety timing."""

    uri: str = DEFAULT_URI
    scan_topic: str = "/scan"
    odometry_topic: str = "/odom"
    cmd_vel_topic: str = "/cmd_vel"
    cmd_vel_type: str = TWIST_TYPES[0]
    cmd_vel_frame: str = "base_link"
    estop_topic: str = "/e_stop"
    odometry_frame: str = "odom"
    base_frame: str = "base_link"
    goal_frame: str = MARK_FRAME
    start: tuple[float, ...] = (0.0, 0.0, 0.0)
    start_tolerance: tuple[float, ...] = (0.3, 0.35)
    goal: tuple[float, ...] = GOAL
    goals: dict[str, tuple[float, ...]] = field(default_factory=dict)
    max_speed: float = RobotLimits.max_speed
    max_turn_rate: float = RobotLimits.max_turn_rate
    max_acceleration: float = RobotLimits.max_acceleration
    max_angular_acceleration: float = RobotLimits.max_angular_acceleration
    footprint: tuple[float, ...] = (2.0 * RobotLimits.half_length, 2.0 * RobotLimits.half_width)
    protective_margin: float = 0.1
    reaction_time: float = 0.2
    protective_hold: float = 3.0
    stall_time: float = 2.0
    watchdog: float = 0.5
    plan_timeout: float = 1.0
    min_valid_share: float = 0.05
    sensor_wait: float = 20.0
    people_radius: float = 8.0
    min_people_share: float = 0.5
    timeout: float = 60.0
    command_rate: float = 20.0
    nav_stack_action: str = ""
    nav_stack_cmd_vel_topic: str = "/cmd_vel_nav"
    nav_stack_cmd_vel_type: str = TWIST_TYPES[0]

    @property
    def navigation_action(self) -> str:
        """The navigation stack's action: `nav_stack_action`, by default move_base's (ROS 1) or Nav2's (ROS 2)."""
        return self.nav_stack_action or ("move_base" if self.robot_uri.scheme == ROS1 else "navigate_to_pose")

    @property
    def robot_uri(self) -> RobotUri:
        return RobotUri.parse(self.uri)

    @property
    def limits(self) -> RobotLimits:
        """The follower's limits: the table's speeds and accelerations, backwards at half speed, and its footprint."""
        return RobotLimits(max_speed=self.max_speed, max_reverse_speed=0.5 * self.max_speed, max_turn_rate=self.max_turn_rate,
                           max_acceleration=self.max_acceleration, max_angular_acceleration=self.max_angular_acceleration,
                           half_length=0.5 * self.footprint[0], half_width=0.5 * self.footprint[1])

    def goal_for(self, row: dict[str, str]) -> tuple[float, ...]:
        """The goal of a plan row: its Direction level's, else the table's `goal`."""
        return self.goals.get(row.get(DIRECTION, ""), self.goal)

    def recorded(self) -> dict[str, str]:
        """The settings as a run log's metadata records them (strings)."""
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "goals"}
        text = {name: (" ".join(f"{v:g}" for v in value) if isinstance(value, tuple) else
                       f"{value:g}" if isinstance(value, float) else str(value)) for name, value in values.items()}
        return {f"robot_{name}": value for name, value in text.items()}


#: Numeric keys and their closed ranges.
RANGES: dict[str, tuple[float, float]] = {
    "max_speed": (0.01, 5.0), "max_turn_rate": (0.01, 10.0), "max_acceleration": (0.01, 20.0),
    "max_angular_acceleration": (0.01, 50.0), "protective_margin": (0.0, 2.0), "reaction_time": (0.0, 2.0),
    "protective_hold": (0.5, 600.0), "stall_time": (0.5, 60.0), "watchdog": (0.05, 5.0), "plan_timeout": (0.1, 10.0),
    "min_valid_share": (0.0, 1.0),
    "sensor_wait": (0.5, 600.0), "people_radius": (0.5, 50.0), "min_people_share": (0.0, 1.0), "timeout": (STEP_S, 3600.0), "command_rate": (5.0, 200.0),
}
TEXTS = ("uri", "scan_topic", "odometry_topic", "cmd_vel_topic", "cmd_vel_type", "cmd_vel_frame", "estop_topic", "odometry_frame",
         "base_frame", "goal_frame", "nav_stack_action", "nav_stack_cmd_vel_topic", "nav_stack_cmd_vel_type")
#: The text keys that may be empty.
MAY_BE_EMPTY = ("odometry_topic", "nav_stack_action")
KEYS = (*TEXTS, "footprint", *RANGES, "start", "start_tolerance", "goal", "goals")
#: The footprint's closed range of length and width (m).
FOOTPRINT_M = (0.05, 10.0)
#: The start tolerance's closed ranges (m, rad).
START_TOLERANCE = ((0.01, 5.0), (0.01, math.pi))
#: Furthest goal coordinate a table may give (m): beyond it a value is a typing slip.
MAX_GOAL_M = 1e4


def read_robot_settings(spec: Path) -> RobotSettings | None:
    """The `[robot]` table of a study.toml, checked; None when the study has none (it is not driven live).

    Raises:
        StudyError: unreadable TOML, an unknown key, or a value of the wrong kind or out of range, naming the file and key.
    """
    table = study_table(spec, TABLE)
    return None if table is None else settings_from_table(table, f"{spec} [{TABLE}]")


def robot_table(spec: Path | None, uri: str | None = None) -> dict[str, Any]:
    """The `[robot]` table of a study.toml as written ({} without one), after checking it, so that `trials design` can
    carry it into the study.toml it writes; with `uri` (`trials design --robot`) that uri and every key the table leaves
    out at its default, so the lab edits what its robot has."""
    settings = read_robot_settings(spec) if spec is not None else None
    table = tomllib.loads(spec.read_text(encoding="utf-8")).get(TABLE, {}) if settings is not None and spec is not None else {}
    if uri is not None:
        RobotUri.parse(uri)
        table = {**default_table(), **table, "uri": uri}
    return table


def default_table() -> dict[str, Any]:
    """Every key of the `[robot]` table at its default, in the order the docs list them (no `goals`: none by default)."""
    defaults = RobotSettings()
    return {f.name: list(value) if isinstance(value := getattr(defaults, f.name), tuple) else value
            for f in fields(defaults) if f.name != "goals"}


def settings_from_table(table: dict[str, Any], where: str) -> RobotSettings:
    """RobotSettings from a `[robot]` table, each key checked; StudyError names `where` and the key."""
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise StudyError(f"{where}: unknown key {unknown[0]!r} (expected {', '.join(KEYS)})")
    values: dict[str, Any] = {}
    for key in TEXTS:
        if key in table:
            values[key] = _text(table[key], key, where, empty=key in MAY_BE_EMPTY)
    for key in ("cmd_vel_type", "nav_stack_cmd_vel_type"):
        if values.get(key, TWIST_TYPES[0]) not in TWIST_TYPES:
            raise StudyError(f"{where}: {key} must be one of {', '.join(TWIST_TYPES)}, got {values[key]!r}")
    if "footprint" in table:
        size = table["footprint"]
        low, high = FOOTPRINT_M
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int | float) and not isinstance(v, bool)
                                                                 and math.isfinite(v) and low <= v <= high for v in size)):
            raise StudyError(f"{where}: footprint must be [length, width] in metres, each in [{low:g}, {high:g}], got {size!r}")
        values["footprint"] = tuple(float(v) for v in size)
    if "uri" in values:
        try:
            RobotUri.parse(values["uri"])
        except StudyError as exc:
            raise StudyError(f"{where}: uri: {exc}") from None
    for key, (low, high) in RANGES.items():
        if key in table:
            value = table[key]
            if not (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and low <= value <= high):
                raise StudyError(f"{where}: {key} must be a number in [{low:g}, {high:g}], got {value!r}")
            values[key] = float(value)
    if "start" in table:
        values["start"] = _pose(table["start"], "start", where)
        values["start"] += (0.0,) * (3 - len(values["start"]))
    if "start_tolerance" in table:
        tolerance = table["start_tolerance"]
        if not (isinstance(tolerance, list) and len(tolerance) == 2 and all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and low <= v <= high
                for v, (low, high) in zip(tolerance, START_TOLERANCE))):
            (m0, m1), (r0, r1) = START_TOLERANCE
            raise StudyError(f"{where}: start_tolerance must be [metres, radians], in [{m0:g}, {m1:g}] and [{r0:g}, {r1:.4g}], "
                             f"got {tolerance!r}")
        values["start_tolerance"] = tuple(float(v) for v in tolerance)
    if "goal" in table:
        values["goal"] = _pose(table["goal"], "goal", where)
    if "goals" in table:
        goals = table["goals"]
        if not isinstance(goals, dict):
            raise StudyError(f"{where}: goals must be a table of Direction level = [x, y], got {goals!r}")
        values["goals"] = {str(level): _pose(pose, f"goals.{level}", where) for level, pose in goals.items()}
    settings = RobotSettings(**values)
    if settings.nav_stack_cmd_vel_topic in (settings.cmd_vel_topic, settings.estop_topic):
        raise StudyError(f"{where}: nav_stack_cmd_vel_topic must differ from cmd_vel_topic and estop_topic (the run relays the "
                         f"stack's commands to the base), got {settings.nav_stack_cmd_vel_topic!r}")
    if settings.watchdog * settings.command_rate < 2.0:
        raise StudyError(f"{where}: watchdog {settings.watchdog:g} s is shorter than two commands at {settings.command_rate:g} Hz")
    return settings


def _text(value: Any, key: str, where: str, empty: bool) -> str:
    if not isinstance(value, str) or (not value.strip() and not empty) or value != value.strip():
        wanted = "a name (may be empty)" if empty else "a non-empty name without surrounding spaces"
        raise StudyError(f"{where}: {key} must be {wanted}, got {value!r}")
    return value


def _pose(value: Any, key: str, where: str) -> tuple[float, ...]:
    ok = (isinstance(value, list) and len(value) in (2, 3)
          and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= MAX_GOAL_M for v in value))
    if not ok:
        raise StudyError(f"{where}: {key} must be [x, y] or [x, y, yaw] in metres and radians (|value| <= {MAX_GOAL_M:g}), got {value!r}")
    return tuple(float(v) for v in value)
