"""The DDS types of Nav2's NavigateToPose action as a stock ROS 2 node with rmw_cyclonedds_cpp exchanges them.

A ROS 2 action is three services and two topics. A service's request and reply go over DDS with rmw_cyclonedds_cpp's
16-byte header first (the client's id, a uint64, and the request's sequence number, an int64), then the rosidl type's
fields; the DDS type keeps rosidl's name (`nav2_msgs::action::dds_::NavigateToPose_SendGoal_Request_`). The goal follows
nav2_msgs/action/NavigateToPose (Humble to Kilted: a PoseStamped and a behaviour tree's name). No annotations
(`from __future__`) here: cyclonedds reads the field types from the live class annotations.
"""

from dataclasses import dataclass

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, int8, int64, sequence, uint8, uint64

from trials.robot.ros2_types import Header, Pose, Time


@dataclass
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    """unique_identifier_msgs/UUID: a goal's id."""

    uuid: array[uint8, 16]


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    """geometry_msgs/PoseStamped."""

    header: Header
    pose: Pose


@dataclass
class NavigateToPoseGoal(IdlStruct, typename="nav2_msgs::action::dds_::NavigateToPose_Goal_"):
    """nav2_msgs/action/NavigateToPose's goal."""

    pose: PoseStamped
    behavior_tree: str


@dataclass
class SendGoalRequest(IdlStruct, typename="nav2_msgs::action::dds_::NavigateToPose_SendGoal_Request_"):
    """A goal sent (`client`, `sequence`: the request header)."""

    client: uint64
    sequence: int64
    goal_id: UUID
    goal: NavigateToPoseGoal


@dataclass
class SendGoalResponse(IdlStruct, typename="nav2_msgs::action::dds_::NavigateToPose_SendGoal_Response_"):
    """The server's answer to a goal: accepted or not."""

    client: uint64
    sequence: int64
    accepted: bool
    stamp: Time


@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    """action_msgs/GoalInfo: a goal's id and when it was accepted."""

    goal_id: UUID
    stamp: Time


@dataclass
class CancelGoalRequest(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    """Cancel goals: a zero id and a zero stamp cancel every goal the server holds."""

    client: uint64
    sequence: int64
    goal_info: GoalInfo


@dataclass
class CancelGoalResponse(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    """The goals a cancel request reached."""

    client: uint64
    sequence: int64
    return_code: int8
    goals_canceling: sequence[GoalInfo]


@dataclass
class GoalStatus(IdlStruct, typename="action_msgs::msg::dds_::GoalStatus_"):
    """action_msgs/GoalStatus."""

    goal_info: GoalInfo
    status: int8


@dataclass
class GoalStatusArray(IdlStruct, typename="action_msgs::msg::dds_::GoalStatusArray_"):
    """action_msgs/GoalStatusArray: the server's goals and their states (latched)."""

    status_list: sequence[GoalStatus]
