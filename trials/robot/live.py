"""One run driven live on a robot: sensors in, the controller's plans, velocity commands out, and the stop rules.

The robot's LaserScans go through the same person tracker as `trials log track` (the learned detector,
the static world), placed in the odometry frame by tf; every 0.4 s of the robot's clock the controller
gets an `Observation` in that frame and answers with a `Plan` (on its own thread, so a slow plan never
delays a command); after every tracked scan, and at least at `command_rate`, the path follower of the
simulator turns the latest plan into a velocity command, held within the robot's speed and acceleration limits.

Time is the robot's: header stamps, counted from the newest scan when the run starts (t = 0), so a
robot whose clock differs from this computer's is driven alike. Staleness is judged two ways: by this
computer's clock since a scan or odometry message last arrived (the `watchdog`), and by the robot's
clock between the newest scan and the newest odometry (a stale odometry on time-stamped scans).

Only valid sensors count: a scan with too few beams returning a range, or odometry or tf with non-finite values, is
dropped as if it never came. Every command passes the protective field of the scan before it
(`trials.robot.protective_field`), so no controller drives into what the laser sees; gaps and the collision call
compare the people a scan saw with the robot where it stood at that scan's stamp.

The robot stops (a zero velocity is the last command sent) on the goal, a collision, the timeout, an
e-stop (the console's stop file or `true` on the e-stop topic), SIGINT or SIGTERM (`StopRequest`),
the middleware lost, stale sensors, a protective stop held too long, a stall or a base that does not respond, a
controller that has not answered within `plan_timeout`, and any exception; a run never starts before scans, odometry
and the laser's transform to the base have all been seen.

The robot's own navigation stack as the controller (`trials.controllers.nav_stack`) is sent the goal when the run starts;
its velocity commands take the follower's place while it drives that goal, relayed through the same limits and protective
field; a stack that has not taken the goal or has ended it for `plan_timeout` is a controller that has not answered;
every stop sends a zero velocity, cancels the stack's goals, then sends the zeros (`trials.robot.navigation`).
A killed worker sends nothing itself: its parent's `trials.robot.guard.Guard` stops the robot (docs/live_runs.md).
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import Future
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.records import RunMetrics
from robot_logs.frames import FrameTree, Pose2D, frame_name
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.physical import PEDESTRIAN_RADIUS_M, STEP_S, T_OBS
from robot_logs.pipeline import PersonTracker
from robot_logs.records import Odometry, Scan, Transform
from robot_logs.tracks import TrackRow, TrackTable, history_at
from trials.controllers.base import Controller, Observation, Plan
from trials.controllers.nav_stack import is_nav_stack
from trials.controllers.obstacles import OBSTACLE_RANGE_M, thinned
from trials.log_trial import People
from trials.metrics import measure
from trials.robot.navigation import NavigationClient, StackCommands, StackRelay, arrival_pose, open_navigation
from trials.robot.one_driver import PublisherWatch, node_name, wait_for_discovery
from trials.robot.people_check import PeopleCounter
from trials.robot.protective_field import OPEN, FieldReading, ProtectiveField, returns_in, valid_returns
from trials.robot.sensor_checks import ClockCheck, OdometryCheck, blank_cause, scan_fault, tf_fault
from trials.robot.settings import RobotSettings
from trials.robot.staging import Stage, off_start
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST_KINDS, Transport, Velocity, open_transport
from trials.run_settings import LIVE, SOFTWARE_ROBOT
from trials.sim.closed_loop import START, TIMEOUT, SimConfig, run_ending
from trials.sim.follower import WaypointFollower
from trials.sim.robot import RobotLimits, RobotState

#: A run that stopped for any reason but its own ending (goal, collision, timeout).
ABORTED = "aborted"
#: The states a live run passes through, as the console shows them.
WAITING, DRIVING = "waiting for sensors", "driving"
#: The event a run's log records when the protective field holds the robot against its controller.
PROTECTIVE_STOP = "protective stop"
#: The field when the laser cannot be placed on the base: nothing may move.
BLIND = FieldReading(0.0, 0.0, True, 0.0, 0.0)
#: The reasons a run stopped by the console's E-STOP, or by the robot's e-stop topic (then its name), gives.
ESTOP_CONSOLE, ESTOP_TOPIC = "e-stop from the console", "e-stop on"
#: Where a run announces its code (std_msgs/String, latched): a software robot sets up that row's scene.
RUN_TOPIC = "/trials/run"
#: Where the software robot says what it is (std_msgs/String, latched): runs driven on it are recorded as such.
SOFTWARE_ROBOT_TOPIC = "/trials/software_robot"
#: Zero velocity commands sent when a run stops, 20 ms apart, so that one lost message does not leave the robot moving.
STOP_REPEATS = 3
#: Where `warm_up` puts the goal (m ahead).
GOAL_AHEAD = (10.0, 0.0)
#: Nobody tracked yet.
NOBODY = People((), np.zeros((0, 2)), np.zeros((0, 2)))
#: Scans kept waiting for the loop; more means the loop has fallen behind and the oldest are dropped.
SCAN_QUEUE = 64
#: Seconds after a run's announcement before its sensors count: a robot brought to its start may still be sending the
#: pose it had before.
SETTLE_S = 0.5
#: A stall: over `stall_time` the commands would have moved the robot at least this far (m) or turned it this much
#: (rad), and odometry shows less than `STALL_SHARE` of it.
STALL_MIN_M, STALL_MIN_RAD, STALL_SHARE = 0.2, 0.4, 0.25


def estopped(reason: str) -> bool:
    """Whether a run's stop reason is an e-stop, which ends the whole `trials run` session."""
    return reason == ESTOP_CONSOLE or reason.startswith(f"{ESTOP_TOPIC} ")


