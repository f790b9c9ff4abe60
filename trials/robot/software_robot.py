"""The software robot: the closed-loop simulator behind a robot's ROS topics, for rehearsing a field day and for tests.

It publishes what a Husky- or TurtleBot-class base with a planar lidar does: LaserScans of the simulated
lidar (walkers drawn as legs, `robot_logs.lidar_sim`), nav_msgs/Odometry, and tf (odometry frame to base
frame, and the laser's static mount), all stamped with this computer's clock; it obeys geometry_msgs/Twist
within the robot's limits, and like a real base it stops by itself when no command has come for
`command_timeout` seconds (what stops a robot whose driver was killed).

The robot stands in a walled room (a rectangle in the odometry frame, 22 x 10 m by default, the robot's start 6 m
from one end) and has a bumper: a move that would make its footprint touch a wall is not made, the base stops, and
the contact is written to the `contacts` file, so a test can tell that a wall was touched. When a live run
announces its code (`trials.robot.live.RUN_TOPIC`), the robot is brought to that row's start, as the operator would
bring a real one (`trials.robot.staging`: the row's start in the odometry frame, or relative to the study's start mark;
its own start otherwise), and lays out that plan row's scene (`trials.scenario`, seeded as `trials run` would simulate it)
around it, so the walkers appear ahead; without a study it lays out the default scene. `unstaged` rehearses a row staged
wrong: a robot left where it stands, or walkers who never came.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from contextlib import suppress
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from robot_logs.frames import Pose2D, frame_name
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.records import Odometry, Scan, Transform
from trials.errors import StudyError
from trials.robot.live import RUN_TOPIC, SOFTWARE_ROBOT_TOPIC
from trials.robot.settings import RobotSettings
from trials.robot.staging import row_scenario, stage_of
from trials.robot.transport import ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST_KINDS, Transport, Velocity
from trials.scenario import Scenario
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotState, footprint_gaps, step_robot
from trials.sim.social_force import SocialForceParams
from trials.study import StudyFolder

#: Failures a rehearsal can stage, each from some seconds after a run is announced: scans stop coming; scans keep
#: coming but `FAULT_LAG_S` late by their stamps; scans keep coming with every range NaN; odometry stops; odometry
#: keeps coming with its stamp frozen; the wheels are blocked (commands are heard, the base does not move); the robot's
#: clock steps `CLOCK_STEP_S` back or ahead (every stamp after it); one scan is stamped `CLOCK_STEP_S` ahead; odometry
#: jumps `JUMP_M` ahead; the scans' frame changes; tf gets a transform from the base back to the odometry frame (a loop);
#: scans come with `HUGE_BEAMS` beams.
SCANS_STOP, SCANS_LATE, SCANS_BLANK = "scans-stop", "scans-late", "scans-blank"
ODOMETRY_STOP, ODOMETRY_STALE, STALL = "odometry-stop", "odometry-stale", "stall"
CLOCK_BACK, CLOCK_AHEAD, SCAN_FUTURE = "clock-back", "clock-ahead", "scan-future"
ODOMETRY_JUMP, FRAME_CHANGE, TF_LOOP, SCANS_HUGE = "odometry-jump", "frame-change", "tf-loop", "scans-huge"
FAULTS = (SCANS_STOP, SCANS_LATE, SCANS_BLANK, ODOMETRY_STOP, ODOMETRY_STALE, STALL,
          CLOCK_BACK, CLOCK_AHEAD, SCAN_FUTURE, ODOMETRY_JUMP, FRAME_CHANGE, TF_LOOP, SCANS_HUGE)
FAULT_LAG_S = 1.0
CLOCK_STEP_S, JUMP_M, HUGE_BEAMS = 30.0, 50.0, 100_000
#: The default room: x from, y from, x to, y to (m, odometry frame), around a start at the origin facing +x.
ROOM = (-6.0, -5.0, 16.0, 5.0)
#: Spacing (m) of the points along the walls that the bumper checks against the footprint.
BUMPER_STEP_M = 0.02


@dataclass(frozen=True)
class Fault:
    """A staged failure: its kind (`FAULTS`) and when it begins, in seconds after each run's announcement."""

    kind: str
    after_s: float

    @classmethod
    def parse(cls, text: str) -> Fault:
        """`KIND@SECONDS`, e.g. `scans-stop@3`.

        Raises:
            StudyError: an unknown kind or a time that is not a finite number of seconds from 0.
        """
        kind, _, after = text.partition("@")
        try:
            seconds = float(after)
        except ValueError:
            seconds = math.nan
        if kind not in FAULTS or not (math.isfinite(seconds) and seconds >= 0):
            raise StudyError(f"--fault {text!r}: expected KIND@SECONDS with KIND one of {', '.join(FAULTS)} and SECONDS >= 0")
        return cls(kind, seconds)


