"""`Transport` over ROS 2: DDS through cyclonedds, speaking what a stock rclcpp node with
rmw_cyclonedds_cpp (or Fast DDS, over RTPS) speaks, with no ROS 2 installation.

Names: the DDS topic is "rt" + the ROS topic ("/scan" -> "rt/scan"), the type is rosidl's
`pkg::msg::dds_::Type_` (see `trials.robot.ros2_types`), samples are XCDR1.

QoS, as rclcpp and tf2_ros set it:

- publishers: reliable, volatile, keep-last 10 (rclcpp's default); `latched=True`: reliable,
  transient-local, keep-last 1 (the last value waits for late subscribers, as ROS 1 latching).
- `TF_STATIC` publishers are always latched, as tf2_ros' static broadcaster, and like it publish
  every static transform sent so far (keyed by child frame), so a late subscriber gets them all.
- subscribers: best-effort, volatile, keep-last 10, which matches reliable and best-effort
  publishers (SensorDataQoS lidar drivers) alike; `TF_STATIC` subscribers: reliable,
  transient-local, keep-last 100 (tf2_ros' static listener), the only way to get latched samples.
  A volatile subscriber never gets a latched value sent before it joined; that is ROS 2's rule.

Network: by default Cyclone picks the interface as on any ROS 2 machine (CYCLONEDDS_URI, if
set, applies as it does for rmw_cyclonedds; ROS_LOCALHOST_ONLY is not read). With
`loopback=True`, or the environment variable `NAVTRIALS_DDS_LOOPBACK=1`, the node stays on
127.0.0.1 with multicast off: discovery goes by unicast to participant indexes 0-32 of the
domain's ports on 127.0.0.1, which needs no multicast on `lo` (containers often lack it). The
tests run so. The choice is per domain and process: nodes of one process on one domain share it.

Receiving: one thread per node waits on a DDS waitset and runs the callbacks, rather than a
Cyclone listener, which would run Python on DDS's own receive thread (stalling its acks) and
could not be stopped cleanly from `close()`.

`lost()` is None unless that thread died of a DDS error: DDS has no master whose loss could be
noticed, and a robot that stops publishing is seen by the live loop as silence. Nodes do not
announce themselves on `ros_discovery_info`, so `ros2 node list` does not show them; `ros2 topic
list/echo` do.
"""

from __future__ import annotations

import logging
import math
import os
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsParticipant, BuiltinTopicDcpsPublication
from cyclonedds.core import DDSException, Entity, GuardCondition, InstanceState, Policy, Qos, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from robot_logs.convert import to_odometry, to_scan, to_transforms
from robot_logs.errors import LogError
from robot_logs.records import Odometry, Scan, Transform
from trials.errors import StudyError
from trials.robot import ros2_types as msg
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, LinkError, RobotUri, Velocity

#: Set to "1" to keep every ROS 2 node of this process on the loopback interface (tests do).
LOOPBACK_ENV = "NAVTRIALS_DDS_LOOPBACK"

#: Cyclone's configuration for a loopback-only node: unicast discovery among 127.0.0.1's participant indexes.
LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain Id="any">'
    '<General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General>'
    "<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>"
    '<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    "</Domain></CycloneDDS>"
)

_log = logging.getLogger(__name__)
_RELIABLE = Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
_XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)
#: Writers' QoS: rclcpp's default (also ROS 2's services'), and latched (also an action's status).
PUBLISHER_QOS = Qos(_RELIABLE, Policy.Durability.Volatile, Policy.History.KeepLast(10), _XCDR1)
LATCHED_QOS = Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(1), _XCDR1)
_SUBSCRIBER = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(10))
_LATCHED_SUBSCRIBER = Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(1))
_STATIC_SUBSCRIBER = Qos(_RELIABLE, Policy.Durability.TransientLocal, Policy.History.KeepLast(100))
#: Discovery samples read at most at once: participants or writers in one domain.
MAX_DISCOVERED = 4096
_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any


def _stamp(stamp_ns: int) -> msg.Time:
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return msg.Time(sec, nanosec)


