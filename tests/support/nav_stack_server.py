"""A stand-in for a robot's navigation stack, for the tests, as its own process: a move_base action server (ROS 1,
actionlib) or a Nav2 NavigateToPose action server (ROS 2, over DDS as rmw_cyclonedds_cpp). Given a goal in the
odometry frame it drives the software robot toward it, from the robot's odometry, with velocity commands on
/cmd_vel_nav, until it is within 0.2 m (succeeded) or cancelled. Every goal and cancel it hears is appended to FILE as a
JSON line (a goal's frame and pose; over ROS 2 also the request's bytes as sent).

    python -m tests.support.nav_stack_server URI FILE [--give-up-after S]

`--give-up-after S`: S seconds into a goal, abort it and send no more commands (a stack that gives up).
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
import time
from pathlib import Path

from trials.robot.transport import ODOMETRY, ROS1, TWIST, RobotUri, Velocity, open_transport

#: The stack's command topic (the toolkit's default `nav_stack_cmd_vel_topic`), its rate, and when a goal counts as reached.
COMMANDS, RATE_HZ, REACHED_M = "/cmd_vel_nav", 20.0, 0.2


class Stack:
    """What both servers share: the robot's newest pose, the command law, and the record of what was heard."""

    def __init__(self, uri: RobotUri, out: Path, give_up_after: float | None) -> None:
        self.out, self.give_up_after = out, give_up_after
        self.transport = open_transport(uri, "stand_in_navigation")
        self.pose: tuple[float, float, float] | None = None
        self.transport.subscribe("/odom", ODOMETRY, lambda odometry: setattr(self, "pose", (odometry.pose.x, odometry.pose.y, odometry.pose.yaw)))
        self.publish = self.transport.publisher(COMMANDS, TWIST)
        self.lock = threading.Lock()

    def record(self, entry: dict) -> None:
        with self.lock, self.out.open("a", encoding="utf-8") as file:
            file.write(json.dumps({"wall_ns": time.time_ns(), **entry}) + "\n")

    def step(self, goal: tuple[float, float], began: float) -> bool | None:
        """Send one command toward `goal`: True when reached (a zero sent), None when the stack gives up, else False."""
        if self.give_up_after is not None and time.monotonic() - began > self.give_up_after:
            return None
        if self.pose is None:
            return False
        x, y, yaw = self.pose
        dx, dy = goal[0] - x, goal[1] - y
        if math.hypot(dx, dy) < REACHED_M:
            self.publish(Velocity(0.0, 0.0))
            return True
        error = math.atan2(math.sin(math.atan2(dy, dx) - yaw), math.cos(math.atan2(dy, dx) - yaw))
        self.publish(Velocity(0.8 * max(math.cos(error), 0.0), max(-1.5, min(1.5, 2.0 * error))))
        return False


def serve_ros1(stack: Stack) -> None:
    """move_base: actionlib's SimpleActionServer on the stack's rospy node; cancels are also heard on the topic itself."""
    import actionlib
    import rospy
    from actionlib_msgs.msg import GoalID
    from move_base_msgs.msg import MoveBaseAction

    def execute(goal) -> None:
        target = goal.target_pose
        q = target.pose.orientation
        stack.record({"goal": {"frame": target.header.frame_id, "x": target.pose.position.x, "y": target.pose.position.y,
                               "yaw": 2.0 * math.atan2(q.z, q.w)}})
        began = time.monotonic()
        while not rospy.is_shutdown():
            if server.is_preempt_requested():
                stack.publish(Velocity(0.0, 0.0))
                server.set_preempted()
                return
            reached = stack.step((target.pose.position.x, target.pose.position.y), began)
            if reached is None:
                server.set_aborted()
                return
            if reached:
                server.set_succeeded()
                return
            time.sleep(1.0 / RATE_HZ)

    rospy.Subscriber("/move_base/cancel", GoalID, lambda message: stack.record({"cancel": message.id}))
    server = actionlib.SimpleActionServer("move_base", MoveBaseAction, execute_cb=execute, auto_start=False)
    server.start()


def serve_ros2(stack: Stack, stop: threading.Event) -> None:
    """navigate_to_pose: the action's DDS endpoints on the stack's participant, answered on this thread."""
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from trials.robot import ros2_action_types as act
    from trials.robot import ros2_types as msg
    from trials.robot.ros2 import LATCHED_QOS, PUBLISHER_QOS
    from trials.robot.ros2_navigation import action_topics

    participant = stack.transport.participant
    names = action_topics("navigate_to_pose")
    goals = DataReader(participant, Topic(participant, names["goal"], act.SendGoalRequest), PUBLISHER_QOS)
    goal_replies = DataWriter(participant, Topic(participant, names["goal_reply"], act.SendGoalResponse), PUBLISHER_QOS)
    cancels = DataReader(participant, Topic(participant, names["cancel"], act.CancelGoalRequest), PUBLISHER_QOS)
    cancel_replies = DataWriter(participant, Topic(participant, names["cancel_reply"], act.CancelGoalResponse), PUBLISHER_QOS)
    status = DataWriter(participant, Topic(participant, names["status"], act.GoalStatusArray), LATCHED_QOS)
    current: tuple[act.GoalInfo, tuple[float, float], float] | None = None

    def say(info: act.GoalInfo, state: int) -> None:
        status.write(act.GoalStatusArray([act.GoalStatus(info, state)]))

    while not stop.wait(1.0 / RATE_HZ):
        for request in goals.take(16):
            pose = request.goal.pose
            q = pose.pose.orientation
            stack.record({"goal": {"frame": pose.header.frame_id, "x": pose.pose.position.x, "y": pose.pose.position.y,
                                   "yaw": 2.0 * math.atan2(q.z, q.w)}, "request": request.serialize().hex()})
            now = time.time_ns()
            info = act.GoalInfo(request.goal_id, msg.Time(now // 1_000_000_000, now % 1_000_000_000))
            goal_replies.write(act.SendGoalResponse(request.client, request.sequence, True, info.stamp))
            current = (info, (pose.pose.position.x, pose.pose.position.y), time.monotonic())
            say(info, 2)  # executing
        for request in cancels.take(16):
            stack.record({"cancel": bytes(request.goal_info.goal_id.uuid).hex()})
            canceling = [current[0]] if current is not None else []
            cancel_replies.write(act.CancelGoalResponse(request.client, request.sequence, 0, canceling))
            if current is not None:
                stack.publish(Velocity(0.0, 0.0))
                say(current[0], 5)  # canceled
                current = None
        reached = stack.step(current[1], current[2]) if current is not None else False
        if current is not None and reached is not False:
            say(current[0], 4 if reached else 6)  # succeeded, or aborted: given up
            current = None


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("uri")
    parser.add_argument("out", type=Path)
    parser.add_argument("--give-up-after", type=float)
    args = parser.parse_args(argv)
    uri = RobotUri.parse(args.uri)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    stack = Stack(uri, args.out, args.give_up_after)
    if uri.scheme == ROS1:
        serve_ros1(stack)
        Path(f"{args.out}.ready").touch()
        stop.wait()
    else:
        Path(f"{args.out}.ready").touch()
        serve_ros2(stack, stop)
    stack.transport.close()


if __name__ == "__main__":
    main(sys.argv[1:])