class StopRequest:
    """The first reason anyone gave to stop the run (a signal handler, the e-stop topic, the loop itself); thread-safe."""

    def __init__(self) -> None:
        self._reason: str | None = None
        self._lock = threading.Lock()

    def request(self, reason: str) -> None:
        with self._lock:
            if self._reason is None:
                self._reason = reason

    @property
    def reason(self) -> str | None:
        return self._reason


class Sensors:
    """What the robot's middleware delivered, kept for the loop: queued scans, the frame tree (tf and odometry),
    the newest odometry, and when each kind last arrived on this computer's monotonic clock."""

    def __init__(self, settings: RobotSettings) -> None:
        self.settings = settings
        self.stop: StopRequest | None = None
        self.scans: queue.Queue[tuple[Scan, float]] = queue.Queue(SCAN_QUEUE)
        self.tree = FrameTree(max_gap_s=settings.watchdog)
        self.odometry: Odometry | None = None
        self.scan_seen: float | None = None
        self.odometry_seen: float | None = None
        self.newest_scan_ns: int | None = None
        #: The robot's tf messages as they came, for the run log; and its static transforms by child frame (sent once).
        self.transforms: queue.Queue[list[Transform]] = queue.Queue()
        self.static: dict[str, Transform] = {}
        self.dropped = 0
        #: Scans with too few valid beams, and odometry or transforms with non-finite values, ignored since the run began.
        self.blank_scans = 0
        self.bad_odometry = 0
        #: Whether the e-stop topic's newest message says the button is pressed.
        self.estop_held = False
        #: What the software robot said it is, None while no software robot spoke (a real robot).
        self.software_robot: str | None = None
        #: The first message since the run began that must stop the robot (`trials.robot.sensor_checks`), and the checks
        #: against the messages before it that only a driving run makes (a robot carried to its start may jump).
        self.fault: str | None = None
        self.blank_cause = ""
        self.laser_frame: str | None = None
        self._scan_clock: ClockCheck | None = None
        self._odometry_clock: ClockCheck | None = None
        self._odometry_jump: OdometryCheck | None = None
        self._lock = threading.Lock()

    def attach(self, transport: Transport) -> None:
        s = self.settings
        transport.subscribe(s.scan_topic, SCAN, self.on_scan)
        if s.odometry_topic:
            transport.subscribe(s.odometry_topic, ODOMETRY, self.on_odometry)
        transport.subscribe("/tf", TF, self.on_transforms)
        transport.subscribe("/tf_static", TF_STATIC, self.on_transforms)
        transport.subscribe(s.estop_topic, FLAG, self.on_estop)
        transport.subscribe(SOFTWARE_ROBOT_TOPIC, TEXT, self.on_software_robot, latched=True)

    def start_run(self, stop: StopRequest) -> None:
        """Forget the scans and tf messages queued since the last run (the frame tree and the newest odometry stay: static
        transforms come only once); an e-stop on the topic now stops this run."""
        for waiting in (self.scans, self.transforms):
            while not waiting.empty():
                waiting.get_nowait()
        self.blank_scans = self.bad_odometry = 0
        self.fault = None
        self.stop = stop

    def begin_drive(self, laser_frame: str) -> None:
        """From now on until `end_drive`, check each message against the one before it: the robot's clock, the scan's frame
        and how far odometry moves."""
        s = self.settings
        with self._lock:
            odometry = self.odometry
            assert odometry is not None and self.odometry_seen is not None and self.newest_scan_ns is not None and self.scan_seen is not None
            self.laser_frame = laser_frame
            # Each check starts from the newest message before the run, so that the run's first one is checked too.
            self._scan_clock = ClockCheck(f"scans on {s.scan_topic}", s.watchdog, (self.newest_scan_ns, self.scan_seen))
            self._odometry_clock = ClockCheck(f"odometry messages on {s.odometry_topic or '/tf'}", s.watchdog,
                                              (odometry.stamp_ns, self.odometry_seen))
            self._odometry_jump = OdometryCheck(f"odometry on {s.odometry_topic}" if s.odometry_topic else
                                                f"tf from {s.odometry_frame} to {s.base_frame}", s.max_speed,
                                                (odometry.stamp_ns, odometry.pose))

    def end_drive(self) -> None:
        with self._lock:
            self.laser_frame = self._scan_clock = self._odometry_clock = self._odometry_jump = None

    def fail(self, reason: str) -> None:
        """Keep the first reason to stop since the run began."""
        with self._lock:
            self.fault = self.fault or reason

    def on_scan(self, scan: Scan) -> None:
        arrived = time.monotonic()
        fault = scan_fault(scan, self.laser_frame)
        if fault is not None:
            self.fail(fault)
            return
        if not len(scan.ranges) or valid_returns(scan).mean() < self.settings.min_valid_share:
            self.blank_scans += 1  # counts as no scan: the watchdog stops the robot when only such scans come
            self.blank_cause = blank_cause(scan)
            return
        with self._lock:
            clock = self._scan_clock.add(scan.stamp_ns, arrived) if self._scan_clock is not None else None
        if clock is not None:
            self.fail(clock)
            return
        with self._lock:
            self.scan_seen = arrived
            self.newest_scan_ns = max(scan.stamp_ns, self.newest_scan_ns or scan.stamp_ns)
        try:
            self.scans.put_nowait((scan, arrived))
        except queue.Full:
            self.dropped += 1

    def on_odometry(self, odometry: Odometry) -> None:
        if not all(map(math.isfinite, (odometry.pose.x, odometry.pose.y, odometry.pose.yaw, odometry.linear, odometry.angular))):
            self.bad_odometry += 1  # counts as no odometry
            return
        fault = self._placed(odometry.frame_id, odometry.child_frame_id) or self._moved(odometry.stamp_ns, odometry.pose)
        if fault is not None:
            self.fail(fault)
            return
        with self._lock:
            self.tree.add(odometry.frame_id, odometry.child_frame_id, odometry.stamp_ns, odometry.pose)
            if self.odometry is None or odometry.stamp_ns >= self.odometry.stamp_ns:
                self.odometry = odometry
            self.odometry_seen = time.monotonic()

    def _placed(self, parent: str, child: str) -> str | None:
        """Why a transform cannot join the frame tree (a loop, a second parent), else None."""
        with self._lock:
            return tf_fault(self.tree, parent, child)

    def _moved(self, stamp_ns: int, pose: Pose2D) -> str | None:
        """Why the base's new pose cannot be believed while driving (the robot's clock, a jump), else None."""
        arrived = time.monotonic()
        with self._lock:
            if self._odometry_clock is None or self._odometry_jump is None:
                return None
            return self._odometry_clock.add(stamp_ns, arrived) or self._odometry_jump.add(stamp_ns, pose)

    def on_transforms(self, transforms: list[Transform]) -> None:
        s = self.settings
        finite = [t for t in transforms if all(map(math.isfinite, (t.pose.x, t.pose.y, t.pose.yaw)))]
        if len(finite) < len(transforms):
            self.bad_odometry += 1
        transforms = []
        for t in finite:
            base = not s.odometry_topic and frame_name(t.child) == frame_name(s.base_frame) and not t.static
            fault = self._placed(t.parent, t.child) or (self._moved(t.stamp_ns, t.pose) if base else None)
            if fault is not None:
                self.fail(fault)
            else:
                transforms.append(t)
        self.transforms.put(transforms)
        with self._lock:
            self.static.update((frame_name(t.child), t) for t in transforms if t.static)
            for t in transforms:
                self.tree.add(t.parent, t.child, t.stamp_ns, t.pose, t.static)
                if not s.odometry_topic and frame_name(t.child) == frame_name(s.base_frame) and not t.static:
                    # No odometry topic: the base's pose comes from tf (odometry frame -> base frame).
                    self.odometry = Odometry(t.stamp_ns, s.odometry_frame, s.base_frame, t.pose, math.nan, math.nan)
                    self.odometry_seen = time.monotonic()

    def on_software_robot(self, said: str) -> None:
        self.software_robot = said

    def on_estop(self, pressed: bool) -> None:
        self.estop_held = pressed  # a held button (true latched) keeps every later run from starting until released
        if pressed and self.stop is not None:
            self.stop.request(f"{ESTOP_TOPIC} {self.settings.estop_topic}")

    def lookup(self, target: str, source: str, stamp_ns: int) -> Pose2D | None:
        """Pose of `source` in `target` at a time, None when unknown or the frames are not connected."""
        with self._lock:
            try:
                return self.tree.lookup(target, source, stamp_ns)
            except ValueError:
                return None

    def missing(self, laser_frame: str | None, stage_frame: str | None = None) -> list[str]:
        """What a run still waits for before it may start (its stage in `stage_frame`, a frame tf places)."""
        s = self.settings
        wanted = []
        if self.scan_seen is None:
            wanted.append(f"a scan on {s.scan_topic}")
        if self.odometry is None:
            wanted.append(f"odometry on {s.odometry_topic}" if s.odometry_topic else f"tf from {s.odometry_frame} to {s.base_frame}")
        if laser_frame is not None and self.odometry is not None and self.newest_scan_ns is not None:
            if self.lookup(s.base_frame, laser_frame, self.newest_scan_ns) is None:
                wanted.append(f"the transform from {laser_frame} to {s.base_frame}")
        elif self.scan_seen is not None and laser_frame is None:
            wanted.append("the scan's frame")
        if stage_frame is not None and frame_name(stage_frame) != frame_name(s.odometry_frame) and self.newest_scan_ns is not None:
            if self.lookup(s.odometry_frame, stage_frame, self.newest_scan_ns) is None:
                wanted.append(f"the transform from {frame_name(stage_frame)} (the start and goal's frame) to {s.odometry_frame}")
        return wanted

    def staleness(self, now: float) -> str | None:
        """Why the sensors cannot be trusted now, else None."""
        s = self.settings
        with self._lock:
            scan_age = now - self.scan_seen if self.scan_seen is not None else math.inf
            odometry_age = now - self.odometry_seen if self.odometry_seen is not None else math.inf
            behind = (self.newest_scan_ns - self.odometry.stamp_ns) * 1e-9 if self.odometry and self.newest_scan_ns else 0.0
        if scan_age > s.watchdog:
            blank = (f"; {self.blank_scans} had under {s.min_valid_share:.0%} valid beams, the last {self.blank_cause}"
                     if self.blank_scans else "")
            return f"stale scans: no valid scan on {s.scan_topic} for {scan_age:.2f} s (watchdog {s.watchdog:g} s{blank})"
        if odometry_age > s.watchdog:
            bad = f"; {self.bad_odometry} with non-finite values" if self.bad_odometry else ""
            return f"stale odometry: none valid for {odometry_age:.2f} s (watchdog {s.watchdog:g} s{bad})"
        if abs(behind) > s.watchdog:
            return (f"stale odometry: its newest stamp is {behind:.2f} s behind the newest scan's "
                    f"(watchdog {s.watchdog:g} s)" if behind > 0 else
                    f"stale scans: the newest scan's stamp is {-behind:.2f} s behind the odometry's (watchdog {s.watchdog:g} s)")
        return None


