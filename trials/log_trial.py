"""Logged trials: a real robot log played through a controller open loop (`trials run --from-log`).

The log's LaserScans go through robot_logs' person tracker, in the odometry frame when the log
has odometry, else in the scan's own frame with the robot standing at the sensor's origin. Time
is the log's header stamps (robot_logs' rule), counted from the run's first scan (t = 0). Every
0.4 s the controller gets the tracks as of the newest scan and the robot's recorded pose and
history, and plans; the robot keeps doing what it did in the log. Each plan is logged next to
the robot's recorded positions at its way-points' times (their distance: the plan's deviation)
and the footprint's gap along the plan to the people at those times, where the log shows them
(the plan's predicted clearance; open loop, so people reacted to the real robot, not the plan).
The run ends as a simulated trial does: recorded robot at the goal, in contact with a tracked
person's disc, or at the end of the window (status `timeout`).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.records import RunMetrics
from designs.spec import LOG_COLUMN
from robot_logs.convert import to_odometry
from robot_logs.errors import LogError
from robot_logs.log_tracking import LogTracking, result_rows
from robot_logs.occupancy_map import OccupancyMap
from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M, STEP_S, T_OBS
from robot_logs.reader import LogReader
from robot_logs.records import seconds, stamp_text
from robot_logs.run_log import REPLAY_METADATA
from robot_logs.sources import TopicInfo
from robot_logs.topics import ODOMETRY_TYPES, TopicNames, pick_topic
from robot_logs.tracks import TrackRow, TrackTable, history_at
from trials.controllers.base import Controller, Observation, Plan
from trials.metrics import measure
from trials.run_log import RunLog
from trials.sim.closed_loop import COLLISION, GOAL, START, TIMEOUT
from trials.sim.follower import WaypointFollower
from trials.sim.robot import RobotLimits, RobotState, footprint_gaps

#: Seconds of log the controller must have seen before its first plan: 8 samples 0.4 s apart.
OBSERVATION_S = (T_OBS - 1) * STEP_S
#: The default goal lies this far ahead of the robot's first pose, as in the simulated scenes.
GOAL_AHEAD_M = 10.0


@dataclass(frozen=True)
class ReplayOptions:
    """How logs are played: `log` (from --from-log) replaces every run's own log; goal in the
    log's frame (None: 10 m ahead of the first pose); the window in seconds after the first scan;
    `occupancy`: a ROS map whose occupied cells are not people (--map)."""

    log: Path | None = None
    goal: tuple[float, float] | None = None
    start_s: float = 0.0
    duration_s: float | None = None
    topics: TopicNames = TopicNames()
    salvage: bool = False
    occupancy: OccupancyMap | None = None


def log_of(row: dict[str, str], root: Path, options: ReplayOptions) -> Path | None:
    """The log a plan row plays: --from-log, else its `Log` cell (relative to the study folder), else None."""
    if options.log is not None:
        return options.log
    cell = (row.get(LOG_COLUMN) or "").strip()
    return root / cell if cell else None


@dataclass(frozen=True)
class RobotPath:
    """The robot's recorded base pose and velocity over run time (s since t = 0); held constant
    beyond its ends."""

    time: np.ndarray
    pose: np.ndarray
    velocity: np.ndarray

    @classmethod
    def standing(cls) -> RobotPath:
        """A robot that never moves, at the origin of the scan's frame."""
        return cls(np.zeros(1), np.zeros((1, 3)), np.zeros((1, 2)))

    @classmethod
    def from_odometry(cls, log: LogReader, topic: str, origin_ns: int) -> RobotPath:
        """Poses and twists of every odometry message, in stamp order, timed from the header stamp `origin_ns`."""
        samples = sorted((o.stamp_ns, o.pose.x, o.pose.y, o.pose.yaw, o.linear, o.angular)
                         for o in (to_odometry(m.data, m.record_ns) for m in log.messages({topic})))
        table = np.array(samples, dtype=float).reshape(-1, 6)
        time = (table[:, 0] - origin_ns) * 1e-9
        pose = np.column_stack([table[:, 1:3], np.unwrap(table[:, 3])])
        return cls(time, pose, table[:, 4:6])

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) poses (heading in [-pi, pi)) and (n, 2) velocities at the given times."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        pose = np.column_stack([np.interp(times, self.time, self.pose[:, k]) for k in range(3)])
        pose[:, 2] = (pose[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        velocity = np.column_stack([np.interp(times, self.time, self.velocity[:, k]) for k in range(2)])
        return pose, velocity


@dataclass(frozen=True)
class People:
    """The confirmed tracks at one scan, shaped as the run log expects the simulator's crowd."""

    ids: tuple[int, ...]
    position: np.ndarray
    velocity: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class LoggedScene:
    """A log read and tracked once (in the parent process), ready to be played by any controller.

    Attributes:
        path, format: the log and its format in words; damage: what --salvage met, if anything.
        frame: the log frame the run is played in (the MCAP's `map`): the odometry frame, or the
            scan's frame when the log has no odometry.
        scan_topic, odometry_topic: the topics read (odometry_topic None: the robot stands still).
        offset_s: t = 0 (the run's first scan) in seconds after the log's first scan.
        scan_ns: (K,) header stamps of the run's scans (t = 0 at the first); time: the same in
            seconds since t = 0; people: the tracks at each of them.
        rows: track rows from the log's first scan to the run's last, in stamp order.
        robot: the recorded robot; goal: (2,) in `frame`.
        plan_times: seconds since t = 0 at which the controller plans.
        row_stamps: the header stamp of each row, for finding the rows of an observation window.
        static_map: the ROS map the tracks were made with (--map) and its frame, if any.
    """

    path: Path
    format: str
    damage: str | None
    frame: str
    scan_topic: str
    odometry_topic: str | None
    offset_s: float
    scan_ns: list[int]
    time: np.ndarray
    people: list[People]
    rows: list[TrackRow]
    robot: RobotPath
    goal: np.ndarray
    plan_times: np.ndarray
    row_stamps: list[int]
    static_map: str | None = None

    def metadata(self) -> dict[str, str]:
        """The run log's metadata entries that describe the replay (strings)."""
        return {
            "log": str(self.path), "log_format": self.format, "log_frame": self.frame, "scan_topic": self.scan_topic,
            "odometry": self.odometry_topic or "none: the robot stands at the sensor's origin",
            "log_start_stamp": stamp_text(self.scan_ns[0]),
            "log_offset_s": f"{self.offset_s:.3f}", "goal_x": f"{self.goal[0]:g}", "goal_y": f"{self.goal[1]:g}",
            **({"log_damage": self.damage} if self.damage else {}),
            **({"static_map": self.static_map} if self.static_map else {}),
        }


def _odometry_topic(log: LogReader, topics: TopicNames) -> TopicInfo | None:
    """The odometry topic to read, or None when the log has none (and none was named)."""
    if topics.odometry is None and not any(t.msgtype in ODOMETRY_TYPES for t in log.topics):
        return None
    return pick_topic(log.topics, ODOMETRY_TYPES, "Odometry", topics.odometry, log.path, "--odom-topic")


def prepare(path: Path, options: ReplayOptions) -> LoggedScene:
    """Read and track a log up to the end of the window and check a plan fits in it.

    Raises:
        LogError: missing or damaged log, no LaserScan topic (the message lists the topics),
            scans that odometry and tf cannot place, or a window too short for one plan.
    """
    with LogReader(path, salvage=options.salvage) as log:
        odometry = _odometry_topic(log, options.topics)
        tracking = LogTracking(log, "odom" if odometry else "sensor", options.topics, occupancy=options.occupancy)
        first_ns: int | None = None
        frame = ""
        run_ns: list[int] = []
        people: list[People] = []
        rows: list[TrackRow] = []
        elapsed = 0.0
        for scan, result in tracking:
            if first_ns is None:
                first_ns = scan.stamp_ns
            elapsed = seconds(scan.stamp_ns - first_ns)
            if options.duration_s is not None and elapsed > options.start_s + options.duration_s + 1e-9:
                break
            rows += result_rows(result)
            frame = result.frame
            if elapsed >= options.start_s - 1e-9:
                run_ns.append(scan.stamp_ns)
                people.append(People(tuple(t.track_id for t in result.tracks),
                                     np.array([[t.x, t.y] for t in result.tracks], dtype=float).reshape(-1, 2),
                                     np.array([[t.vx, t.vy] for t in result.tracks], dtype=float).reshape(-1, 2)))
        if first_ns is None:
            raise LogError(f"{path}: no scan on {tracking.scan_topic.name} can be placed in the odometry frame")
        if not run_ns and elapsed < options.start_s:
            raise LogError(f"{path}: --start {options.start_s:g} s lies beyond the log's last scan ({elapsed:.1f} s after its first)")
        if not run_ns:
            raise LogError(f"{path}: no scan from {options.start_s:g} s to {options.start_s + (options.duration_s or 0.0):g} s "
                           "after the log's first; choose another --start or --duration")
        robot = RobotPath.from_odometry(log, odometry.name, run_ns[0]) if odometry else RobotPath.standing()
        damage = log.damage
    offset = seconds(run_ns[0] - first_ns)
    time = np.array([seconds(ns - run_ns[0]) for ns in run_ns])
    ticks = np.arange(0.0, time[-1] + 1e-9, STEP_S)
    ticks = ticks[offset + ticks >= OBSERVATION_S - 1e-9]
    if not len(ticks):
        raise LogError(
            f"{path}: too short for a logged trial: its scans from {offset:.1f} s to {offset + time[-1]:.1f} s "
            f"after the first leave no planning step, and the controller needs {OBSERVATION_S:g} s of log "
            f"({T_OBS} steps of {STEP_S:g} s) before its first plan")
    if options.goal is not None:
        goal = np.array(options.goal, dtype=float)
    else:
        x, y, heading = robot.at(np.zeros(1))[0][0]
        goal = np.array([x + GOAL_AHEAD_M * math.cos(heading), y + GOAL_AHEAD_M * math.sin(heading)])
    rows.sort(key=lambda r: r.stamp_ns)
    return LoggedScene(path, log.format, damage, frame, tracking.scan_topic.name, odometry.name if odometry else None,
                       offset, run_ns, time, people, rows, robot, goal, ticks, [r.stamp_ns for r in rows],
                       _map_note(options.occupancy, tracking.unmapped))


def _map_note(occupancy: OccupancyMap | None, unmapped: int) -> str | None:
    """The run log's word on the map the tracks were made with, and the scans tf could not place on it."""
    if occupancy is None:
        return None
    return f"{occupancy.source} in frame {occupancy.frame}" + (f"; {unmapped} scans had no pose in it" if unmapped else "")


@dataclass(frozen=True)
class Comparison:
    """One plan against the log: the recorded robot at the way-points' times (those within the
    run), their mean and last distances to the way-points, and the smallest gap between the
    footprint along the plan and the people there then (None with nobody there)."""

    recorded: np.ndarray
    deviation_m: float | None
    final_deviation_m: float | None
    clearance_m: float | None


@dataclass(frozen=True)
class Replay:
    """A played log: how it ended, the outcome of the recorded motion, and the plans' figures."""

    status: str
    outcome: RunMetrics
    comparisons: list[Comparison]

    def summary(self) -> dict[str, str]:
        """The plans against the log over the run (metadata record `replay`, strings; empty: no value)."""
        deviations = [c.deviation_m for c in self.comparisons if c.deviation_m is not None]
        clearances = [c.clearance_m for c in self.comparisons if c.clearance_m is not None]

        def text(value: float | None) -> str:
            return "" if value is None else f"{value:.3f}"

        return {
            "plans": str(len(self.comparisons)),
            "plan_deviation_mean_m": text(float(np.mean(deviations)) if deviations else None),
            "plan_deviation_max_m": text(max(deviations) if deviations else None),
            "plan_min_clearance_m": text(min(clearances) if clearances else None),
        }


class TrackIndex:
    """Where each tracked person was at any time of the log (NaN outside their track's span)."""

    def __init__(self, scene: LoggedScene) -> None:
        table = TrackTable(scene.rows)
        origin = seconds(scene.scan_ns[0])
        self.tracks = [(stamps - origin, xy) for stamps, xy in map(table.track, table.ids)]
        self.first = np.array([s[0] for s, _ in self.tracks])
        self.last = np.array([s[-1] for s, _ in self.tracks])

    def positions(self, times: np.ndarray) -> np.ndarray:
        """(N, n, 2) positions at the run times `times` of the people tracked at some of them."""
        alive = np.flatnonzero((self.first <= times.max() + 1e-9) & (self.last >= times.min() - 1e-9))
        out = np.full((len(alive), len(times), 2), np.nan)
        for n, j in enumerate(alive):
            stamps, xy = self.tracks[j]
            inside = (times >= stamps[0] - 1e-9) & (times <= stamps[-1] + 1e-9)
            out[n, inside] = np.column_stack([np.interp(times[inside], stamps, xy[:, k]) for k in (0, 1)])
        return out


def observe(scene: LoggedScene, t: float) -> Observation:
    """What the controller is shown at run time t: the tracks as of the newest scan, the recorded robot."""
    now_ns = scene.scan_ns[int(np.searchsorted(scene.time, t + 1e-9)) - 1]
    since = bisect.bisect_left(scene.row_stamps, now_ns - int(STEP_S * T_OBS * 1e9))
    until = bisect.bisect_right(scene.row_stamps, now_ns)
    ids, history = history_at(TrackTable(scene.rows[since:until]), seconds(now_ns))
    poses, _ = scene.robot.at(t - STEP_S * np.arange(T_OBS - 1, -1, -1))
    now, speed = scene.robot.at(np.array([t]))
    return Observation(time=t, robot_pose=now[0], robot_velocity=speed[0], goal=scene.goal.copy(),
                       robot_history=poses[:, :2], pedestrian_ids=ids, pedestrian_history=history)


def compare(scene: LoggedScene, people: TrackIndex, t: float, end: float, plan: Plan, limits: RobotLimits) -> Comparison:
    """The plan made at t against what the log shows up to the run's end."""
    waypoints = np.asarray(plan.waypoints, dtype=float).reshape(-1, 2)
    times = t + plan.step * np.arange(1, len(waypoints) + 1)
    covered = times <= end + 1e-9
    if not covered.any():
        return Comparison(np.zeros((0, 2)), None, None, None)
    start, _ = scene.robot.at(np.array([t]))
    recorded, _ = scene.robot.at(times[covered])
    gaps = np.hypot(*(waypoints[covered] - recorded[:, :2]).T)
    path = np.vstack([start[:, :2], waypoints[covered]])
    step = np.diff(path, axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    still = np.hypot(step[:, 0], step[:, 1]) < 0.01
    for k in np.flatnonzero(still):  # standing still keeps the heading it had
        heading[k] = heading[k - 1] if k else start[0, 2]
    around = people.positions(times[covered])
    clearance = None
    for k, (point, yaw) in enumerate(zip(waypoints[covered], heading)):
        present = around[:, k][np.isfinite(around[:, k, 0])]
        if len(present):
            gap = max(float(footprint_gaps(np.array([*point, yaw]), present, limits, PEDESTRIAN_RADIUS_M).min()), 0.0)
            clearance = gap if clearance is None else min(clearance, gap)
    return Comparison(recorded[:, :2], float(gaps.mean()), float(gaps[-1]), clearance)


def _ending(scene: LoggedScene, limits: RobotLimits) -> tuple[int, str, str]:
    """The scan at which the run ends, its status and the event's detail."""
    poses, _ = scene.robot.at(scene.time)
    for k, (pose, people) in enumerate(zip(poses, scene.people)):
        if len(people.ids):
            gaps = footprint_gaps(pose, people.position, limits, PEDESTRIAN_RADIUS_M)
            hit = int(np.argmin(gaps))
            if gaps[hit] <= 0.0:
                return k, COLLISION, f"track {people.ids[hit]}"
        distance = float(np.hypot(*(pose[:2] - scene.goal)))
        if distance <= GOAL_TOLERANCE_M:
            return k, GOAL, f"{distance:.2f} m from the goal"
    distance = float(np.hypot(*(poses[-1, :2] - scene.goal)))
    return len(scene.time) - 1, TIMEOUT, f"end of the log window, {distance:.2f} m from the goal"


def play(scene: LoggedScene, controller: Controller, log: RunLog, limits: RobotLimits = RobotLimits()) -> Replay:
    """Play the scene through a reset controller, writing the run log; returns how it went."""
    last, status, detail = _ending(scene, limits)
    time = scene.time[: last + 1]
    poses, velocities = scene.robot.at(time)
    ticks = list(scene.plan_times[scene.plan_times <= time[-1] + 1e-9])
    people = TrackIndex(scene)
    follower = WaypointFollower(limits)
    comparisons: list[Comparison] = []
    command, planned = (0.0, 0.0), False
    log.event(0.0, START, f"log from {scene.offset_s:.1f} s, goal ({scene.goal[0]:g}, {scene.goal[1]:g}) in frame {scene.frame}")
    for k, t in enumerate(time):
        robot = RobotState(*poses[k], *velocities[k])
        while ticks and ticks[0] <= t + 1e-9:
            tick = ticks.pop(0)
            observation = observe(scene, tick)
            plan = controller.plan(observation)
            log.perceived(tick, observation.pedestrian_ids, observation.pedestrian_history)
            log.planned(tick, plan)
            comparison = compare(scene, people, tick, float(time[-1]), plan, limits)
            log.compared(tick, comparison.recorded, _figures(comparison))
            comparisons.append(comparison)
            follower.follow(tick, observation.robot_pose[:2], plan)
            planned = True
        if planned:  # what the latest plan would have commanded from where the robot really was
            command = follower.command(float(t), robot)
        log.state(float(t), robot, command, scene.people[k])
    log.event(float(time[-1]), status, detail)
    ids = sorted({i for p in scene.people[: last + 1] for i in p.ids})
    column = {i: n for n, i in enumerate(ids)}
    positions = np.full((len(time), len(ids), 2), np.nan)
    for k, p in enumerate(scene.people[: last + 1]):
        positions[k, [column[i] for i in p.ids]] = p.position
    outcome = measure(status, time, poses, velocities, positions, limits, PEDESTRIAN_RADIUS_M)
    replay = Replay(status, outcome, comparisons)
    log.add_metadata(REPLAY_METADATA, replay.summary())
    return replay


def _figures(comparison: Comparison) -> dict[str, Any]:
    return {"deviation_m": comparison.deviation_m, "final_deviation_m": comparison.final_deviation_m,
            "min_clearance_m": comparison.clearance_m}
