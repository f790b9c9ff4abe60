"""Ros2Transport speaks ROS 2 as a stock node does: every kind round-trips between processes with
exact stamps, the bytes on the wire are the standard messages under rosidl's DDS names and
rclcpp's QoS, and a latched /tf_static reaches a node that joins later.

All traffic stays on 127.0.0.1 (loopback=True: unicast discovery, no multicast), each test on a
random domain id so parallel test processes do not hear each other. Waits poll against a
generous deadline, for a loaded 2-core machine.
"""

from __future__ import annotations

import logging
import math
import random
import select
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cyclonedds._clayer import ddspy_take
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication
from cyclonedds.core import InstanceState, Policy, Qos, SampleState, ViewState
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from rosbags.typesys import Stores, get_typestore

from robot_logs.frames import Pose2D, wrap_angle
from robot_logs.records import Odometry, Scan
from tests.support.ros2_talker import STATIC, TOPICS, VALUES
from trials.errors import StudyError
from trials.robot import ros2_types as msg
from trials.robot.ros2 import Ros2Transport, dds_topic
from trials.robot.transport import FLAG, MAX_DOMAIN, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, LinkError, RobotUri, Velocity

ROOT = Path(__file__).resolve().parents[1]
DEADLINE_S = 60.0
TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
#: Each kind's ROS 2 type, as rosbags names it and as rosidl names it for DDS.
ROS_TYPES = {SCAN: "sensor_msgs/msg/LaserScan", ODOMETRY: "nav_msgs/msg/Odometry", TF: "tf2_msgs/msg/TFMessage",
             TF_STATIC: "tf2_msgs/msg/TFMessage", TWIST: "geometry_msgs/msg/Twist",
             TWIST_STAMPED: "geometry_msgs/msg/TwistStamped", FLAG: "std_msgs/msg/Bool", TEXT: "std_msgs/msg/String"}
DDS_NAMES = {"rt/scan": "sensor_msgs::msg::dds_::LaserScan_", "rt/odom": "nav_msgs::msg::dds_::Odometry_",
             "rt/tf": "tf2_msgs::msg::dds_::TFMessage_", "rt/tf_static": "tf2_msgs::msg::dds_::TFMessage_",
             "rt/cmd_vel": "geometry_msgs::msg::dds_::Twist_", "rt/cmd_vel_stamped": "geometry_msgs::msg::dds_::TwistStamped_",
             "rt/trial_active": "std_msgs::msg::dds_::Bool_",
             "rt/trial_note": "std_msgs::msg::dds_::String_"}
IDL_TYPES = {SCAN: msg.LaserScan, ODOMETRY: msg.Odometry, TF: msg.TFMessage, TF_STATIC: msg.TFMessage,
             TWIST: msg.Twist, TWIST_STAMPED: msg.TwistStamped, FLAG: msg.Bool, TEXT: msg.String}


def random_uri() -> RobotUri:
    """A domain no other test process is likely to use at the same time."""
    return RobotUri.parse(f"ros2://{random.SystemRandom().randint(1, MAX_DOMAIN)}")


def wait_for(done: Callable[[], bool], what: str) -> None:
    """Poll `done` until it holds; fail naming `what` after the deadline."""
    end = time.monotonic() + DEADLINE_S
    while not done():
        assert time.monotonic() < end, f"no {what} within {DEADLINE_S:.0f} s"
        time.sleep(0.02)


def collect(transport: Ros2Transport, topics: dict[str, str]) -> dict[str, list[Any]]:
    """Subscribe to each kind's topic; the lists fill from the transport's thread."""
    received: dict[str, list[Any]] = {kind: [] for kind in topics}
    for kind, topic in topics.items():
        transport.subscribe(topic, kind, received[kind].append)
    return received


def assert_pose(got: Pose2D, sent: Pose2D) -> None:
    assert (got.x, got.y) == (sent.x, sent.y)
    assert abs(wrap_angle(got.yaw - sent.yaw)) < 1e-9


