"""One simulated trial in closed loop: physics at 10 Hz, the controller at 2.5 Hz (every 0.4 s).

Each physics step the robot follows the current plan and the pedestrians react to it and to each
other; every fourth step the controller is shown an `Observation` and plans again. The run ends
when the robot's centre is within 0.5 m of the goal, when its footprint overlaps a pedestrian's
0.25 m disc, or after 60 s. Everything is reported to a `RunSink` (the run log) as it happens.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M, STEP_S, T_OBS
from trials.controllers.base import Controller, Observation, Plan
from trials.scenario import Scenario
from trials.sim.follower import FollowerParams, WaypointFollower
from trials.sim.pedestrians import Crowd
from trials.sim.perception import Perception
from trials.sim.robot import RobotLimits, RobotState, footprint_gaps, step_robot
from trials.sim.social_force import SocialForceParams

START, COLLISION, GOAL, TIMEOUT = "start", "collision", "goal", "timeout"


@dataclass(frozen=True)
class SimConfig:
    """Rates, ending rules and the models' constants of a simulated trial."""

    physics_dt: float = 0.1
    timeout_s: float = 60.0
    goal_tolerance_m: float = GOAL_TOLERANCE_M
    pedestrian_radius_m: float = PEDESTRIAN_RADIUS_M
    limits: RobotLimits = RobotLimits()
    social: SocialForceParams = SocialForceParams()
    follower: FollowerParams = FollowerParams()

    @property
    def plan_every(self) -> int:
        """Physics steps per planning step."""
        return max(round(STEP_S / self.physics_dt), 1)


class Bodies(Protocol):
    """People as a run's ending sees them: the simulator's crowd, or the tracked people of a live run."""

    ids: tuple[int, ...]
    position: np.ndarray

    def __len__(self) -> int: ...


class RunSink(Protocol):
    """Where a run reports what happens (the MCAP run log, or nothing)."""

    def state(self, time: float, robot: RobotState, command: tuple[float, float], crowd: Crowd) -> None: ...

    def perceived(self, time: float, ids: tuple[int, ...], history: np.ndarray) -> None: ...

    def planned(self, time: float, plan: Plan) -> None: ...

    def event(self, time: float, name: str, detail: str) -> None: ...


@dataclass
class Trace:
    """The run sampled at every physics step: times, robot pose and velocities, pedestrian positions."""

    time: list[float] = field(default_factory=list)
    pose: list[np.ndarray] = field(default_factory=list)
    velocity: list[tuple[float, float]] = field(default_factory=list)
    pedestrians: list[np.ndarray] = field(default_factory=list)

    def add(self, time: float, robot: RobotState, crowd: Crowd) -> None:
        self.time.append(time)
        self.pose.append(robot.pose)
        self.velocity.append((robot.v, robot.w))
        self.pedestrians.append(crowd.position.copy())


@dataclass(frozen=True)
class RunResult:
    """How a run ended, when, and its trace."""

    status: str
    duration_s: float
    trace: Trace


def _observation(time: float, robot: RobotState, history: deque[np.ndarray], goal: np.ndarray,
                 ids: tuple[int, ...], pedestrians: np.ndarray) -> Observation:
    return Observation(time=time, robot_pose=robot.pose, robot_velocity=np.array([robot.v, robot.w]), goal=goal,
                       robot_history=np.array(history), pedestrian_ids=ids, pedestrian_history=pedestrians)


def run_ending(time: float, robot: RobotState, crowd: Bodies, goal: np.ndarray, config: SimConfig) -> tuple[str, str] | None:
    """How a run ends now, if it does: the robot's footprint touching a person's disc, the goal, or the timeout (with
    its detail). Simulated, logged and live runs end by this one rule."""
    if len(crowd):
        gaps = footprint_gaps(robot.pose, crowd.position, config.limits, config.pedestrian_radius_m)
        hit = int(np.argmin(gaps))
        if gaps[hit] <= 0.0:
            return COLLISION, f"pedestrian {crowd.ids[hit]}"
    distance = float(np.hypot(*(robot.position - goal)))
    if distance <= config.goal_tolerance_m:
        return GOAL, f"{distance:.2f} m from the goal"
    if time >= config.timeout_s - 1e-9:
        return TIMEOUT, f"{distance:.2f} m from the goal after {config.timeout_s:g} s"
    return None


def simulate(scenario: Scenario, controller: Controller, perception: Perception, sink: RunSink,
             config: SimConfig, crowd_seed: int) -> RunResult:
    """Run `scenario` with `controller` until it ends; the controller must already be reset."""
    robot = RobotState(*scenario.robot_start)
    goal = np.array(scenario.goal, dtype=float)
    crowd = Crowd(scenario, config.social, crowd_seed)
    follower = WaypointFollower(config.limits, config.follower)
    history = deque([robot.position] * T_OBS, maxlen=T_OBS)
    trace = Trace()
    command = (0.0, 0.0)
    dt = config.physics_dt
    step, time = 0, 0.0
    perception.sense(time, robot, crowd)
    trace.add(time, robot, crowd)
    sink.state(time, robot, command, crowd)
    sink.event(time, START, f"goal ({goal[0]:g}, {goal[1]:g}), {len(crowd)} pedestrians")
    ending = run_ending(time, robot, crowd, goal, config)
    while ending is None:
        if step % config.plan_every == 0:
            if step:
                history.append(robot.position)
            ids, pedestrians = perception.observe(time, robot, crowd)
            sink.perceived(time, ids, pedestrians)
            plan = controller.plan(_observation(time, robot, history, goal, ids, pedestrians))
            sink.planned(time, plan)
            follower.follow(time, robot.position, plan)
        command = follower.command(time, robot)
        crowd.step(time, dt, robot, config.limits)
        robot = step_robot(robot, *command, dt, config.limits)
        step += 1
        time = step * dt
        perception.sense(time, robot, crowd)
        trace.add(time, robot, crowd)
        sink.state(time, robot, command, crowd)
        ending = run_ending(time, robot, crowd, goal, config)
    status, detail = ending
    sink.event(time, status, detail)
    return RunResult(status, time, trace)


class NoSink:
    """A sink that keeps nothing (tests, benchmarks of the simulator alone)."""

    def state(self, *args: Any) -> None: ...

    def perceived(self, *args: Any) -> None: ...

    def planned(self, *args: Any) -> None: ...

    def event(self, *args: Any) -> None: ...