@dataclass
class Trace:
    """The run at every command tick: run time, the robot's pose and velocity, the tracked people by id."""

    time: list[float] = field(default_factory=list)
    pose: list[np.ndarray] = field(default_factory=list)
    velocity: list[tuple[float, float]] = field(default_factory=list)
    people: list[dict[int, np.ndarray]] = field(default_factory=list)

    def positions(self) -> np.ndarray:
        """(K, N, 2) every tracked person's position at each tick, NaN while untracked."""
        ids = sorted({i for seen in self.people for i in seen})
        column = {i: n for n, i in enumerate(ids)}
        out = np.full((len(self.time), len(ids), 2), np.nan)
        for k, seen in enumerate(self.people):
            for i, xy in seen.items():
                out[k, column[i]] = xy
        return out


@dataclass(frozen=True)
class LiveEnd:
    """How a live run ended: `goal`, `collision`, `timeout` or `aborted`, in words, after how long, and its
    metrics from the robot's real path and the tracked people."""

    status: str
    detail: str
    duration_s: float
    metrics: RunMetrics
    #: Scan to velocity command on this computer (s), one per scan that a command followed: the tracking and follower path.
    latencies: list[float] = field(default_factory=list)
    #: Seconds each plan took.
    plan_seconds: list[float] = field(default_factory=list)
    #: Planning steps skipped because the controller was still busy with the previous one.
    late_plans: int = 0
    #: The most people tracked within `people_radius` of the robot at once (`trials.robot.people_check`), and from when.
    people: PeopleCounter = field(default_factory=PeopleCounter)
    #: `live`, or `software-robot` when the software robot drove (`trials.run_settings`).
    perception: str = LIVE


