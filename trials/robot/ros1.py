"""The ROS 1 `Transport`: one rospy node registered with the robot's ROS 1 master, topics over TCPROS.

rospy comes from Debian 12's packages (python3-rospy and the message packages) in
/usr/lib/python3/dist-packages, which a virtual environment does not see: that folder is appended to
sys.path on first use, after the environment's own packages, so the environment's numpy and yaml win.
"""

from __future__ import annotations

import http.client
import importlib
import logging
import math
import os
import socket
import sys
import tempfile
import threading
import time
import xmlrpc.client
from collections.abc import Callable
from logging.handlers import RotatingFileHandler
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from robot_logs.convert import to_odometry, to_scan, to_transforms
from robot_logs.errors import LogError
from robot_logs.records import Odometry, Scan, Transform
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, LinkError, RobotUri, Velocity

DIST_PACKAGES = "/usr/lib/python3/dist-packages"
INSTALL = ("sudo apt-get install python3-rospy python3-rosmaster python3-sensor-msgs python3-nav-msgs python3-geometry-msgs "
           "python3-tf2-ros python3-tf2-msgs python3-std-msgs")
#: What the transport imports from Debian's packages.
ROS_MODULES = ("rospy", "rospkg", "std_msgs.msg", "geometry_msgs.msg", "nav_msgs.msg", "sensor_msgs.msg", "tf2_msgs.msg")
#: Seconds the master has to answer before the node registers (rospy's init_node would wait forever).
CHECK_TIMEOUT_S = 3.0
#: The master is asked for its pid this often, each time within POLL_TIMEOUT_S; MISSES failures in a row
#: mean it is gone (a stopped master refuses at once, so that takes about MISSES * POLL_S).
POLL_S = 0.25
POLL_TIMEOUT_S = 1.0
MISSES = 2
#: close() waits this long for rospy to unregister from a master that may no longer answer.
CLOSE_TIMEOUT_S = 5.0
QUEUE_SIZE = 10
#: Loggers of rospy and the libraries under it; their records go to the node's log file only.
ROS_LOGGERS = ("rospy", "rosout", "rosgraph", "xmlrpc")
_MASTER_ERRORS = (OSError, http.client.HTTPException, xmlrpc.client.Error, ValueError, TypeError)

_claim = threading.Lock()
_opened: str | None = None  # the node this process registered, if any: rospy allows one per process, once


