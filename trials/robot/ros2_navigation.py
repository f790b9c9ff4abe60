"""Nav2's NavigateToPose action on ROS 2, as an rclcpp action client speaks it over DDS with rmw_cyclonedds_cpp.

The action `navigate_to_pose` is the DDS topics `rq/navigate_to_pose/_action/send_goalRequest` and
`rr/.../send_goalReply`, `rq/.../cancel_goalRequest` and `rr/.../cancel_goalReply`, and `rt/.../status`
(`trials.robot.ros2_action_types` has their types). Requests and replies are reliable and volatile with a depth of 10
(ROS 2's services default); the status is reliable and transient-local with a depth of 1, as rcl_action latches it. The
client's id is random per client; replies carrying another id are another client's. Nav2 over Fast DDS puts a service's
request header in the RTPS message instead, so it never answers this client: `ready` waits for an answer, not only for
DDS to match the endpoints.
"""

from __future__ import annotations

import math
import secrets
import time
import uuid

from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from robot_logs.frames import Pose2D
from trials.robot import navigation as nav
from trials.robot import ros2_action_types as act
from trials.robot import ros2_types as msg
from trials.robot.ros2 import LATCHED_QOS, PUBLISHER_QOS, Ros2Transport, dds_topic
from trials.robot.transport import LinkError

#: action_msgs/GoalStatus's values in `trials.robot.navigation`'s words.
STATES = (nav.LOST, nav.PENDING, nav.ACTIVE, nav.CANCELING, nav.SUCCEEDED, nav.CANCELED, nav.ABORTED)
#: A zero goal id and stamp: cancel every goal.
EVERY_GOAL = act.GoalInfo(act.UUID([0] * 16), msg.Time(0, 0))
#: Seconds between the cancel-all requests `ready` sends until one is answered.
ASK_EVERY_S = 0.5


def action_topics(action: str) -> dict[str, str]:
    """The DDS topics of a ROS 2 action by role: goal, goal_reply, cancel, cancel_reply, status."""
    base = dds_topic(action)[2:] + "/_action"
    return {"goal": f"rq{base}/send_goalRequest", "goal_reply": f"rr{base}/send_goalReply",
            "cancel": f"rq{base}/cancel_goalRequest", "cancel_reply": f"rr{base}/cancel_goalReply", "status": f"rt{base}/status"}


def valid(reader: DataReader) -> list:
    """The samples `reader` holds, less those that only say a writer went away (a restarted server leaves some)."""
    return [sample for sample in reader.take(64) if sample.sample_info.valid_data]


class Ros2Navigation:
    """A NavigateToPose client of `action` on the transport's DDS participant; replies and status are read when asked,
    on the caller's thread (the live loop's)."""

    def __init__(self, transport: Ros2Transport, action: str) -> None:
        if not isinstance(transport, Ros2Transport):
            raise LinkError(f"{transport.uri}: a ROS 2 action needs a ROS 2 node")
        self.action = action
        participant = transport.participant
        names = action_topics(action)

        def topic(role: str, kind: type) -> Topic:
            return Topic(participant, names[role], kind)

        self._goals = DataWriter(participant, topic("goal", act.SendGoalRequest), PUBLISHER_QOS)
        self._goal_replies = DataReader(participant, topic("goal_reply", act.SendGoalResponse), PUBLISHER_QOS)
        self._cancels = DataWriter(participant, topic("cancel", act.CancelGoalRequest), PUBLISHER_QOS)
        self._cancel_replies = DataReader(participant, topic("cancel_reply", act.CancelGoalResponse), PUBLISHER_QOS)
        self._status = DataReader(participant, topic("status", act.GoalStatusArray), LATCHED_QOS)
        self._client = int.from_bytes(secrets.token_bytes(8), "little")
        self._sequence = 0
        self._goal: tuple[int, list[int]] | None = None  # the newest goal's request sequence and id
        self._state = ""
        self._answered = False
        self._matched: frozenset[int] = frozenset()
        self._asked_at = -ASK_EVERY_S

    def ready(self) -> bool:
        """Whether the server DDS matches now has answered one of this client's requests: until it has, a cancel-all is
        sent every ASK_EVERY_S seconds (harmless: nothing of this run is under way yet). A server that restarted is a new
        match, asked again."""
        matched = frozenset(self._goals.get_matched_subscriptions())
        if matched != self._matched:
            self._matched, self._answered = matched, False
            valid(self._goal_replies), valid(self._cancel_replies)  # answers of a server gone do not count
        self._read_replies()
        if matched and not self._answered and time.monotonic() - self._asked_at >= ASK_EVERY_S:
            self._asked_at = time.monotonic()
            self.cancel()
        return self._answered

    def send(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        pose = msg.Pose(msg.Point(goal.x, goal.y, 0.0), msg.Quaternion(0.0, 0.0, math.sin(goal.yaw / 2.0), math.cos(goal.yaw / 2.0)))
        goal_id = list(uuid.uuid4().bytes)
        self._sequence += 1
        self._goal, self._state = (self._sequence, goal_id), nav.PENDING
        self._goals.write(act.SendGoalRequest(self._client, self._sequence, act.UUID(goal_id),
                                              act.NavigateToPoseGoal(act.PoseStamped(msg.Header(msg.Time(sec, nanosec), frame), pose), "")))

    def cancel(self) -> None:
        self._sequence += 1
        self._cancels.write(act.CancelGoalRequest(self._client, self._sequence, EVERY_GOAL))

    def status(self) -> str:
        self._read_replies()
        for statuses in valid(self._status):
            for status in statuses.status_list:
                if self._goal is not None and list(status.goal_info.goal_id.uuid) == self._goal[1] and self._state != nav.REJECTED:
                    self._state = STATES[status.status] if 0 <= status.status < len(STATES) else nav.LOST
        return self._state

    def _read_replies(self) -> None:
        for reply in valid(self._goal_replies):
            if reply.client == self._client:
                self._answered = True
                if self._goal is not None and reply.sequence == self._goal[0] and not reply.accepted:
                    self._state = nav.REJECTED
        for reply in valid(self._cancel_replies):
            self._answered = self._answered or reply.client == self._client