def assert_received(kind: str, got: Any, sent: Any) -> None:
    """`got` is `sent` after a trip through ROS 2: exact stamps and frames, float32 scan fields, yaw to 1e-9."""
    if kind == SCAN:
        assert isinstance(got, Scan)
        assert (got.stamp_ns, got.frame_id) == (sent.stamp_ns, sent.frame_id)
        assert (got.angle_min, got.angle_increment) == (np.float32(sent.angle_min), np.float32(sent.angle_increment))
        assert (got.range_min, got.range_max) == (np.float32(sent.range_min), np.float32(sent.range_max))
        np.testing.assert_array_equal(got.ranges, sent.ranges.astype(np.float32))
    elif kind == ODOMETRY:
        assert isinstance(got, Odometry)
        assert (got.stamp_ns, got.frame_id, got.child_frame_id, got.linear, got.angular) == (
            sent.stamp_ns, sent.frame_id, sent.child_frame_id, sent.linear, sent.angular)
        assert_pose(got.pose, sent.pose)
    elif kind in (TF, TF_STATIC):
        assert [(t.stamp_ns, t.parent, t.child, t.static) for t in got] == [(t.stamp_ns, t.parent, t.child, t.static) for t in sent]
        for g, s in zip(got, sent):
            assert_pose(g.pose, s.pose)
    else:
        assert got == sent and type(got) is type(sent)