#: Physics steps at most per wake-up: a process paused longer than this many steps loses the rest of the pause.
MAX_CATCH_UP = 20


@dataclass(frozen=True)
class SoftwareRobotConfig:
    """Rates (Hz), the base's own command timeout (s), the laser's frame and mount on the base, and the lidar's seed."""

    scan_rate: float = 40.0
    #: Seconds between a scan's stamp (when the laser took it) and its publication, as a real laser's driver has.
    scan_latency: float = 0.0
    odometry_rate: float = 50.0
    physics_rate: float = 100.0
    command_timeout: float = 0.5
    laser_frame: str = "laser"
    mount: Pose2D = Pose2D(0.35, 0.0, 0.0)
    seed: int = 0
    faults: tuple[Fault, ...] = ()
    room: tuple[float, float, float, float] | None = ROOM
    start: Pose2D = Pose2D()
    #: A row staged wrong: "robot" (it stays where it stands instead of being brought to its start), "walkers" (nobody walks).
    unstaged: frozenset[str] = frozenset()


def parse_room(text: str) -> tuple[float, float, float, float] | None:
    """`--room`'s `X0,Y0,X1,Y1` (a rectangle around the start, at least 1.5 m from it on every side), or `none`.

    Raises:
        StudyError: anything else.
    """
    if text == "none":
        return None
    try:
        x0, y0, x1, y1 = (float(v) for v in text.split(","))
    except ValueError:
        x0 = y0 = x1 = y1 = math.nan
    if not (all(map(math.isfinite, (x0, y0, x1, y1))) and max(x0, y0) <= -1.5 and min(x1, y1) >= 1.5):
        raise StudyError(f"--room {text!r}: expected X0,Y0,X1,Y1 in metres around the start (X0 and Y0 at most -1.5, X1 and Y1 "
                         "at least 1.5), or none")
    return x0, y0, x1, y1


def room_walls(room: tuple[float, float, float, float] | None) -> np.ndarray:
    """(W, 2, 2) the wall segments of a rectangular room (none without one)."""
    if room is None:
        return np.zeros((0, 2, 2))
    x0, y0, x1, y1 = room
    corners = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
    return np.stack((corners, np.roll(corners, -1, axis=0)), axis=1)


def wall_points(walls: np.ndarray, step: float = BUMPER_STEP_M) -> np.ndarray:
    """(P, 2) points every `step` metres along the walls (their ends included)."""
    points = [np.linspace(a, b, max(int(np.ceil(np.hypot(*(b - a)) / step)), 1) + 1) for a, b in walls]
    return np.concatenate(points) if points else np.zeros((0, 2))