class Ros1Transport:
    """This process's node on a ROS 1 robot (see `trials.robot.transport` for the kinds and their values).

    rospy allows one node per process, and never a second after the first was shut down: a second
    `Ros1Transport` in a process raises LinkError, even after the first was closed. The node is anonymous
    (`NODE_<pid>_<ms>`), installs no signal handlers (the caller owns SIGINT/SIGTERM) and logs into
    ROS's log folder only (ROS_LOG_DIR, else ROS_HOME/log, else ~/.ros/log; a temporary folder where that
    cannot be written; `log_file` says which file), never on the terminal.
    """

    def __init__(self, uri: RobotUri, node: str) -> None:
        """Register `node` with the master at `uri`, addressed by this machine's address on the route to it.

        Raises:
            LinkError: rospy is missing, the master does not answer, or this process already has a node.
        """
        global _opened
        self.uri = uri
        rospy = import_rospy()
        where = f"cannot reach the ROS 1 master at {uri}"
        try:
            address = _local_address(uri.host, uri.port)
            self._master_pid = _master_pid(uri.master_uri, f"/{node}", CHECK_TIMEOUT_S)
        except _MASTER_ERRORS as error:
            raise LinkError(f"{where}: {_reason(error)}") from error
        with _claim:
            if _opened is not None:
                raise LinkError(f"this process already opened the ROS 1 node {_opened!r}: rospy allows one node per process")
            _opened = node
        os.environ.update(ROS_MASTER_URI=uri.master_uri, ROS_IP=address, ROS_HOSTNAME=address)
        if ":" in address:
            os.environ["ROS_IPV6"] = "on"
        self._rospy = rospy
        self._lock = threading.Lock()
        self._closed = False
        self._lost: str | None = None
        self._fault: str | None = None
        self._topics: list[Any] = []
        self.log_file = _init_node(rospy, node)
        self.node_id = str(rospy.get_name())
        self._stop = threading.Event()
        self._watcher = threading.Thread(target=self._watch, name=f"ros1-master-watch-{node}", daemon=True)
        self._watcher.start()

    def publisher(self, topic: str, kind: str, latched: bool = False) -> Callable[[Any], None]:
        """A function that publishes one value of `kind` on `topic` (TF_STATIC is always latched).

        The function raises LinkError once the node is closed or shut down."""
        pub = self._rospy.Publisher(topic, _message_class(kind), queue_size=QUEUE_SIZE, latch=latched or kind == TF_STATIC, tcp_nodelay=True)
        self._topics.append(pub)

        def publish(value: Any) -> None:
            if self._closed:
                raise LinkError(f"cannot publish on {topic}: the ROS 1 node was closed")
            try:
                pub.publish(_to_message(self._rospy, kind, value))
            except self._rospy.ROSException as error:
                raise LinkError(f"cannot publish on {topic}: {error}") from error

        return publish

    def subscribe(self, topic: str, kind: str, callback: Callable[[Any], None], latched: bool = False) -> None:
        """Call `callback(value)` from rospy's threads for every message of `kind` on `topic` (a latched publisher's last
        value included, whatever `latched` says: ROS 1 latches on the publisher's side).

        A message that cannot be converted (or a callback that raises) is reported by `lost()` rather
        than only in rospy's log file."""
        where = f"{kind} on {topic}"

        def receive(msg: Any) -> None:
            if self._closed:
                return
            try:
                callback(_from_message(kind, msg, where))
            except Exception as error:  # rospy would only log it to a file nobody reads
                self._fault = self._fault or (str(error) if isinstance(error, LogError) else f"{where}: {type(error).__name__}: {error}")

        self._topics.append(self._rospy.Subscriber(topic, _message_class(kind), receive, queue_size=QUEUE_SIZE, tcp_nodelay=True))

    def publishers(self, topic: str) -> dict[str, str]:
        """The nodes the master lists as publishing on `topic` (by name), within POLL_TIMEOUT_S.

        Raises:
            LinkError: the master did not answer."""
        try:
            with xmlrpc.client.ServerProxy(self.uri.master_uri, transport=_TimeoutTransport(POLL_TIMEOUT_S)) as master:
                code, message, state = master.getSystemState(self.node_id)
            if code != 1:
                raise ValueError(f"getSystemState answered {code}: {message}")
        except _MASTER_ERRORS as error:
            raise LinkError(f"cannot ask the ROS 1 master at {self.uri} who publishes on {topic}: {_reason(error)}") from error
        resolved = self._rospy.resolve_name(topic)
        nodes = next((nodes for name, nodes in state[0] if name == resolved), [])
        return {str(node): str(node) for node in nodes if node == self.node_id or self._alive(str(node))}

    def _alive(self, node: str) -> bool:
        """Whether a node the master lists still runs: a killed one stays registered until someone cleans up after it
        (`rosnode cleanup`), but its own XML-RPC port refuses. A node that answers late (a frozen process) counts as alive."""
        try:
            with xmlrpc.client.ServerProxy(self.uri.master_uri, transport=_TimeoutTransport(POLL_TIMEOUT_S)) as master:
                code, _, api = master.lookupNode(self.node_id, node)
            if code != 1:
                return False
            with xmlrpc.client.ServerProxy(api, transport=_TimeoutTransport(POLL_TIMEOUT_S)) as other:
                other.getPid(self.node_id)
        except ConnectionRefusedError:
            return False
        except _MASTER_ERRORS:
            return True
        return True

    def lost(self) -> str | None:
        """Why this node can no longer be trusted: the master stopped answering or restarted (its registrations
        are gone), rospy was shut down from outside, or a received message could not be handled."""
        if self._lost or self._fault:
            return self._lost or self._fault
        if not self._closed and self._rospy.is_shutdown():
            return f"the ROS 1 node on {self.uri} was shut down from outside (e.g. rosnode kill)"
        return None

    def close(self) -> None:
        """Unregister every topic and shut rospy down, waiting at most CLOSE_TIMEOUT_S; safe to call again."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._stop.set()
        leaving = threading.Thread(target=self._leave, name="ros1-close", daemon=True)
        leaving.start()
        leaving.join(CLOSE_TIMEOUT_S)
        self._watcher.join(POLL_TIMEOUT_S + POLL_S)

    def _leave(self) -> None:
        for topic in self._topics:
            topic.unregister()
        self._rospy.signal_shutdown("trials closed its ROS 1 transport")

    def _watch(self) -> None:
        """Poll the master, whose death TCPROS connections between nodes would otherwise hide."""
        misses = 0
        while not self._stop.wait(POLL_S):
            try:
                pid = _master_pid(self.uri.master_uri, "/trials_watch", POLL_TIMEOUT_S)
            except _MASTER_ERRORS as error:
                misses += 1
                if misses >= MISSES:
                    self._lost = f"the ROS 1 master at {self.uri} stopped answering: {_reason(error)}"
                    return
                continue
            misses = 0
            if pid != self._master_pid:
                self._lost = f"the ROS 1 master at {self.uri} restarted (pid {self._master_pid}, now {pid}): this node is no longer registered"
                return


def import_rospy() -> ModuleType:
    """rospy, its message packages imported too, from Debian's dist-packages where the running Python does not see them by itself.

    Raises:
        LinkError: they are not installed (the message says how to).
    """
    try:
        return _import_ros()
    except ImportError:
        if sys.version_info[:2] == (3, 11) and os.path.isdir(DIST_PACKAGES) and DIST_PACKAGES not in sys.path:
            sys.path.append(DIST_PACKAGES)
    try:
        return _import_ros()
    except ImportError as error:
        raise LinkError(f"ROS 1 needs rospy and its message packages ({error}): install Debian 12's with `{INSTALL}`") from error


def _import_ros() -> ModuleType:
    for name in ROS_MODULES:
        importlib.import_module(name)
    return importlib.import_module("rospy")


class _TimeoutTransport(xmlrpc.client.Transport):
    """XML-RPC over HTTP that gives up after `timeout` seconds (the stock one waits as long as TCP does)."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