@pytest.fixture(scope="module")
def talker() -> Iterator[RobotUri]:
    """A ros2_talker process on a random domain, past its one latched /tf_static publication ("ready")."""
    uri = random_uri()
    process = subprocess.Popen([sys.executable, "-m", "tests.support.ros2_talker", str(uri.domain)], cwd=ROOT,
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert process.stdin is not None and process.stdout is not None
    try:
        started, _, _ = select.select([process.stdout], [], [], DEADLINE_S)
        assert started and process.stdout.readline() == "ready\n", "the talker did not start"
        yield uri
        process.stdin.close()
        assert process.wait(timeout=DEADLINE_S) == 0
    finally:
        process.kill()
        process.wait()


def test_every_kind_round_trips_from_another_process_and_tf_static_is_latched(talker: RobotUri) -> None:
    # The talker sent /tf_static once, before this node existed: only transient-local durability brings it here.
    transport = Ros2Transport(talker, "listener", loopback=True)
    try:
        received = collect(transport, TOPICS)
        wait_for(lambda: all(received.values()), "message of every kind")
    finally:
        transport.close()
    for kind, sent in VALUES.items():
        assert_received(kind, received[kind][0], sent)
    assert_received(TF_STATIC, received[TF_STATIC][0], STATIC[0] + STATIC[1])


def raw_reader(participant: DomainParticipant, kind: str) -> Callable[[], list[bytes]]:
    """A reader of the talker's `kind` topic returning each sample's bytes as they came over the wire."""
    latched = kind == TF_STATIC
    qos = Qos(Policy.Reliability.Reliable(0) if latched else Policy.Reliability.BestEffort,
              Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile)
    reader = DataReader(participant, Topic(participant, dds_topic(TOPICS[kind]), IDL_TYPES[kind]), qos)
    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    # cyclonedds' own take, less its deserialization: the CDR payload with its encapsulation header.
    return lambda: [data for data, info in ddspy_take(reader._ref, mask, 16) if info.valid_data]


def test_the_wire_carries_standard_ros2_messages_under_rosidl_names_and_qos(talker: RobotUri) -> None:
    # A probe node holds the loopback domain in this process; a bare participant on it sees the raw traffic.
    probe = Ros2Transport(talker, "probe", loopback=True)
    try:
        participant = DomainParticipant(talker.domain)
        readers = {kind: raw_reader(participant, kind) for kind in TOPICS}
        publications = BuiltinDataReader(participant, BuiltinTopicDcpsPublication)
        raw: dict[str, bytes] = {}
        offered: dict[str, Any] = {}

        def arrived() -> bool:
            for kind, read in readers.items():
                for data in read():
                    raw.setdefault(kind, data)
            offered.update((p.topic_name, p) for p in publications.take(64))
            return len(raw) == len(readers) and DDS_NAMES.keys() <= offered.keys()

        wait_for(arrived, "raw sample and publication of every talker topic")
    finally:
        probe.close()

    assert {name: offered[name].type_name for name in DDS_NAMES} == DDS_NAMES
    for name in DDS_NAMES:
        qos = offered[name].qos
        latched = name == "rt/tf_static"
        assert qos[Policy.Reliability] == Policy.Reliability.Reliable(max_blocking_time=100_000_000), name
        assert qos[Policy.Durability] == (Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile), name
        assert qos[Policy.History] == Policy.History.KeepLast(1 if latched else 10), name

    for kind, data in raw.items():
        assert data[:2] == b"\x00\x01", f"{kind}: XCDR1 little-endian, as rmw_cyclonedds sends"
        again = bytes(TYPESTORE.serialize_cdr(TYPESTORE.deserialize_cdr(data, ROS_TYPES[kind]), ROS_TYPES[kind]))
        assert data == again.ljust(len(data), b"\0") and len(data) - len(again) < 4, f"{kind}: rosbags re-encodes other bytes"
    decoded = {kind: TYPESTORE.deserialize_cdr(data, ROS_TYPES[kind]) for kind, data in raw.items()}

    scan, sent = decoded[SCAN], VALUES[SCAN]
    assert (scan.header.stamp.sec, scan.header.stamp.nanosec, scan.header.frame_id) == (1_700_000_123, 456_789_012, "laser")
    assert scan.angle_max == np.float32(sent.angle_min + (len(sent.ranges) - 1) * sent.angle_increment)
    assert scan.ranges.dtype == np.float32 and len(scan.intensities) == 0
    np.testing.assert_array_equal(scan.ranges, sent.ranges.astype(np.float32))

    odom = decoded[ODOMETRY]
    assert (odom.header.stamp.sec, odom.header.stamp.nanosec, odom.header.frame_id, odom.child_frame_id) == (1_700_000_123, 987_654_321, "odom", "base_link")
    orientation = odom.pose.pose.orientation
    assert (orientation.x, orientation.y, orientation.z, orientation.w) == (0.0, 0.0, math.sin(2.9 / 2), math.cos(2.9 / 2))
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y, odom.twist.twist.linear.x, odom.twist.twist.angular.z) == (12.25, -3.5, 0.4, -0.7)
    assert not odom.pose.covariance.any() and not odom.twist.covariance.any()

    tf = decoded[TF].transforms
    assert [(t.header.stamp.sec, t.header.stamp.nanosec, t.header.frame_id, t.child_frame_id) for t in tf] == [
        (1_700_000_124, 999, "odom", "base_link"), (1_700_000_124, 1000, "map", "odom")]
    assert (tf[1].transform.translation.x, tf[1].transform.translation.y, tf[1].transform.rotation.z) == (-1.0, 0.5, math.sin(0.125))
    assert [t.child_frame_id for t in decoded[TF_STATIC].transforms] == ["laser", "camera"]
    twist = decoded[TWIST]
    assert (twist.linear.x, twist.linear.y, twist.angular.x, twist.angular.z) == (0.55, 0.0, 0.0, -0.35)
    stamped = decoded[TWIST_STAMPED]
    assert (stamped.header.stamp.sec, stamped.header.stamp.nanosec, stamped.header.frame_id) == (1_700_000_124, 500_000_077, "base_footprint")
    assert (stamped.twist.linear.x, stamped.twist.angular.z) == (-0.25, 1.5)
    assert decoded[FLAG].data is True and decoded[TEXT].data == "trial 7: héllo"


def test_a_laserscan_serialized_by_rosbags_decodes_with_our_type() -> None:
    types = TYPESTORE.types
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=-2, nanosec=999_999_999), frame_id="base_scan")
    ranges = np.array([0.5, np.inf, 3.25], dtype=np.float32)
    scan = types["sensor_msgs/msg/LaserScan"](header=header, angle_min=-0.5, angle_max=0.5, angle_increment=0.5, time_increment=1e-4,
                                              scan_time=0.1, range_min=0.1, range_max=12.0, ranges=ranges, intensities=np.float32([7, 8, 9]))
    ours = msg.LaserScan.deserialize(bytes(TYPESTORE.serialize_cdr(scan, "sensor_msgs/msg/LaserScan")))
    assert ours.header == msg.Header(msg.Time(-2, 999_999_999), "base_scan")
    assert (ours.angle_min, ours.angle_max, ours.angle_increment, ours.range_max) == (-0.5, 0.5, 0.5, 12.0)
    assert (ours.time_increment, ours.scan_time, ours.range_min) == (np.float32(1e-4), np.float32(0.1), np.float32(0.1))
    assert ours.ranges == ranges.tolist() and ours.intensities == [7.0, 8.0, 9.0]