class LiveSink:
    """Where a live run reports (the MCAP run log through `trials.robot.live_log`, or nothing)."""

    def started(self, start_ns: int, goal: np.ndarray, perception: str) -> None: ...

    def scan(self, time: float, scan: Scan, sensor: Pose2D) -> None: ...

    def transforms(self, time: float, transforms: list[Transform]) -> None: ...

    def state(self, time: float, robot: RobotState, command: tuple[float, float], people: People) -> None: ...

    def perceived(self, time: float, ids: tuple[int, ...], history: np.ndarray) -> None: ...

    def planned(self, time: float, plan: Plan) -> None: ...

    def event(self, time: float, name: str, detail: str) -> None: ...


class RobotLink:
    """A process's lasting hold on the robot: the sensors' subscriptions and the command and announcement publishers, made
    once (a middleware keeps a subscription until its node closes) and shared by every run driven through them; with
    `nav_stack`, also the robot's navigation stack's action client and its commands, for every run alike (blinding)."""

    def __init__(self, transport: Transport, settings: RobotSettings, session: str, nav_stack: bool = False) -> None:
        self.transport, self.settings = transport, settings
        self.sensors = Sensors(settings)
        self.sensors.attach(transport)
        self.twist = velocity_publisher(transport, settings)
        self.announce = transport.publisher(RUN_TOPIC, TEXT, latched=True)
        self.navigation: NavigationClient | None = None
        self.stack_commands: StackCommands | None = None
        if nav_stack:
            try:
                self.navigation, self.stack_commands = open_navigation(transport, settings)
            except Exception:
                transport.close()
                raise
        wait_for_discovery(transport)
        self.publishers = PublisherWatch(transport, settings, session)

    @classmethod
    def open(cls, settings: RobotSettings, session: str, nav_stack: bool = False) -> RobotLink:
        """The worker's node of `trials run --robot` session `session` (`trials.robot.one_driver.new_session`).

        Raises:
            LinkError: the robot cannot be reached."""
        return cls(open_transport(settings.robot_uri, node_name(session, "run")), settings, session, nav_stack)

    def close(self) -> None:
        self.publishers.close()
        self.transport.close()