def _master_pid(master_uri: str, caller: str, timeout: float) -> int:
    """The process id the ROS 1 master at `master_uri` reports, within `timeout` seconds."""
    with xmlrpc.client.ServerProxy(master_uri, transport=_TimeoutTransport(timeout)) as master:
        code, message, pid = master.getPid(caller)
    if code != 1:
        raise ValueError(f"getPid answered {code}: {message}")
    return int(pid)


def _reason(error: Exception) -> str:
    """An exception as a short phrase for a one-line message."""
    if isinstance(error, xmlrpc.client.ProtocolError):
        return f"HTTP {error.errcode} {error.errmsg} (not a ROS master?)"
    text = error.strerror if isinstance(error, OSError) and error.strerror else str(error) or type(error).__name__
    return " ".join(text.split())


def _local_address(host: str, port: int) -> str:
    """This machine's address on the route to host:port (127.0.0.1 for a loopback master): the one the
    master and the robot's nodes can call this node back on, and the only one it listens on if loopback."""
    host = host.strip("[]")
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect((host, port))  # UDP: picks the route, sends nothing
        return str(probe.getsockname()[0])


def _init_node(rospy: ModuleType, node: str) -> Path:
    """Register the anonymous node, its log records going to a file only; returns that file.

    rospy's stock logging configuration would replace the root logger's handlers and echo rospy's
    warnings on the terminal, so an empty one (ROS_PYTHON_LOG_CONFIG_FILE) stands in for it, and one
    file handler on rospy's loggers does the logging.

    Raises:
        LinkError: the master refused or dropped the registration.
    """
    import rospkg

    folder = Path(rospkg.get_log_dir())
    if not _writable(folder):
        folder = Path(tempfile.mkdtemp(prefix="trials-ros1-log-"))
        os.environ["ROS_LOG_DIR"] = str(folder)
    log_file = folder / f"{node}-{os.getpid()}.log"
    handler = RotatingFileHandler(log_file, maxBytes=50_000_000, backupCount=4)
    handler.setFormatter(logging.Formatter("[%(name)s][%(levelname)s] %(asctime)s: %(message)s"))
    for name in ROS_LOGGERS:
        logger = logging.getLogger(name)
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
        logger.propagate = False
    descriptor, config = tempfile.mkstemp(prefix="trials-ros1-logging-", suffix=".yaml")
    before = os.environ.get("ROS_PYTHON_LOG_CONFIG_FILE")
    try:
        with os.fdopen(descriptor, "w") as out:
            out.write("version: 1\nincremental: true\n")
        os.environ["ROS_PYTHON_LOG_CONFIG_FILE"] = config
        # argv: the toolkit's own command line holds no ROS remappings
        rospy.init_node(node, argv=sys.argv[:1], anonymous=True, disable_signals=True)
    except (rospy.ROSException, OSError) as error:
        raise LinkError(f"cannot register the node {node!r} with the ROS 1 master at {os.environ['ROS_MASTER_URI']}: {_reason(error)}") from error
    finally:
        os.unlink(config)
        if before is None:
            os.environ.pop("ROS_PYTHON_LOG_CONFIG_FILE", None)
        else:
            os.environ["ROS_PYTHON_LOG_CONFIG_FILE"] = before
    return log_file