def test_two_nodes_of_one_process_exchange_every_kind_and_a_late_node_gets_all_static_tf() -> None:
    uri = random_uri()
    talking, listening = Ros2Transport(uri, "talking", loopback=True), Ros2Transport(uri, "listening", loopback=True)
    late = None
    try:
        received = collect(listening, {kind: TOPICS[kind] for kind in VALUES})
        publish = {kind: talking.publisher(TOPICS[kind], kind) for kind in VALUES}
        static = talking.publisher(TOPICS[TF_STATIC], TF_STATIC)
        for transforms in STATIC:
            static(transforms)

        def delivered() -> bool:
            for kind, value in VALUES.items():
                publish[kind](value)
            return all(received.values())

        wait_for(delivered, "message of every kind")
        late = Ros2Transport(uri, "late", loopback=True)
        statics = collect(late, {TF_STATIC: TOPICS[TF_STATIC]})[TF_STATIC]
        wait_for(lambda: bool(statics), "latched /tf_static")
    finally:
        for transport in (talking, listening, late):
            if transport is not None:
                transport.close()
    for kind, sent in VALUES.items():
        assert_received(kind, received[kind][0], sent)
    # What a tf listener keeps (the latest transform of each child frame) is every static transform; under
    # load DDS has once handed the late reader two samples, which that merge takes as one.
    kept = {t.child: t for message in statics for t in message}
    assert_received(TF_STATIC, [kept[t.child] for t in STATIC[0] + STATIC[1]], STATIC[0] + STATIC[1])
    assert len(kept) == len(STATIC[0] + STATIC[1])


def test_a_failing_callback_is_logged_and_later_messages_still_arrive(caplog: pytest.LogCaptureFixture) -> None:
    uri = random_uri()
    transport = Ros2Transport(uri, "node", loopback=True)
    texts: list[str] = []

    def fussy(text: str) -> None:
        if not texts:
            texts.append("refused")
            raise RuntimeError("refused")
        texts.append(text)

    try:
        transport.subscribe("/note", TEXT, fussy)
        publish = transport.publisher("/note", TEXT)
        wait_for(lambda: publish("again") or len(texts) > 1, "message after the failing one")
    finally:
        transport.close()
    assert texts[1] == "again"
    assert any(r.levelno == logging.ERROR and r.exc_info and "refused" in str(r.exc_info[1]) for r in caplog.records)


def test_a_closed_node_refuses_work_and_closes_twice() -> None:
    transport = Ros2Transport(random_uri(), "node", loopback=True)
    publish = transport.publisher("/cmd_vel", TWIST)
    transport.close()
    transport.close()
    assert transport.lost() is None
    with pytest.raises(LinkError, match="closed"):
        publish(Velocity(0.1, 0.0))
    with pytest.raises(LinkError, match="closed"):
        transport.subscribe("/scan", SCAN, print)


def test_names_kinds_and_network_settings_are_checked() -> None:
    assert (dds_topic("/scan"), dds_topic("scan"), dds_topic("/robot_1/odom")) == ("rt/scan", "rt/scan", "rt/robot_1/odom")
    for bad in ("", "/", "/scan/", "//scan", "/1scan", "/sc an", "~/scan"):
        with pytest.raises(StudyError, match="ROS topic"):
            dds_topic(bad)
    uri = random_uri()
    transport = Ros2Transport(uri, "node", loopback=True)
    try:
        with pytest.raises(StudyError, match="message kind 'laser'"):
            transport.subscribe("/scan", "laser", print)
        transport.publisher("/scan", SCAN)
        with pytest.raises(StudyError, match="already uses it"):
            transport.subscribe("/scan", ODOMETRY, print)
        # Checked before Cyclone starts anything, so no traffic leaves the loopback here.
        with pytest.raises(LinkError, match="other network settings"):
            Ros2Transport(uri, "other", loopback=False)
    finally:
        transport.close()