class LiveRun:
    """Drives one run: `wait` for the sensors, then `drive` until the run ends or stops.

    Args:
        link: the process's hold on the robot.
        stop: who may stop the run besides the loop itself.
        on_state: told each state the console shows (waiting, driving, and the ending), with a detail.
        estop_file: a file whose appearance is an e-stop (the console's button).
    """

    def __init__(self, link: RobotLink, stop: StopRequest, on_state: Callable[[str, str], None] = lambda state, detail: None,
                 estop_file: Path | None = None) -> None:
        self.link, self.transport, self.settings = link, link.transport, link.settings
        self.stop, self.on_state, self.estop_file = stop, on_state, estop_file
        self.sensors = link.sensors
        self.sensors.start_run(stop)
        self.command = (0.0, 0.0)
        self.laser_frame: str | None = None
        self.stage: Stage | None = None
        #: The navigation stack's side of a NavStack run once its goal is being sent: every stop cancels the stack's goals.
        self.relay: StackRelay | None = None

    # --- safety --------------------------------------------------------------------------------------

    def send(self, linear: float, angular: float) -> None:
        self.command = (linear, angular)
        self.link.twist(linear, angular)

    def halt(self) -> None:
        """Zero velocity, sent `STOP_REPEATS` times: whatever happened, the last command is a stop. A NavStack run also
        cancels the stack's goals, after a first zero (a cancel may wait on the middleware)."""
        relay, self.relay = self.relay, None
        try:
            if relay is not None:
                with suppress(Exception):
                    self.send(0.0, 0.0)
                with suppress(Exception):  # a lost middleware must not keep the zeros below from being sent
                    relay.client.cancel()
        finally:
            stop_robot(self.send)

    def _why_stop(self, now: float, check_sensors: bool) -> str | None:
        # The console's E-STOP creates its file before it signals `trials run`: the file names the cause.
        reason = ESTOP_CONSOLE if self.estop_file is not None and self.estop_file.exists() else None
        held = f"{ESTOP_TOPIC} {self.settings.estop_topic} (held)" if self.sensors.estop_held else None
        reason = reason or held or self.stop.reason or self.transport.lost() or self.sensors.fault or self.link.publishers.fault
        if reason is None and check_sensors:
            reason = self.sensors.staleness(now)
        return reason

    # --- waiting -------------------------------------------------------------------------------------

    def wait(self, run_code: str, stage: Stage | None) -> str | None:
        """Announce the run and wait until scans, odometry and the laser's transform have all been seen and the robot stands
        at the stage's start (`trials.robot.staging`; None: wherever it stands). Returns None when ready, else why the run
        cannot start (the robot was told to stand still)."""
        self.stage = stage
        frame = stage.frame if stage is not None else None
        self.on_state(WAITING, ", ".join(self.sensors.missing(None, frame)))
        if self.link.navigation is not None:  # before every row, whichever arm drives it: no goal of the stack lingers
            with suppress(Exception):  # a middleware that fails here is the stop rules' to report
                self.link.navigation.cancel()
        self.link.announce(run_code)
        self.send(0.0, 0.0)
        announced = time.monotonic()
        deadline = announced + self.settings.sensor_wait
        shown = ""
        while True:
            now = time.monotonic()
            if self.laser_frame is None and not self.sensors.scans.empty():
                self.laser_frame = self.sensors.scans.queue[0][0].frame_id
            missing = self.sensors.missing(self.laser_frame, frame) + self._stack_missing()
            stale = self.sensors.staleness(now)
            settled = min(self.sensors.scan_seen or 0.0, self.sensors.odometry_seen or 0.0) >= announced + SETTLE_S
            away = self._off_start() if not missing and stale is None and settled else None
            if not missing and stale is None and settled and away is None:
                return None
            if away is not None and away != shown:
                self.on_state(WAITING, away)
                shown = away
            reason = self._why_stop(now, check_sensors=False)
            if reason is None and now > deadline:
                waited = away or f"still waiting for {', '.join(missing) if missing else stale or 'the sensors to settle'}"
                reason = f"no start after {self.settings.sensor_wait:g} s: {waited}"
            if reason is not None:
                self.halt()
                return reason
            time.sleep(0.02)

    def _stack_missing(self) -> list[str]:
        """The navigation stack's action server, while a link that has a stack does not see it (asked before every run)."""
        navigation = self.link.navigation
        return [] if navigation is None or navigation.ready() else ["an answer from the robot's action server (nav_stack_action)"]

    def _off_start(self) -> str | None:
        """Why the robot does not stand at its stage's start now, else None (always None for an unstaged run)."""
        s, stage = self.settings, self.stage
        if stage is None:
            return None
        odometry = self.sensors.odometry
        assert odometry is not None and self.sensors.newest_scan_ns is not None
        if frame_name(stage.frame) == frame_name(s.odometry_frame):
            robot = odometry.pose
        else:
            robot = self.sensors.lookup(stage.frame, s.base_frame, self.sensors.newest_scan_ns)
            if robot is None:
                return f"still waiting for the robot's pose in {stage.frame}"
        return off_start(robot, stage, s.start_tolerance)

    # --- driving -------------------------------------------------------------------------------------

    def drive(self, controller: Controller, goal_pose: tuple[float, ...], sink: LiveSink) -> LiveEnd:
        """Drive the reset controller's plans toward the goal (given in the `goal_frame` of the settings) until
        the run ends; the robot is stopped whatever happens, exceptions included (they are re-raised)."""
        try:
            return self._drive(controller, goal_pose, sink)
        finally:
            self.halt()

    def _goal(self, goal_pose: tuple[float, ...], start: Pose2D, stamp_ns: int) -> np.ndarray:
        """The goal in the odometry frame: the stage's, placed by tf, or (unstaged) `goal_pose` relative to the robot's start."""
        s, stage = self.settings, self.stage
        if stage is None:
            return start.apply(np.array(goal_pose[:2], dtype=float))[0]
        point = np.array(stage.goal, dtype=float)
        if frame_name(stage.frame) == frame_name(s.odometry_frame):
            return point
        placed = self.sensors.lookup(s.odometry_frame, stage.frame, stamp_ns)
        assert placed is not None, "wait() saw the stage's frame placed"  # a failed assertion stops the robot like any exception
        return placed.apply(point)[0]

    def _drive(self, controller: Controller, goal_pose: tuple[float, ...], sink: LiveSink) -> LiveEnd:
        s, sensors = self.settings, self.sensors
        limits = s.limits
        odometry = sensors.odometry
        assert odometry is not None and sensors.newest_scan_ns is not None and self.laser_frame is not None
        start_ns = sensors.newest_scan_ns
        goal = self._goal(goal_pose, odometry.pose, start_ns)
        perception = SOFTWARE_ROBOT if sensors.software_robot is not None else LIVE
        sink.started(start_ns, goal, perception)
        sink.transforms(0.0, list(sensors.static.values()))
        tracker = PersonTracker.learned()
        follower = WaypointFollower(limits)
        protective = ProtectiveField(limits, s.protective_margin, s.reaction_time, s.max_acceleration)
        reading, held_since = OPEN, None
        seen: tuple[float, Pose2D] | None = None
        stall = StallWatch(s)
        counter = PeopleCounter()
        rows: deque[TrackRow] = deque()
        robot_poses: deque[tuple[float, np.ndarray]] = deque()
        trace = Trace()
        people = NOBODY
        ending_rule = SimConfig(timeout_s=s.timeout, limits=limits)
        pending: Future[tuple[float, np.ndarray, Plan, float]] | None = None
        next_plan, planned, asked_at = 0.0, False, 0.0
        latencies: list[float] = []
        plan_seconds: list[float] = []
        late = 0
        waiting_scans: list[float] = []
        scans = 0
        period = 1.0 / s.command_rate
        began = sent_at = time.monotonic()
        t = 0.0
        sensors.begin_drive(self.laser_frame)
        sink.event(0.0, START, f"goal ({goal[0]:.2f}, {goal[1]:.2f}) in frame {s.odometry_frame}")
        self.on_state(DRIVING, f"goal ({goal[0]:.2f}, {goal[1]:.2f}) in {s.odometry_frame}")
        ending: tuple[str, str] | None = None
        relay = None
        if is_nav_stack(controller):
            assert self.link.navigation is not None and self.link.stack_commands is not None, "a NavStack arm opens the link with a stack"
            relay = StackRelay(self.link.navigation, self.link.stack_commands, s)
        try:
            if relay is not None:
                self.relay = relay  # set first: a goal whose sending fails halfway is cancelled too
                relay.start(arrival_pose(np.array([odometry.pose.x, odometry.pose.y]), goal), s.odometry_frame, start_ns)
            while ending is None:
                now = time.monotonic()
                reason = self._why_stop(now, check_sensors=True) or self._command_gap(now - sent_at, scans)
                if reason is not None:
                    ending = (ABORTED, reason)
                    break
                # A command follows every scan as soon as it is tracked, and at least every `period` without scans.
                for scan, arrived in _arrivals(sensors.scans, sent_at + period - now):
                    sensor = sensors.lookup(s.odometry_frame, scan.frame_id, scan.stamp_ns)
                    if sensor is None or scan.stamp_ns < start_ns:
                        continue
                    laser = sensors.lookup(s.base_frame, scan.frame_id, scan.stamp_ns)
                    reading = protective.read(returns_in(scan, laser)) if laser is not None else BLIND
                    result = tracker.process(scan, sensor_pose=sensor, frame=s.odometry_frame, scan_index=scans)
                    scans += 1
                    scan_t = (scan.stamp_ns - start_ns) * 1e-9
                    # The robot where it stood when the scan saw the people: the gaps and the collision call compare
                    # the two at one instant, not the people then with the robot as the newest odometry has it since.
                    base = sensor.compose(laser.inverse()) if laser is not None else sensors.lookup(s.odometry_frame, s.base_frame, scan.stamp_ns)
                    seen = (scan_t, base) if base is not None else seen
                    if seen is not None:
                        near = [tr for tr in result.tracks if math.hypot(tr.x - seen[1].x, tr.y - seen[1].y) <= s.people_radius]
                        counter.add(scan_t, len(near))
                    sink.scan(scan_t, scan, sensor)
                    rows.extend(TrackRow(scan.stamp_ns, result.scan_index, tr.track_id, tr.x, tr.y, tr.vx, tr.vy, s.odometry_frame)
                                for tr in result.tracks)
                    people = People(tuple(tr.track_id for tr in result.tracks),
                                    np.array([[tr.x, tr.y] for tr in result.tracks], dtype=float).reshape(-1, 2),
                                    np.array([[tr.vx, tr.vy] for tr in result.tracks], dtype=float).reshape(-1, 2))
                    waiting_scans.append(arrived)
                    oldest = scan.stamp_ns - int(STEP_S * (T_OBS + 1) * 1e9)
                    while rows and rows[0].stamp_ns < oldest:
                        rows.popleft()
                while not sensors.transforms.empty():
                    sent_tf = sensors.transforms.get_nowait()
                    sink.transforms(max((sent_tf[0].stamp_ns - start_ns) * 1e-9, 0.0) if sent_tf else t, sent_tf)
                odometry = sensors.odometry
                assert odometry is not None
                t = max((sensors.newest_scan_ns - start_ns) * 1e-9, (odometry.stamp_ns - start_ns) * 1e-9, t)
                robot = RobotState(odometry.pose.x, odometry.pose.y, odometry.pose.yaw,
                                   _finite(odometry.linear, self.command[0]), _finite(odometry.angular, self.command[1]))
                robot_poses.append((t, robot.position))
                while robot_poses and robot_poses[0][0] < t - STEP_S * (T_OBS + 1):
                    robot_poses.popleft()
                # A finished plan replaces the one followed; a new one is asked for every 0.4 s of robot time. The stack
                # answers with velocity commands instead, as often as it likes.
                if relay is not None:
                    stopped = relay.poll()
                    if stopped is not None:
                        ending = (ABORTED, stopped)
                        break
                elif pending is not None and pending.done():
                    plan_t, position, plan, took = pending.result()
                    pending = None
                    plan_seconds.append(took)
                    sink.planned(plan_t, plan)
                    follower.follow(plan_t, position, plan)
                    planned = True
                elif pending is not None and time.monotonic() - asked_at > s.plan_timeout:
                    ending = (ABORTED, f"no plan within {s.plan_timeout:g} s")
                    break
                if t >= next_plan - 1e-9:
                    # The observation is logged every 0.4 s whether or not the controller is free to take it, so
                    # the public log's messages never count a slow controller's plans.
                    world = tracker.world.static_points(robot.position, OBSTACLE_RANGE_M) if tracker.world is not None else None
                    observation = self._observation(t, robot, goal, robot_poses, rows, start_ns, thinned(world) if world is not None else None)
                    sink.perceived(t, observation.pedestrian_ids, observation.pedestrian_history)
                    next_plan = max(next_plan + STEP_S, t)
                    if relay is not None:
                        sink.planned(t, relay.planned(robot.pose, controller.name))
                    elif pending is None:
                        pending, asked_at = _plan_aside(controller, observation), time.monotonic()
                    else:
                        late += 1
                if relay is not None:
                    command = relay.command()
                else:
                    command = follower.command(t, robot) if planned else (0.0, 0.0)
                wanted = _limited(command, self.command, limits, min(max(time.monotonic() - sent_at, 1e-3), period))
                command = reading.limit(*wanted)
                at_scan = robot if seen is None else RobotState(seen[1].x, seen[1].y, seen[1].yaw, robot.v, robot.w)
                # The timeout runs on this computer's monotonic clock too: no step of the robot's clock stretches a run.
                ending = run_ending(max(t, time.monotonic() - began), at_scan, people, goal, ending_rule)
                if ending is not None:
                    break
                if reading.blocks(wanted[0]) and wanted != (0.0, 0.0):
                    if held_since is None:
                        held_since = t
                        sink.event(t, PROTECTIVE_STOP, reading.describe())
                    if t - held_since >= s.protective_hold:
                        ending = (ABORTED, f"protective stop held {s.protective_hold:g} s: {reading.describe()}")
                        break
                else:
                    held_since = None
                stalled = stall.add(t, robot, command)
                if stalled is not None:
                    ending = (ABORTED, stalled)
                    break
                self.send(*command)
                sent_at = time.monotonic()
                latencies.extend(sent_at - arrived for arrived in waiting_scans)
                waiting_scans.clear()
                sampled = t if seen is None else seen[0]
                if not trace.time or sampled > trace.time[-1] + 1e-6:  # one sample per instant of the robot's clock
                    sink.state(sampled, at_scan, command, people)
                    trace.time.append(sampled)
                    trace.pose.append(at_scan.pose)
                    trace.velocity.append((robot.v, robot.w))
                    trace.people.append(dict(zip(people.ids, people.position)))
        except Exception:
            self.halt()
            # Public words only: which exception it was could tell the controllers apart (the traceback is sealed).
            detail = "an exception stopped the run"
            with suppress(Exception):
                self.on_state(ABORTED, detail)
            with suppress(Exception):
                sink.event(t, ABORTED, detail)
            raise
        finally:
            sensors.end_drive()
        self.halt()
        status, detail = ending
        self.on_state(status, detail)
        sink.event(t, status, detail)
        if not trace.time:
            trace.time.append(t)
            trace.pose.append(np.array([odometry.pose.x, odometry.pose.y, odometry.pose.yaw]))
            trace.velocity.append((0.0, 0.0))
            trace.people.append({})
        metrics = measure(status if status != ABORTED else TIMEOUT, np.array(trace.time), np.array(trace.pose),
                          np.array(trace.velocity), trace.positions(), limits, PEDESTRIAN_RADIUS_M)
        return LiveEnd(status, detail, t, metrics, latencies, plan_seconds, late, counter, perception)

    def _command_gap(self, since: float, scans: int) -> str | None:
        """Why the loop must stop because the base has gone `since` seconds without a command, else None."""
        if since <= self.settings.watchdog:
            return None
        return (f"no command for {since:.2f} s (watchdog {self.settings.watchdog:g} s): tracking the scans "
                f"({scans} so far) could not keep up")

    @staticmethod
    def _observation(t: float, robot: RobotState, goal: np.ndarray, poses: deque[tuple[float, np.ndarray]],
                     rows: deque[TrackRow], start_ns: int, obstacles: np.ndarray | None) -> Observation:
        times = np.array([p[0] for p in poses])
        xy = np.array([p[1] for p in poses]).reshape(-1, 2)
        instants = t - STEP_S * np.arange(T_OBS - 1, -1, -1)
        history = np.column_stack([np.interp(instants, times, xy[:, k]) for k in (0, 1)])
        ids, pedestrians = history_at(TrackTable(list(rows)), start_ns * 1e-9 + t) if rows else ((), np.zeros((0, T_OBS, 2)))
        return Observation(time=t, robot_pose=robot.pose, robot_velocity=np.array([robot.v, robot.w]), goal=goal.copy(),
                           robot_history=history, pedestrian_ids=ids, pedestrian_history=pedestrians,
                           obstacles=np.zeros((0, 2)) if obstacles is None else obstacles)


