"""move_base's MoveBase action on ROS 1, through actionlib's SimpleActionClient on this process's rospy node
(`trials.robot.ros1`): Debian's python3-actionlib and python3-move-base-msgs."""

from __future__ import annotations

import importlib
import math
from typing import Any

from robot_logs.frames import Pose2D
from trials.robot import navigation as nav
from trials.robot.ros1 import import_rospy
from trials.robot.transport import LinkError

INSTALL = "sudo apt-get install python3-actionlib python3-actionlib-msgs python3-move-base-msgs"
#: actionlib_msgs/GoalStatus's values (0-9) in `trials.robot.navigation`'s words.
STATES = (nav.PENDING, nav.ACTIVE, nav.CANCELED, nav.SUCCEEDED, nav.ABORTED, nav.REJECTED, nav.CANCELING, nav.CANCELING,
          nav.CANCELED, nav.LOST)


class Ros1Navigation:
    """An actionlib client of `action` (move_base_msgs/MoveBaseAction); the node must already be registered."""

    def __init__(self, action: str) -> None:
        self.action = action
        self._rospy = import_rospy()
        try:
            actionlib = importlib.import_module("actionlib")
            self._msgs = importlib.import_module("move_base_msgs.msg")
        except ImportError as error:
            raise LinkError(f"the navigation stack's action needs actionlib and move_base_msgs ({error}): {INSTALL}") from None
        self._client: Any = actionlib.SimpleActionClient(action, self._msgs.MoveBaseAction)
        self._sent = False

    def ready(self) -> bool:
        """Whether the server's status has been heard and it takes this client's goals and cancels: actionlib's own
        `wait_for_server` test, asked once (that call waits on ROS time, which stands still under /use_sim_time)."""
        client = self._client.action_client
        status = client.last_status_msg
        if status is None:
            return False
        server = status._connection_header["callerid"]
        return bool(client.pub_goal.impl.has_connection(server) and client.pub_cancel.impl.has_connection(server))

    def send(self, goal: Pose2D, frame: str, stamp_ns: int) -> None:
        message = self._msgs.MoveBaseGoal()
        target = message.target_pose
        target.header.frame_id = frame
        target.header.stamp = self._rospy.Time(*divmod(stamp_ns, 1_000_000_000))
        target.pose.position.x, target.pose.position.y = goal.x, goal.y
        target.pose.orientation.z, target.pose.orientation.w = math.sin(goal.yaw / 2.0), math.cos(goal.yaw / 2.0)
        self._client.send_goal(message)
        self._sent = True

    def cancel(self) -> None:
        self._client.cancel_all_goals()

    def status(self) -> str:
        if not self._sent:
            return ""
        state = int(self._client.get_state())
        return STATES[state] if 0 <= state < len(STATES) else nav.LOST