def _writable(folder: Path) -> bool:
    """Whether files can be created in `folder` (made if missing); root passes os.access on read-only mounts too."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def _message_class(kind: str) -> type:
    """The ROS 1 message class that carries `kind`."""
    from geometry_msgs.msg import Twist, TwistStamped
    from nav_msgs.msg import Odometry as OdometryMsg
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Bool, String
    from tf2_msgs.msg import TFMessage

    classes = {SCAN: LaserScan, ODOMETRY: OdometryMsg, TF: TFMessage, TF_STATIC: TFMessage, TWIST: Twist,
               TWIST_STAMPED: TwistStamped, FLAG: Bool, TEXT: String}
    if kind not in classes:
        raise ValueError(f"unknown message kind {kind!r}, expected one of {', '.join(classes)}")
    return classes[kind]


def _header(rospy: ModuleType, stamp_ns: int, frame_id: str) -> Any:
    from std_msgs.msg import Header

    secs, nsecs = divmod(stamp_ns, 1_000_000_000)
    return Header(stamp=rospy.Time(secs, nsecs), frame_id=frame_id)


def _quaternion(yaw: float) -> Any:
    from geometry_msgs.msg import Quaternion

    return Quaternion(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def _to_message(rospy: ModuleType, kind: str, value: Any) -> Any:
    """A robot_logs record (or Velocity, bool, str) as the ROS 1 message of `kind`."""
    from geometry_msgs.msg import Point, Pose, TransformStamped, Twist, TwistStamped, Vector3
    from geometry_msgs.msg import Transform as TransformMsg
    from nav_msgs.msg import Odometry as OdometryMsg
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Bool, String
    from tf2_msgs.msg import TFMessage

    if kind == SCAN:
        scan: Scan = value
        return LaserScan(header=_header(rospy, scan.stamp_ns, scan.frame_id), angle_min=scan.angle_min,
                         angle_max=scan.angle_min + (len(scan.ranges) - 1) * scan.angle_increment, angle_increment=scan.angle_increment,
                         time_increment=0.0, scan_time=0.0, range_min=scan.range_min, range_max=scan.range_max,
                         ranges=np.asarray(scan.ranges, dtype=np.float32).tolist(), intensities=[])
    if kind == ODOMETRY:
        odometry: Odometry = value
        msg = OdometryMsg(header=_header(rospy, odometry.stamp_ns, odometry.frame_id), child_frame_id=odometry.child_frame_id)
        msg.pose.pose = Pose(Point(odometry.pose.x, odometry.pose.y, 0.0), _quaternion(odometry.pose.yaw))
        msg.twist.twist = Twist(Vector3(odometry.linear, 0.0, 0.0), Vector3(0.0, 0.0, odometry.angular))
        return msg
    if kind in (TF, TF_STATIC):
        transforms: list[Transform] = value
        return TFMessage([TransformStamped(_header(rospy, t.stamp_ns, t.parent), t.child,
                                           TransformMsg(Vector3(t.pose.x, t.pose.y, 0.0), _quaternion(t.pose.yaw))) for t in transforms])
    if kind == TWIST:
        return Twist(Vector3(value.linear, 0.0, 0.0), Vector3(0.0, 0.0, value.angular))
    if kind == TWIST_STAMPED:
        return TwistStamped(_header(rospy, value.stamp_ns, value.frame_id), Twist(Vector3(value.linear, 0.0, 0.0), Vector3(0.0, 0.0, value.angular)))
    if kind == FLAG:
        return Bool(bool(value))
    if kind == TEXT:
        return String(str(value))
    raise ValueError(f"unknown message kind {kind!r}")


def _from_message(kind: str, msg: Any, where: str) -> Any:
    """A received ROS 1 message as the value of `kind` (robot_logs' converters, timed now where unstamped)."""
    if kind == SCAN:
        return to_scan(msg, time.time_ns(), where)
    if kind == ODOMETRY:
        return to_odometry(msg, time.time_ns())
    if kind in (TF, TF_STATIC):
        return to_transforms(msg, time.time_ns(), static=kind == TF_STATIC)
    if kind == TWIST:
        return Velocity(float(msg.linear.x), float(msg.angular.z))
    if kind == TWIST_STAMPED:
        stamp = msg.header.stamp
        return Velocity(float(msg.twist.linear.x), float(msg.twist.angular.z), stamp.secs * 1_000_000_000 + stamp.nsecs, msg.header.frame_id)
    if kind == FLAG:
        return bool(msg.data)
    return str(msg.data)
