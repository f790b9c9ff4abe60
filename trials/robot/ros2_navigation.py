"""Nav2's NavigateToPose action on ROS 2, as an rclcpp action client speaks it over DDS with rmw_cyclonedds_cpp.

The action `navigate_to_pose` is the DDS topics `rq/navigate_to_pose/_action/send_goalRequest` and
`rr/.../send_goalReply`, `rq/.../cancel_goalRequest` and `rr/.../cancel_goalReply`, and `rt/.../status`
(`trials.robot.ros2_action_types` has their types). Requests and replies are reliable and volatile with a depth of 10
(ROS 2's services default); the status is reliable and transient-local with a depth of 1, as rcl_action latches it. The
client's id is random per client; replies carrying another id are another client's. Nav2 over Fast DDS puts a service's
request header in the RTPS message instead: this client speaks to stacks on rmw_cyclonedds_cpp only.
"""

from __future__ import annotations

import math
import secrets
import threading
import uuid

from cyclonedds.core import Policy, Qos
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from robot_logs.frames import Pose2D
from trials.robot import navigation as nav
from trials.robot import ros2_action_types as act
from trials.robot import ros2_types as msg
from trials.robot.ros2 import Ros2Transport, dds_topic
from trials.robot.transport import LinkError

_RELIABLE = Policy.Reliability.Reliable(max_blocking_time=100_000_000)
_XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)
SERVICE_QOS = Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepLast(10), _XCDR1)
STATUS_QOS = Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(1), _XCDR1)
#: action_msgs/GoalStatus's values in `trials.robot.navigation`'s words.
STATES = (nav.LOST, nav.PENDING, nav.ACTIVE, nav.CANCELING, nav.SUCCEEDED, nav.CANCELED, nav.ABORTED)
#: A zero goal id and stamp: cancel every goal.
EVERY_GOAL = act.GoalInfo(act.UUID([0] * 16), msg.Time(0, 0))


def action_topics(action: str) -> dict[str, str]:
    """The DDS topics of a ROS 2 action by role: goal, goal_reply, cancel, cancel_reply, status."""
    base = dds_topic(action)[2:] + "/_action"
    return {"goal": f"rq{base}/send_goalRequest", "goal_reply": f"rr{base}/send_goalReply",
            "cancel": f"rq{base}/cancel_goalRequest", "cancel_reply": f"rr{base}/cancel_goalReply", "status": f"rt{base}/status"}


class Ros2Navigation:
    """A NavigateToPose client of `action` on the transport's DDS participant; replies and status are read when asked."""

    def __init__(self, transport: Ros2Transport, action: str) -> None:
        if not isinstance(transport, Ros2Transport):
            raise LinkError(f"{transport.uri}: a ROS 2 action needs a ROS 2 node")
        self.action = action
        participant = transport.participant
        names = action_topics(action)

        def topic(role: str, kind: type) -> Topic:
            return Topic(participant, names[role], kind)

        self._goals = DataWriter(participant, topic("goal", act.SendGoalRequest), SERVICE_QOS)
        self._goal_replies = DataReader(participant, topic("goal_reply", act.SendGoalResponse), SERVICE_QOS)
        self._cancels = DataWriter(participant, topic("cancel", act.CancelGoalRequest), SERVICE_QOS)
        self._cancel_replies = DataReader(participant, topic("cancel_reply", act.CancelGoalResponse), SERVICE_QOS)
        self._status = DataReader(participant, topic("status", act.GoalStatusArray), STATUS_QOS)
        self._client = int.from_bytes(secrets.token_bytes(8), "little")
        self._sequence = 0
        self._goal: list[int] | None = None
        self._state = ""
        self._lock = threading.Lock()

    def ready(self) -> bool:
        return bool(self._goals.get_matched_subscriptions()) and bool(self._cancels.get_matched_subscriptions())

    def send(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        pose = msg.Pose(msg.Point(goal.x, goal.y, 0.0), msg.Quaternion(0.0, 0.0, math.sin(goal.yaw / 2.0), math.cos(goal.yaw / 2.0)))
        goal_id = list(uuid.uuid4().bytes)
        with self._lock:
            self._sequence += 1
            self._goal, self._state = goal_id, nav.PENDING
            request = act.SendGoalRequest(self._client, self._sequence, act.UUID(goal_id),
                                          act.NavigateToPoseGoal(act.PoseStamped(msg.Header(msg.Time(sec, nanosec), frame), pose), ""))
        self._goals.write(request)

    def cancel(self) -> None:
        with self._lock:
            self._sequence += 1
            request = act.CancelGoalRequest(self._client, self._sequence, EVERY_GOAL)
        self._cancels.write(request)

    def status(self) -> str:
        with self._lock:
            for reply in self._goal_replies.take(64):
                if reply.client == self._client and not reply.accepted and self._goal is not None:
                    self._state = nav.REJECTED
            self._cancel_replies.take(64)  # read so they do not pile up; the status says what a cancel did
            for statuses in self._status.take(64):
                for status in statuses.status_list:
                    if list(status.goal_info.goal_id.uuid) == self._goal and self._state != nav.REJECTED:
                        self._state = STATES[status.status] if 0 <= status.status < len(STATES) else nav.LOST
            return self._state