class StallWatch:
    """Ends a run whose base does not move as commanded: over the last `stall_time` seconds of the robot's clock, the
    commands sent would have moved it at least `STALL_MIN_M` (or turned it `STALL_MIN_RAD`) and odometry shows under
    `STALL_SHARE` of that. A base that has not moved at all since the run began does not hear its commands."""

    def __init__(self, settings: RobotSettings) -> None:
        self.settings = settings
        self.samples: deque[tuple[float, np.ndarray, float, float]] = deque()
        self.first: np.ndarray | None = None
        self.moved = False

    def add(self, t: float, robot: RobotState, command: tuple[float, float]) -> str | None:
        """Note the robot's pose at `t` and the command it is sent now; the reason to stop, if it stalls."""
        pose = robot.pose
        self.first = pose if self.first is None else self.first
        self.moved = self.moved or float(np.hypot(*(pose[:2] - self.first[:2]))) > 0.05 or abs(_wrap(pose[2] - self.first[2])) > 0.05
        self.samples.append((t, pose, abs(command[0]), abs(command[1])))
        window = self.settings.stall_time
        while len(self.samples) > 2 and self.samples[1][0] <= t - window:
            self.samples.popleft()
        if t - self.samples[0][0] < window - 1e-9:
            return None
        times = np.array([sample[0] for sample in self.samples])
        poses = np.array([sample[1] for sample in self.samples])
        speeds = np.array([sample[2:] for sample in self.samples])
        spans = np.diff(times)
        asked_m, asked_rad = (speeds[:-1] * spans[:, None]).sum(axis=0)
        moved_m = float(np.hypot(*np.diff(poses[:, :2], axis=0).T).sum())
        turned = float(np.abs(_wrap(np.diff(poses[:, 2]))).sum())
        if not ((asked_m >= STALL_MIN_M and moved_m < STALL_SHARE * asked_m) or (asked_rad >= STALL_MIN_RAD and turned < STALL_SHARE * asked_rad)):
            return None
        s = self.settings
        what = (f"the commands of the last {window:g} s would have moved it {asked_m:.2f} m and turned it {asked_rad:.2f} rad; "
                f"odometry shows {moved_m:.2f} m and {turned:.2f} rad")
        if not self.moved:
            return f"the base does not respond to {s.cmd_vel_type} on {s.cmd_vel_topic}: {what}"
        return f"stall: {what}"