@dataclass
class Scene:
    """The walkers of one run, laid out in the scene frame, which sits at `anchor` in the odometry frame."""

    scenario: Scenario
    crowd: Crowd
    anchor: Pose2D
    started: float

    def world(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) walker positions and velocities in the odometry frame."""
        c, s = math.cos(self.anchor.yaw), math.sin(self.anchor.yaw)
        return self.anchor.apply(self.crowd.position), self.crowd.velocity @ np.array([[c, s], [-s, c]])


class SoftwareRobot:
    """A simulated robot and crowd on a middleware `transport`, named by the `[robot]` table's topics and frames.

    Args:
        study: a study folder whose plan rows name the scenes (None: the default scene for every run).
        commands: a text file that gets one `wall_ns,linear,angular` line per velocity command received.
        contacts: a text file that gets one `wall_ns,x,y` line each time the footprint comes to touch a wall.
        truth: a text file that gets, with every scan, the ground truth at its stamp: `stamp_ns,x,y,theta` of the robot
            and then `x,y` of each walker, in the odometry frame.
    """

    def __init__(self, transport: Transport, settings: RobotSettings, config: SoftwareRobotConfig = SoftwareRobotConfig(),
                 study: StudyFolder | None = None, commands: TextIO | None = None, contacts: TextIO | None = None,
                 truth: TextIO | None = None) -> None:
        self.transport, self.settings, self.config, self.study = transport, settings, config, study
        self.limits = settings.limits
        self.robot = RobotState(config.start.x, config.start.y, config.start.yaw)
        walls = room_walls(config.room)
        self._wall_points = wall_points(walls)
        self._touching = False
        self._contacts, self._truth = contacts, truth
        # The lidar and legs fitted to the labelled real bags, so the robot's own leg detector sees the walkers.
        self.lidar = LidarSimulator(replace(LidarSpec.fitted(), frame_id=config.laser_frame), BodyModel.fitted(), seed=config.seed,
                                    walls=walls)
        self.scene = self._scene("", time.monotonic())
        self._command = Velocity(0.0, 0.0)
        self._command_at = -math.inf
        self._commands = commands
        self._lock = threading.Lock()
        self._announced: list[str] = []
        self._announced_once = False
        self._frozen_ns = 0
        self._future_sent = False
        self._publish_scan = transport.publisher(settings.scan_topic, SCAN)
        self._late_scans: deque[tuple[float, Scan]] = deque()
        self._publish_odometry = transport.publisher(settings.odometry_topic, ODOMETRY) if settings.odometry_topic else None
        self._publish_tf = transport.publisher("/tf", TF)
        self._publish_static = transport.publisher("/tf_static", TF_STATIC, latched=True)
        transport.subscribe(settings.cmd_vel_topic, TWIST_KINDS[settings.cmd_vel_type], self._on_command)
        transport.subscribe(RUN_TOPIC, TEXT, self._on_run, latched=True)
        # Said once, latched (the publisher kept, so that late subscribers hear it): every run driven on this robot is
        # recorded as a software robot's, not a real one's.
        self._say = transport.publisher(SOFTWARE_ROBOT_TOPIC, TEXT, latched=True)
        self._say("trials robot-sim")

    def _on_command(self, velocity: Velocity) -> None:
        now = time.monotonic()
        with self._lock:
            self._command, self._command_at = velocity, now
        if self._commands is not None:
            self._commands.write(f"{time.time_ns()},{velocity.linear!r},{velocity.angular!r}\n")
            self._commands.flush()

    def _on_run(self, code: str) -> None:
        with self._lock:
            self._announced.append(code)

    def _scene(self, code: str, now: float) -> Scene:
        """The scene of run `code` (its plan row's, seeded as `trials run` seeds it) placed at the robot's pose."""
        scenario = row_scenario(self.study, code, self.config.seed)
        if "walkers" in self.config.unstaged:
            scenario = replace(scenario, walkers=())
        return Scene(scenario, Crowd(scenario, SocialForceParams(), self._crowd_seed(code)),
                     Pose2D(self.robot.x, self.robot.y, self.robot.theta), now)

    def _crowd_seed(self, code: str) -> int:
        """The crowd's seed for run `code`, as `trials run` would simulate it."""
        from trials.runner import row_seeds, run_seed

        if self.study is not None and code in {r["run_code"] for r in self.study.read_plan()}:
            return row_seeds(run_seed(int(self.study.read_design()["seed"]), code))[1]
        return row_seeds(self.config.seed)[1]

    def _start(self, code: str) -> Pose2D:
        """Where the operator brings the robot for run `code`: the row's start in the odometry frame when the study stages
        its rows there (its own frame, or a start mark), else the software robot's own start."""
        if self.study is not None and code:
            row = next((r for r in self.study.read_plan() if r["run_code"] == code), {})
            with suppress(StudyError):  # no mark measured yet: the robot stands where it started
                stage = stage_of(self.settings, row, self.study)
                if stage is not None and frame_name(stage.frame) == frame_name(self.settings.odometry_frame):
                    return stage.start
        return self.config.start

    def step(self, dt: float, now: float) -> None:
        """Advance the robot and the walkers by `dt` seconds of the monotonic clock `now`."""
        with self._lock:
            fresh = now - self._command_at <= self.config.command_timeout
            command = self._command if fresh else Velocity(0.0, 0.0)
            announced, self._announced = self._announced, []
        for code in announced:
            if "robot" not in self.config.unstaged:
                start = self._start(code)
                self.robot = RobotState(start.x, start.y, start.yaw)
            self.scene = self._scene(code, now)
            self._announced_once, self._frozen_ns, self._future_sent = True, 0, False
        scene = self.scene
        local = scene.anchor.inverse().compose(Pose2D(self.robot.x, self.robot.y, self.robot.theta))
        in_scene = RobotState(local.x, local.y, local.yaw, self.robot.v, self.robot.w)
        scene.crowd.step(now - scene.started, dt, in_scene, self.limits)
        if self._faulty(STALL, now):
            self.robot = replace(self.robot, v=0.0, w=0.0)
            return
        moved = step_robot(self.robot, command.linear, command.angular, dt, self.limits)
        touching = bool(len(self._wall_points)) and float(footprint_gaps(moved.pose, self._wall_points, self.limits).min()) <= 0.0
        if touching and not self._touching and self._contacts is not None:
            self._contacts.write(f"{time.time_ns()},{moved.x!r},{moved.y!r}\n")
            self._contacts.flush()
        self._touching = touching
        # The bumper: a move into a wall is not made, and the base stops.
        self.robot = replace(self.robot, v=0.0, w=0.0) if touching else moved

    def _faulty(self, kind: str, now: float) -> bool:
        """Whether a staged fault of `kind` is on at monotonic time `now` (from its time after the last announcement on)."""
        return bool(self._announced_once) and any(f.kind == kind and now - self.scene.started >= f.after_s for f in self.config.faults)

    def _clock(self, stamp_ns: int, now: float) -> int:
        """A stamp of this computer's clock as the robot's clock gives it (stepped back or ahead by a staged fault)."""
        step = -CLOCK_STEP_S if self._faulty(CLOCK_BACK, now) else CLOCK_STEP_S if self._faulty(CLOCK_AHEAD, now) else 0.0
        return stamp_ns + int(step * 1e9)

    def publish_odometry(self, stamp_ns: int, now: float) -> None:
        s, robot = self.settings, self.robot
        pose = Pose2D(robot.x + (JUMP_M if self._faulty(ODOMETRY_JUMP, now) else 0.0), robot.y, robot.theta)
        if self._faulty(ODOMETRY_STOP, now):
            return
        stamp_ns = self._clock(stamp_ns, now)
        if self._faulty(ODOMETRY_STALE, now):
            self._frozen_ns = self._frozen_ns or stamp_ns
            stamp_ns = self._frozen_ns
        if self._publish_odometry is not None:
            self._publish_odometry(Odometry(stamp_ns, s.odometry_frame, s.base_frame, pose, robot.v, robot.w))
        transforms = [Transform(stamp_ns, s.odometry_frame, s.base_frame, pose, False)]
        if self._faulty(TF_LOOP, now):
            transforms.append(Transform(stamp_ns, s.base_frame, s.odometry_frame, pose.inverse(), False))
        self._publish_tf(transforms)

    def publish_scan(self, stamp_ns: int, now: float) -> None:
        if self._faulty(SCANS_STOP, now):
            return
        stamp_ns = self._clock(stamp_ns, now)
        if self._faulty(SCANS_LATE, now):
            stamp_ns -= int(FAULT_LAG_S * 1e9)
        if self._faulty(SCAN_FUTURE, now) and not self._future_sent:
            self._future_sent = True
            stamp_ns += int(CLOCK_STEP_S * 1e9)
        sensor = Pose2D(self.robot.x, self.robot.y, self.robot.theta).compose(self.config.mount)
        positions, velocities = self.scene.world()
        scan = self.lidar.scan(now - self.scene.started, sensor, positions, velocities)
        if self._faulty(SCANS_BLANK, now):
            scan = replace(scan, ranges=np.full(len(scan.ranges), np.nan))
        if self._faulty(FRAME_CHANGE, now):
            scan = replace(scan, frame_id=f"{scan.frame_id}_2")
        if self._faulty(SCANS_HUGE, now):
            k = -(-HUGE_BEAMS // len(scan.ranges))
            scan = replace(scan, ranges=np.repeat(scan.ranges, k), angle_increment=scan.angle_increment / k)
        if self._truth is not None:
            robot = self.robot
            values = (robot.x, robot.y, robot.theta, *positions.ravel())
            self._truth.write(f"{stamp_ns}," + ",".join(f"{v:.6f}" for v in values) + "\n")
        self._late_scans.append((now + self.config.scan_latency, replace(scan, stamp_ns=stamp_ns)))

    def run(self, stop: threading.Event, duration: float | None = None) -> None:
        """Simulate and publish in real time until `stop` is set (or `duration` seconds have passed)."""
        c = self.config
        self._publish_static([Transform(time.time_ns(), self.settings.base_frame, c.laser_frame, c.mount, True)])
        began = last = time.monotonic()
        next_scan = next_odometry = began
        physics = 1.0 / c.physics_rate
        while not stop.is_set() and (duration is None or last - began < duration):
            now = time.monotonic()
            steps = min(max(1, round((now - last) / physics)), MAX_CATCH_UP)  # a late wake-up is caught up in physics steps
            for _ in range(steps):
                self.step((now - last) / steps, now)
            last = now
            stamp = time.time_ns()
            if now >= next_odometry:
                self.publish_odometry(stamp, now)
                next_odometry = max(next_odometry + 1.0 / c.odometry_rate, now)
            if now >= next_scan:
                self.publish_scan(stamp, now)
                next_scan = max(next_scan + 1.0 / c.scan_rate, now)
            while self._late_scans and self._late_scans[0][0] <= now:
                self._publish_scan(self._late_scans.popleft()[1])
            wake = min(next_scan, next_odometry, now + physics, self._late_scans[0][0] if self._late_scans else math.inf)
            stop.wait(max(wake - time.monotonic(), 0.0))

    def close(self) -> None:
        self.transport.close()


def open_commands(path: Path | None) -> TextIO | None:
    """A record file (commands, contacts, truth), opened for appending line by line (None: no file)."""
    return None if path is None else path.open("a", encoding="utf-8", buffering=1)
