"""The software robot: the closed-loop simulator behind a robot's ROS topics, for rehearsing a field day and for tests.

It publishes what a Husky- or TurtleBot-class base with a planar lidar does: LaserScans of the simulated
lidar (walkers drawn as legs, `robot_logs.lidar_sim`), nav_msgs/Odometry, and tf (odometry frame to base
frame, and the laser's static mount), all stamped with this computer's clock; it obeys geometry_msgs/Twist
within the robot's limits, and like a real base it stops by itself when no command has come for
`command_timeout` seconds (what stops a robot whose driver was killed).

When a live run announces its code (`trials.robot.live.RUN_TOPIC`), the robot lays out that plan row's scene
(`trials.scenario`, seeded as `trials run` would simulate it) around the pose it stands at, so the walkers
appear ahead of it; without a study it lays out the default scene. The robot is never moved between runs:
a run's goal is relative to where it starts.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import BodyModel, LidarSimulator, LidarSpec
from robot_logs.records import Odometry, Transform
from trials.errors import StudyError
from trials.robot.live import RUN_TOPIC
from trials.robot.settings import RobotSettings
from trials.robot.transport import ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, Transport, Velocity
from trials.scenario import Scenario, build_scenario, settings_from_row
from trials.sim.pedestrians import Crowd
from trials.sim.robot import RobotState, step_robot
from trials.sim.social_force import SocialForceParams
from trials.study import PLAN, StudyFolder

#: Failures a rehearsal can stage, each from some seconds after a run is announced: scans stop coming; scans keep
#: coming but `FAULT_LAG_S` late by their stamps; odometry stops; odometry keeps coming with its stamp frozen.
SCANS_STOP, SCANS_LATE, ODOMETRY_STOP, ODOMETRY_STALE = "scans-stop", "scans-late", "odometry-stop", "odometry-stale"
FAULTS = (SCANS_STOP, SCANS_LATE, ODOMETRY_STOP, ODOMETRY_STALE)
FAULT_LAG_S = 1.0


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
    odometry_rate: float = 50.0
    physics_rate: float = 100.0
    command_timeout: float = 0.5
    laser_frame: str = "laser"
    mount: Pose2D = Pose2D(0.35, 0.0, 0.0)
    seed: int = 0
    faults: tuple[Fault, ...] = ()


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
    """

    def __init__(self, transport: Transport, settings: RobotSettings, config: SoftwareRobotConfig = SoftwareRobotConfig(),
                 study: StudyFolder | None = None, commands: TextIO | None = None) -> None:
        self.transport, self.settings, self.config, self.study = transport, settings, config, study
        self.limits = settings.limits
        self.robot = RobotState(0.0, 0.0, 0.0)
        # The lidar and legs fitted to the labelled real bags, so the robot's own leg detector sees the walkers.
        self.lidar = LidarSimulator(replace(LidarSpec.fitted(), frame_id=config.laser_frame), BodyModel.fitted(), seed=config.seed)
        self.scene = self._scene("", time.monotonic())
        self._command = Velocity(0.0, 0.0)
        self._command_at = -math.inf
        self._commands = commands
        self._lock = threading.Lock()
        self._announced: list[str] = []
        self._announced_once = False
        self._frozen_ns = 0
        self._publish_scan = transport.publisher(settings.scan_topic, SCAN)
        self._publish_odometry = transport.publisher(settings.odometry_topic, ODOMETRY) if settings.odometry_topic else None
        self._publish_tf = transport.publisher("/tf", TF)
        self._publish_static = transport.publisher("/tf_static", TF_STATIC, latched=True)
        transport.subscribe(settings.cmd_vel_topic, TWIST, self._on_command)
        transport.subscribe(RUN_TOPIC, TEXT, self._on_run, latched=True)

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
        from trials.runner import row_seeds, run_seed

        row: dict[str, str] = {}
        seeds = row_seeds(self.config.seed)
        if self.study is not None and code:
            plan = {r["run_code"]: r for r in self.study.read_plan()}
            if code in plan:
                row = {k: v for k, v in plan[code].items() if k not in ("order", "run_code", "Controller", "Log")}
                seeds = row_seeds(run_seed(int(self.study.read_design()["seed"]), code))
        scenario = build_scenario(settings_from_row(row, f"{self.study.path(PLAN) if self.study else 'the default scene'} run {code}"),
                                  seeds[0])
        return Scene(scenario, Crowd(scenario, SocialForceParams(), seeds[1]), Pose2D(self.robot.x, self.robot.y, self.robot.theta), now)

    def step(self, dt: float, now: float) -> None:
        """Advance the robot and the walkers by `dt` seconds of the monotonic clock `now`."""
        with self._lock:
            fresh = now - self._command_at <= self.config.command_timeout
            command = self._command if fresh else Velocity(0.0, 0.0)
            announced, self._announced = self._announced, []
        for code in announced:
            self.scene = self._scene(code, now)
            self._announced_once, self._frozen_ns = True, 0
        scene = self.scene
        local = scene.anchor.inverse().compose(Pose2D(self.robot.x, self.robot.y, self.robot.theta))
        in_scene = RobotState(local.x, local.y, local.yaw, self.robot.v, self.robot.w)
        scene.crowd.step(now - scene.started, dt, in_scene, self.limits)
        self.robot = step_robot(self.robot, command.linear, command.angular, dt, self.limits)

    def _faulty(self, kind: str, now: float) -> bool:
        """Whether a staged fault of `kind` is on at monotonic time `now` (from its time after the last announcement on)."""
        return bool(self._announced_once) and any(f.kind == kind and now - self.scene.started >= f.after_s for f in self.config.faults)

    def publish_odometry(self, stamp_ns: int, now: float) -> None:
        s, robot = self.settings, self.robot
        pose = Pose2D(robot.x, robot.y, robot.theta)
        if self._faulty(ODOMETRY_STOP, now):
            return
        if self._faulty(ODOMETRY_STALE, now):
            self._frozen_ns = self._frozen_ns or stamp_ns
            stamp_ns = self._frozen_ns
        if self._publish_odometry is not None:
            self._publish_odometry(Odometry(stamp_ns, s.odometry_frame, s.base_frame, pose, robot.v, robot.w))
        self._publish_tf([Transform(stamp_ns, s.odometry_frame, s.base_frame, pose, False)])

    def publish_scan(self, stamp_ns: int, now: float) -> None:
        if self._faulty(SCANS_STOP, now):
            return
        if self._faulty(SCANS_LATE, now):
            stamp_ns -= int(FAULT_LAG_S * 1e9)
        sensor = Pose2D(self.robot.x, self.robot.y, self.robot.theta).compose(self.config.mount)
        positions, velocities = self.scene.world()
        scan = self.lidar.scan(now - self.scene.started, sensor, positions, velocities)
        self._publish_scan(replace(scan, stamp_ns=stamp_ns))

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
            wake = min(next_scan, next_odometry, now + physics)
            stop.wait(max(wake - time.monotonic(), 0.0))

    def close(self) -> None:
        self.transport.close()


def open_commands(path: Path | None) -> TextIO | None:
    """The commands file, opened for appending line by line (None: no file)."""
    return None if path is None else path.open("a", encoding="utf-8", buffering=1)