def _wrap(angle: np.ndarray | float) -> np.ndarray | float:
    return (np.asarray(angle) + math.pi) % (2.0 * math.pi) - math.pi


def stop_robot(send: Callable[[float, float], None]) -> None:
    """Send zero velocity `STOP_REPEATS` times, 20 ms apart, so that one lost message does not leave the robot moving."""
    for k in range(STOP_REPEATS):
        if k:
            time.sleep(0.02)
        send(0.0, 0.0)


def velocity_publisher(transport: Transport, settings: RobotSettings) -> Callable[[float, float], None]:
    """A function sending one velocity command as the base takes it (`cmd_vel_type`): a Twist, or a TwistStamped stamped
    with this computer's clock in `cmd_vel_frame`."""
    kind = TWIST_KINDS[settings.cmd_vel_type]
    publish = transport.publisher(settings.cmd_vel_topic, kind)
    stamped = kind != TWIST_KINDS["Twist"]

    def send(linear: float, angular: float) -> None:
        publish(Velocity(linear, angular, time.time_ns(), settings.cmd_vel_frame) if stamped else Velocity(linear, angular))

    return send


def _arrivals(scans: queue.Queue[tuple[Scan, float]], wait: float) -> list[tuple[Scan, float]]:
    """The scans that arrived: waits up to `wait` seconds for the first, then takes every one queued."""
    arrived = []
    try:
        arrived.append(scans.get(timeout=wait) if wait > 0 else scans.get_nowait())
        while True:
            arrived.append(scans.get_nowait())
    except queue.Empty:
        pass
    return arrived


