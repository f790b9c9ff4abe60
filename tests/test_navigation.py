"""The navigation stack's side of a live run, on its own: the goal's pose, the stand-in plan the sealed record keeps,
and the relay's rules (what is relayed, when the stack has stopped answering), on a clock the test sets."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from robot_logs.frames import Pose2D
from trials.robot import navigation as nav
from trials.robot.navigation import StackCommands, StackRelay, arrival_pose, rollout
from trials.robot.settings import RobotSettings
from trials.robot.transport import Velocity

SETTINGS = RobotSettings(plan_timeout=1.0, watchdog=0.5)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Stack:
    """The stack's action as the relay sees it: the goals sent, and the state the test gives the newest."""

    action = "move_base"

    def __init__(self) -> None:
        self.sent: list[tuple[Pose2D, str, int]] = []
        self.cancels = 0
        self.state = ""

    def ready(self) -> bool:
        return True

    def send(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        self.sent.append((goal, frame, stamp_ns))
        self.state = nav.PENDING

    def cancel(self) -> None:
        self.cancels += 1

    def status(self) -> str:
        return self.state


def relay() -> tuple[StackRelay, Stack, StackCommands, Clock]:
    clock = Clock()
    stack, commands = Stack(), StackCommands(clock)
    return StackRelay(stack, commands, SETTINGS), stack, commands, clock


def test_the_goal_faces_away_from_the_start():
    pose = arrival_pose(np.array([1.0, 1.0]), np.array([4.0, 5.0]))
    assert (pose.x, pose.y) == (4.0, 5.0) and pose.yaw == pytest.approx(math.atan2(4.0, 3.0))


@pytest.mark.parametrize("command", [(0.8, 0.0), (0.5, 0.7), (-0.3, -1.2)])
def test_the_rollout_is_where_holding_the_command_takes_the_robot(command):
    start = np.array([1.0, -2.0, 0.4])
    v, w = command

    def unicycle(t, state):
        return [v * math.cos(state[2]), v * math.sin(state[2]), w]

    times = 0.4 * np.arange(1, nav.ROLLOUT_STEPS + 1)
    integrated = solve_ivp(unicycle, (0.0, times[-1]), start, t_eval=times, rtol=1e-10, atol=1e-12).y[:2].T
    assert np.allclose(rollout(start, command), integrated, atol=1e-7)


def test_the_stack_is_relayed_only_while_it_drives_this_goal():
    stack_relay, stack, commands, clock = relay()
    commands.heard(Velocity(0.9, 0.1))  # a command for an earlier goal
    clock.now += 0.1
    stack_relay.start(Pose2D(10.0, 0.0, 0.0), "odom", 5)
    assert stack.sent == [(Pose2D(10.0, 0.0, 0.0), "odom", 5)]
    assert stack_relay.poll() is None and stack_relay.command() == (0.0, 0.0)  # pending: nothing relayed
    stack.state = nav.ACTIVE
    assert stack_relay.poll() is None and stack_relay.command() == (0.0, 0.0)  # the earlier goal's command is not
    clock.now += 0.05
    commands.heard(Velocity(0.6, -0.2))
    assert stack_relay.poll() is None and stack_relay.command() == (0.6, -0.2)
    clock.now += 0.51  # older than the watchdog: a base would not obey it
    assert stack_relay.poll() is None and stack_relay.command() == (0.0, 0.0)
    clock.now += 30.0  # silent while it drives the goal (planning, a recovery): zero, and the run goes on
    assert stack_relay.poll() is None and stack_relay.command() == (0.0, 0.0)
    plan = stack_relay.planned(np.array([0.0, 0.0, 0.0]), "NavStack")
    assert plan.record == {"controller": "NavStack", "navigation_stack": nav.ACTIVE, "command": [0.0, 0.0]}


@pytest.mark.parametrize("ending", [nav.SUCCEEDED, nav.ABORTED, nav.REJECTED, nav.CANCELED, nav.LOST])
def test_a_stack_that_ends_the_goal_has_stopped_answering_after_the_plan_timeout(ending):
    stack_relay, stack, commands, clock = relay()
    stack_relay.start(Pose2D(10.0, 0.0, 0.0), "odom", 0)
    stack.state = nav.ACTIVE
    commands.heard(Velocity(0.5, 0.0))
    assert stack_relay.poll() is None and stack_relay.command() == (0.5, 0.0)
    stack.state = ending
    clock.now += 0.9
    assert stack_relay.poll() is None and stack_relay.command() == (0.0, 0.0)
    clock.now += 0.2
    assert stack_relay.poll() == "no plan within 1 s"


def test_a_stack_that_never_takes_the_goal_has_stopped_answering():
    stack_relay, stack, _, clock = relay()
    stack_relay.start(Pose2D(3.0, 0.0, 0.0), "odom", 0)
    clock.now += 1.0
    assert stack_relay.poll() is None
    clock.now += 0.01
    assert stack_relay.poll() == "no plan within 1 s" and stack.cancels == 0  # cancelling is the live run's halt


@pytest.mark.slow
def test_over_dds_the_client_waits_for_an_answer_and_outlives_a_server_that_restarts(tmp_path):
    from tests.support.live_rig import repository_env, ros2_uri, wait_for
    from trials.robot.ros2 import LOOPBACK_ENV, Ros2Transport
    from trials.robot.ros2_navigation import Ros2Navigation
    from trials.robot.transport import RobotUri

    uri = ros2_uri()
    env = {**repository_env(), LOOPBACK_ENV: "1"}
    transport = Ros2Transport(RobotUri.parse(uri), "navtrials_test_client", loopback=True)
    client = Ros2Navigation(transport, "navigate_to_pose")
    try:
        assert not client.ready()  # nobody answers yet
        for round_ in range(2):  # the server, then the server started again
            heard = tmp_path / f"stack{round_}.jsonl"
            server = subprocess.Popen([sys.executable, "-m", "tests.support.nav_stack_server", uri, str(heard)], env=env)
            try:
                wait_for(Path(f"{heard}.ready"), "the stand-in stack", [server])
                deadline = time.monotonic() + 60
                while not client.ready():
                    assert time.monotonic() < deadline, "the server never answered"
                    time.sleep(0.05)
                client.send(Pose2D(5.0, 0.0, 0.0), "odom", 0)
                while client.status() != nav.ACTIVE:
                    assert time.monotonic() < deadline, client.status()
                    time.sleep(0.05)
            finally:
                server.terminate()  # a stack shut down, as Ctrl-C does: its node leaves the domain
                server.wait(timeout=30)
            time.sleep(1.0)  # the server's writers are gone: their last samples say so, and carry no data
            assert client.status() == nav.ACTIVE  # no new word on the goal, and no error
    finally:
        transport.close()