def _quaternion(yaw: float) -> msg.Quaternion:
    return msg.Quaternion(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def _scan_msg(scan: Scan) -> msg.LaserScan:
    n = len(scan.ranges)
    return msg.LaserScan(
        msg.Header(_stamp(scan.stamp_ns), scan.frame_id),
        scan.angle_min, scan.angle_min + (n - 1) * scan.angle_increment, scan.angle_increment, 0.0, 0.0,
        scan.range_min, scan.range_max, np.asarray(scan.ranges, dtype=np.float32).tolist(), [],
    )


def _odometry_msg(odometry: Odometry) -> msg.Odometry:
    pose = odometry.pose
    return msg.Odometry(
        msg.Header(_stamp(odometry.stamp_ns), odometry.frame_id),
        odometry.child_frame_id,
        msg.PoseWithCovariance(msg.Pose(msg.Point(pose.x, pose.y, 0.0), _quaternion(pose.yaw)), [0.0] * 36),
        msg.TwistWithCovariance(_twist_msg(Velocity(odometry.linear, odometry.angular)), [0.0] * 36),
    )


def _tf_msg(transforms: list[Transform]) -> msg.TFMessage:
    return msg.TFMessage([
        msg.TransformStamped(
            msg.Header(_stamp(t.stamp_ns), t.parent), t.child,
            msg.Transform(msg.Vector3(t.pose.x, t.pose.y, 0.0), _quaternion(t.pose.yaw)),
        )
        for t in transforms
    ])


def _twist_msg(velocity: Velocity) -> msg.Twist:
    return msg.Twist(msg.Vector3(velocity.linear, 0.0, 0.0), msg.Vector3(0.0, 0.0, velocity.angular))


def _twist_stamped_msg(velocity: Velocity) -> msg.TwistStamped:
    return msg.TwistStamped(msg.Header(_stamp(velocity.stamp_ns), velocity.frame_id), _twist_msg(velocity))


def _velocity(m: msg.TwistStamped) -> Velocity:
    stamp = m.header.stamp
    return Velocity(float(m.twist.linear.x), float(m.twist.angular.z), stamp.sec * 1_000_000_000 + stamp.nanosec, m.header.frame_id)


@dataclass(frozen=True)
class _Kind:
    """How one kind goes over ROS 2: its message type, value -> message, and (message, record ns, where) -> value."""

    type: type[IdlStruct]
    encode: Callable[[Any], IdlStruct]
    decode: Callable[[Any, int, str], Any]


_KINDS = {
    SCAN: _Kind(msg.LaserScan, _scan_msg, to_scan),
    ODOMETRY: _Kind(msg.Odometry, _odometry_msg, lambda m, ns, where: to_odometry(m, ns)),
    TF: _Kind(msg.TFMessage, _tf_msg, lambda m, ns, where: to_transforms(m, ns, static=False)),
    TF_STATIC: _Kind(msg.TFMessage, _tf_msg, lambda m, ns, where: to_transforms(m, ns, static=True)),
    TWIST: _Kind(msg.Twist, _twist_msg, lambda m, ns, where: Velocity(float(m.linear.x), float(m.angular.z))),
    TWIST_STAMPED: _Kind(msg.TwistStamped, _twist_stamped_msg, lambda m, ns, where: _velocity(m)),
    FLAG: _Kind(msg.Bool, lambda value: msg.Bool(bool(value)), lambda m, ns, where: bool(m.data)),
    TEXT: _Kind(msg.String, lambda value: msg.String(str(value)), lambda m, ns, where: str(m.data)),
}


def dds_topic(topic: str) -> str:
    """The DDS topic of a ROS topic: "rt" + its absolute name ("scan" and "/scan" -> "rt/scan").

    Raises:
        StudyError: the name is empty or has an empty, trailing or non-word part.
    """
    name = topic if topic.startswith("/") else "/" + topic
    if not re.fullmatch(r"(/[A-Za-z_][A-Za-z0-9_]*)+", name):
        raise StudyError(f"ROS topic {topic!r}: expected names like /scan or /robot/odom (letters, digits, underscores)")
    return "rt" + name


def _kind(kind: str) -> _Kind:
    if kind not in _KINDS:
        raise StudyError(f"message kind {kind!r}: expected one of {', '.join(_KINDS)}")
    return _KINDS[kind]


def _participant_name(key: str, qos: Qos | None) -> str:
    """A participant as a message names it: its entity name (a ROS 2 node's participant often has none), process and host."""
    if qos is None:
        return f"DDS participant {key}"
    properties = {p.key: p.value for p in qos if isinstance(p, Policy.Property)}
    named = next((p.name for p in qos if isinstance(p, Policy.EntityName)), None) or f"DDS participant {key}"
    pid, host = properties.get("__Pid"), properties.get("__Hostname")
    where = ", ".join(part for part in (f"pid {pid}" if pid else "", f"host {host}" if host else "") if part)
    return f"{named} ({where})" if where else named


def _delete(entity: Entity) -> None:
    """Delete a DDS entity now, its children with it: cyclonedds-python deletes one only in its wrapper's `__del__`."""
    entity.__del__()


@dataclass
class _Joined:
    domain: Domain
    config: str
    nodes: int


_domains: dict[int, _Joined] = {}
_domains_lock = threading.Lock()


def _join(domain_id: int, config: str) -> None:
    """Count one more node on `domain_id`, creating Cyclone's domain with `config` for the first."""
    with _domains_lock:
        joined = _domains.get(domain_id)
        if joined is None:
            _domains[domain_id] = joined = _Joined(Domain(domain_id, config), config, 0)
        elif joined.config != config:
            raise LinkError(f"ros2://{domain_id}: this process already uses the domain with other network settings (loopback or not)")
        joined.nodes += 1


def _leave(domain_id: int) -> None:
    with _domains_lock:
        joined = _domains[domain_id]
        joined.nodes -= 1
        if not joined.nodes:
            del _domains[domain_id]
            _delete(joined.domain)


@dataclass(frozen=True)
class _Subscription:
    reader: DataReader
    decode: Callable[[Any, int, str], Any]
    callback: Callable[[Any], None]
    where: str


class Ros2Transport:
    """One ROS 2 node (a DDS participant on the URI's domain); callbacks run on its one receive thread."""

    def __init__(self, uri: RobotUri, node: str, loopback: bool | None = None) -> None:
        """Join domain `uri.domain`; `loopback` None follows NAVTRIALS_DDS_LOOPBACK.

        Raises:
            LinkError: Cyclone could not start the domain or the participant.
        """
        self.uri = uri
        self.node = node
        if loopback is None:
            loopback = os.environ.get(LOOPBACK_ENV) == "1"
        config = LOOPBACK_CONFIG if loopback else os.environ.get("CYCLONEDDS_URI", "")
        try:
            _join(uri.domain, config)
        except DDSException as e:
            raise LinkError(f"{uri}: cannot start DDS domain {uri.domain}: {e}") from e
        try:
            self._participant = DomainParticipant(uri.domain, qos=Qos(Policy.EntityName(node)))
        except DDSException as e:
            _leave(uri.domain)
            raise LinkError(f"{uri}: cannot join DDS domain {uri.domain} as {node!r}: {e}") from e
        self.node_id = str(self._participant.guid)
        # DDS discovery's own topics: who is in the domain, and every writer they have.
        self._participants = BuiltinDataReader(self._participant, BuiltinTopicDcpsParticipant)
        self._writers = BuiltinDataReader(self._participant, BuiltinTopicDcpsPublication)
        self._topics: dict[str, Topic] = {}
        self._subscriptions: tuple[_Subscription, ...] = ()
        self._static: dict[str, dict[str, Transform]] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._failure: str | None = None
        self._waitset = WaitSet(self._participant)
        self._wake = GuardCondition(self._participant)
        self._waitset.attach(self._wake)
        self._thread = threading.Thread(target=self._receive, name=f"ros2 {node}", daemon=True)
        self._thread.start()

    @property
    def participant(self) -> DomainParticipant:
        """This node's DDS participant, for the entities a ROS 2 action needs (`trials.robot.ros2_navigation`)."""
        self._check_open()
        return self._participant

    def publisher(self, topic: str, kind: str, latched: bool = False) -> Callable[[Any], None]:
        """A function publishing one value of `kind` on `topic` (see the module docstring for QoS)."""
        how = _kind(kind)
        with self._lock:
            self._check_open()
            qos = LATCHED_QOS if latched or kind == TF_STATIC else PUBLISHER_QOS
            writer = DataWriter(self._participant, self._topic(topic, how.type), qos)
            static = self._static.setdefault(topic, {}) if kind == TF_STATIC else None

        def publish(value: Any) -> None:
            if static is not None:
                static.update((t.child, t) for t in value)
                value = list(static.values())
            sample = how.encode(value)
            if self._closed:
                raise LinkError(f"{self.uri}: node {self.node!r} is closed; cannot publish on {topic}")
            try:
                writer.write(sample)
            except DDSException as e:
                raise LinkError(f"{self.uri}: publishing on {topic} failed: {e}") from e

        return publish

    def subscribe(self, topic: str, kind: str, callback: Callable[[Any], None], latched: bool = False) -> None:
        """Call `callback(value)` for each message of `kind` on `topic`, from this node's receive thread; `latched`: as a
        transient-local reader, which also gets the value a latched publisher sent before (and hears latched publishers only)."""
        how = _kind(kind)
        with self._lock:
            self._check_open()
            qos = _STATIC_SUBSCRIBER if kind == TF_STATIC else _LATCHED_SUBSCRIBER if latched else _SUBSCRIBER
            reader = DataReader(self._participant, self._topic(topic, how.type), qos)
            self._subscriptions += (_Subscription(reader, how.decode, callback, f"{self.uri} {topic}"),)
            self._waitset.attach(ReadCondition(reader, _ANY_SAMPLE))

    def publishers(self, topic: str) -> dict[str, str]:
        """The participants with a live writer on `topic`, as DDS discovery has found them so far (a participant that
        joined within the last moments may be missing: discovery takes some hundred milliseconds)."""
        name = dds_topic(topic)
        with self._lock:
            self._check_open()
            keys = {str(w.participant_key) for w in self._writers.read(MAX_DISCOVERED)
                    if w.sample_info.instance_state == InstanceState.Alive and w.topic_name == name}
            known = {str(p.key): p.qos for p in self._participants.read(MAX_DISCOVERED)
                     if p.sample_info.instance_state == InstanceState.Alive}
        return {key: _participant_name(key, known.get(key)) for key in sorted(keys)}

    def lost(self) -> str | None:
        """Why this node stopped receiving, else None: DDS has no master to lose (see the module docstring)."""
        return self._failure

    def close(self) -> None:
        """Stop the receive thread and leave the domain; safe to call twice, or from a callback."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._wake.set(True)
        if threading.current_thread() is not self._thread:
            self._thread.join()

    def _check_open(self) -> None:
        if self._closed:
            raise LinkError(f"{self.uri}: node {self.node!r} is closed")

    def _topic(self, topic: str, type_: type[IdlStruct]) -> Topic:
        name = dds_topic(topic)
        found = self._topics.get(name)
        if found is None:
            found = self._topics[name] = Topic(self._participant, name, type_)
        elif found.data_type is not type_:
            raise StudyError(f"ROS topic {topic}: this node already uses it for {found.data_type.__name__}, not {type_.__name__}")
        return found

    def _receive(self) -> None:
        """Hand each arriving message to its callback until closed, then delete the participant and leave the domain."""
        try:
            while not self._closed:
                self._waitset.wait(duration(infinite=True))
                for subscription in self._subscriptions:
                    if self._closed:
                        break
                    self._deliver(subscription)
        except DDSException as e:
            self._failure = f"{self.uri}: node {self.node!r} stopped receiving: {e}"
            raise
        finally:
            with self._lock:
                self._closed = True
                _delete(self._participant)
                _leave(self.uri.domain)

    def _deliver(self, subscription: _Subscription) -> None:
        while samples := subscription.reader.take(64):
            record_ns = time.time_ns()
            for sample in samples:
                if not sample.sample_info.valid_data:
                    continue
                try:
                    value = subscription.decode(sample, record_ns, subscription.where)
                except LogError as e:
                    _log.warning("dropped a message: %s", e)
                    continue
                try:
                    subscription.callback(value)
                except Exception:
                    _log.exception("subscriber to %s failed on a message", subscription.where)