def warm_up(controllers: Iterable[Controller]) -> None:
    """Track a simulated scan of one person and plan once with each controller for a robot standing alone: the first
    of each loads or compiles what it needs (the leg classifier's tree walk, PyTorch's kernels, the lattice's search),
    which would stall the loop for a moment during a run (every run resets its controller before it starts)."""
    scan = LidarSimulator(seed=0).scan(0.0, Pose2D(), np.array([[2.0, 0.0]]), np.array([[0.0, 1.0]]))
    PersonTracker.learned().process(scan)
    still = np.zeros((T_OBS, 2))
    for controller in (c for c in controllers if not is_nav_stack(c)):  # the robot's own stack plans on the robot
        controller.plan(Observation(time=0.0, robot_pose=np.zeros(3), robot_velocity=np.zeros(2), goal=np.array(GOAL_AHEAD),
                                    robot_history=still, pedestrian_ids=(), pedestrian_history=np.zeros((0, T_OBS, 2))))


def _plan_aside(controller: Controller, observation: Observation) -> Future[tuple[float, np.ndarray, Plan, float]]:
    """`_timed_plan` on a daemon thread of its own: a controller that never answers is left behind when the run stops,
    and never keeps the worker process from exiting (a thread pool's threads would be waited for)."""
    future: Future[tuple[float, np.ndarray, Plan, float]] = Future()

    def work() -> None:
        try:
            future.set_result(_timed_plan(controller, observation))
        except BaseException as exc:  # handed to the loop, which stops the run
            future.set_exception(exc)

    threading.Thread(target=work, name="planner", daemon=True).start()
    return future


def _timed_plan(controller: Controller, observation: Observation) -> tuple[float, np.ndarray, Plan, float]:
    began = time.perf_counter()
    plan = controller.plan(observation)
    return observation.time, observation.robot_pose[:2], plan, time.perf_counter() - began


def _finite(value: float, fallback: float) -> float:
    return value if math.isfinite(value) else fallback


def _limited(command: tuple[float, float], last: tuple[float, float], limits: RobotLimits, dt: float) -> tuple[float, float]:
    """The command within the robot's speed limits and no further from the last one than its accelerations allow in dt."""
    v = float(np.clip(command[0], -limits.max_reverse_speed, limits.max_speed))
    w = float(np.clip(command[1], -limits.max_turn_rate, limits.max_turn_rate))
    v = last[0] + float(np.clip(v - last[0], -limits.max_acceleration * dt, limits.max_acceleration * dt))
    w = last[1] + float(np.clip(w - last[1], -limits.max_angular_acceleration * dt, limits.max_angular_acceleration * dt))
    return v, w
