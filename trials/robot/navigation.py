"""The robot's own navigation stack as an arm (the `NavStack` controller): the action client a live run sends the row's
goal to and cancels, over either middleware (move_base's MoveBase action on ROS 1, Nav2's NavigateToPose on ROS 2).

The stack never drives the base itself: its velocity commands go to `nav_stack_cmd_vel_topic` (move_base's cmd_vel
remapped, or Nav2's smoothed commands), and the live loop relays them to the base through the same speed limits and
protective field as its own controllers' commands. So every stop rule holds the robot whatever the stack does, the
one-driver rule still sees one driver, and a killed worker leaves nothing relaying (its guard sends the stop).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.physical import STEP_S
from trials.controllers.base import Plan
from trials.robot.settings import RobotSettings
from trials.robot.transport import ROS1, TWIST_KINDS, Transport, Velocity

#: The words a goal's state is given in, whichever middleware reported it.
PENDING, ACTIVE, CANCELING, SUCCEEDED, CANCELED, ABORTED, REJECTED, LOST = (
    "pending", "active", "canceling", "succeeded", "canceled", "aborted", "rejected", "lost")
#: Way-points in the sealed record's stand-in plan: the stack's command held for this many 0.4 s steps.
ROLLOUT_STEPS = 12


class NavigationClient(Protocol):
    """One action client of the stack's navigation action."""

    action: str

    def ready(self) -> bool:
        """Whether the stack's action server is there to take a goal."""
        ...

    def send(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        """Send a goal pose in `frame` (without waiting for the server's answer)."""
        ...

    def cancel(self) -> None:
        """Cancel every goal the stack holds (the run's and any a stopped run left)."""
        ...

    def status(self) -> str:
        """The newest state of the goal sent last, in this module's words ("" before any)."""
        ...


class StackCommands:
    """The newest velocity command the stack sent on its own topic, and when it arrived on `clock` (this computer's
    monotonic clock)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._newest: tuple[Velocity, float] | None = None
        self._lock = threading.Lock()

    def heard(self, velocity: Velocity) -> None:
        if math.isfinite(velocity.linear) and math.isfinite(velocity.angular):
            with self._lock:
                self._newest = (velocity, self.clock())

    def newest(self) -> tuple[Velocity, float] | None:
        with self._lock:
            return self._newest


def open_navigation(transport: Transport, settings: RobotSettings) -> tuple[NavigationClient, StackCommands]:
    """The stack's action client on this process's node, and the stack's commands as they arrive.

    Raises:
        LinkError: the middleware's action library is missing (ROS 1: python3-actionlib, python3-move-base-msgs).
        StudyError: an action or topic name the middleware cannot take.
    """
    if transport.uri.scheme == ROS1:
        from trials.robot.ros1_navigation import Ros1Navigation

        client: NavigationClient = Ros1Navigation(settings.navigation_action)
    else:
        from trials.robot.ros2_navigation import Ros2Navigation

        client = Ros2Navigation(transport, settings.navigation_action)
    commands = StackCommands()
    transport.subscribe(settings.nav_stack_cmd_vel_topic, TWIST_KINDS[settings.nav_stack_cmd_vel_type], commands.heard)
    return client, commands


def arrival_pose(start: np.ndarray, goal: np.ndarray) -> Pose2D:
    """The goal as a pose: at `goal`, facing away from the start (the way the robot arrives)."""
    heading = math.atan2(goal[1] - start[1], goal[0] - start[0])
    return Pose2D(float(goal[0]), float(goal[1]), heading)


def rollout(pose: np.ndarray, command: tuple[float, float]) -> np.ndarray:
    """(ROLLOUT_STEPS, 2) where holding `command` would take the robot from `pose` (x, y, yaw), every 0.4 s: the stack's
    answer as a plan, so that its sealed record reads as every arm's."""
    v, w = command
    t = STEP_S * np.arange(1, ROLLOUT_STEPS + 1)
    heading = pose[2] + w * t
    if abs(w) < 1e-9:
        return np.column_stack([pose[0] + v * t * math.cos(pose[2]), pose[1] + v * t * math.sin(pose[2])])
    return np.column_stack([pose[0] + v / w * (np.sin(heading) - math.sin(pose[2])),
                            pose[1] - v / w * (np.cos(heading) - math.cos(pose[2]))])


class StackRelay:
    """A NavStack run's side of the live loop: it sends the goal, relays the stack's newest command while the stack
    drives this goal, and tells when the stack has stopped answering.

    A stack driving the goal may fall silent for a while (its first global plan, a recovery): zero is relayed then and the
    run goes on under its own rules. A stack that has not taken the goal, or has ended it short of the run's end
    (succeeded early, aborted, rejected), for `plan_timeout` seconds has stopped answering, like a late plan.
    """

    def __init__(self, client: NavigationClient, commands: StackCommands, settings: RobotSettings) -> None:
        self.client, self.commands, self.clock = client, commands, commands.clock
        self.plan_timeout, self.freshness = settings.plan_timeout, settings.watchdog
        self.state = ""
        self.newest = (0.0, 0.0)
        self.sent_at = self.alive_at = 0.0
        self.heard_at = -math.inf

    def start(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        self.sent_at = self.alive_at = self.clock()
        self.client.send(goal, frame, stamp_ns)

    def poll(self) -> str | None:
        """Take the stack's newest state and command; the reason to stop the run, else None."""
        now = self.clock()
        self.state = self.client.status()
        if self.state != ACTIVE:
            return f"no plan within {self.plan_timeout:g} s" if now - self.alive_at > self.plan_timeout else None
        self.alive_at = now
        heard = self.commands.newest()
        if heard is not None and heard[1] >= self.sent_at:  # a command sent for an earlier goal is not relayed
            self.newest, self.heard_at = (heard[0].linear, heard[0].angular), heard[1]
        return None

    def command(self) -> tuple[float, float]:
        """What the base is sent: the stack's newest command while it drives this goal and the command is younger than
        `watchdog` (a base would not obey an older one either), else zero."""
        fresh = self.clock() - self.heard_at <= self.freshness
        return self.newest if self.state == ACTIVE and fresh else (0.0, 0.0)

    def planned(self, pose: np.ndarray, name: str) -> Plan:
        """The stack's answer at a planning step, as the sealed record keeps every arm's: where holding its command would
        take the robot, the goal's state and the command."""
        command = self.command()
        return Plan(rollout(pose, command), record={"controller": name, "navigation_stack": self.state, "command": list(command)})
