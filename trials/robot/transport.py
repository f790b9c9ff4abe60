"""The one interface between the live-run code and a ROS middleware: typed publish and subscribe of
the few message kinds a run needs, carried as robot_logs' plain records.

`trials.robot.ros1` (rospy, a ROS 1 master) and `trials.robot.ros2` (DDS through cyclonedds, as
a stock ROS 2 node speaks it) implement it; `open_transport` picks one from a robot URI. Nothing
above this module imports a ROS library, so the live loop, the software robot and their tests are
the same over either middleware.

Kinds and the values they carry (the ROS type in brackets):

- `SCAN` (sensor_msgs/LaserScan): `robot_logs.records.Scan`
- `ODOMETRY` (nav_msgs/Odometry): `robot_logs.records.Odometry` (planar pose, linear x, angular z)
- `TF`, `TF_STATIC` (tf2_msgs/TFMessage): a list of `robot_logs.records.Transform`
- `TWIST` (geometry_msgs/Twist): `Velocity` (linear x, angular z)
- `TWIST_STAMPED` (geometry_msgs/TwistStamped): `Velocity` with its header's stamp and frame
- `FLAG` (std_msgs/Bool): bool
- `TEXT` (std_msgs/String): str

Callbacks run on the middleware's own threads; a subscriber must hand values on, not work on them.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from trials.errors import StudyError

SCAN, ODOMETRY, TF, TF_STATIC, TWIST, TWIST_STAMPED, FLAG, TEXT = (
    "scan", "odometry", "tf", "tf_static", "twist", "twist_stamped", "flag", "text")
KINDS = (SCAN, ODOMETRY, TF, TF_STATIC, TWIST, TWIST_STAMPED, FLAG, TEXT)
#: The velocity command types a base may take (the `[robot]` table's `cmd_vel_type`), and the kind that carries each.
TWIST_TYPES = ("Twist", "TwistStamped")
TWIST_KINDS = dict(zip(TWIST_TYPES, (TWIST, TWIST_STAMPED), strict=True))

ROS1, ROS2 = "ros1", "ros2"
#: The highest ROS 2 domain id a DDS port mapping allows.
MAX_DOMAIN = 232


class LinkError(StudyError):
    """The middleware could not be reached or was lost; the message says which URI and why."""


@dataclass(frozen=True)
class Velocity:
    """A velocity command or reading of a planar base: linear (m/s, forward) and angular (rad/s, about z); as a
    TwistStamped, also its header's stamp (ns) and frame."""

    linear: float
    angular: float
    stamp_ns: int = 0
    frame_id: str = ""


@dataclass(frozen=True)
class RobotUri:
    """Where the robot is: `ros1://HOST:PORT` (a ROS 1 master) or `ros2://DOMAIN` (a ROS 2 domain id)."""

    scheme: str
    host: str = ""
    port: int = 0
    domain: int = 0

    @classmethod
    def parse(cls, text: str) -> RobotUri:
        """Read a robot URI.

        Raises:
            StudyError: anything but `ros1://HOST:PORT` with a port 1-65535 or `ros2://DOMAIN` with 0-232.
        """
        one = re.fullmatch(r"ros1://([A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(\d{1,5})/?", text)
        if one and 1 <= int(one[2]) <= 65535:
            return cls(ROS1, host=one[1], port=int(one[2]))
        two = re.fullmatch(r"ros2://(\d{1,3})/?", text)
        if two and int(two[1]) <= MAX_DOMAIN:
            return cls(ROS2, domain=int(two[1]))
        raise StudyError(f"robot URI {text!r}: expected ros1://HOST:PORT (a ROS 1 master, port 1-65535) "
                         f"or ros2://DOMAIN (a ROS 2 domain id, 0-{MAX_DOMAIN})")

    def __str__(self) -> str:
        return f"ros1://{self.host}:{self.port}" if self.scheme == ROS1 else f"ros2://{self.domain}"

    @property
    def master_uri(self) -> str:
        """The ROS_MASTER_URI of a ROS 1 robot."""
        return f"http://{self.host}:{self.port}/"


class Transport(Protocol):
    """One process's node on the robot's middleware."""

    uri: RobotUri
    #: This node as `publishers` names it.
    node_id: str

    def publisher(self, topic: str, kind: str, latched: bool = False) -> Callable[[Any], None]:
        """A function that publishes one value of `kind` on `topic`; `latched`: late subscribers get the
        last value (ROS 1 latching, ROS 2 transient-local durability)."""
        ...

    def subscribe(self, topic: str, kind: str, callback: Callable[[Any], None], latched: bool = False) -> None:
        """Call `callback(value)` for every message of `kind` on `topic` (from the middleware's threads); `latched`: also
        the last value a latched publisher sent before (ROS 2 asks for it with transient-local durability, and then hears
        latched publishers only; ROS 1 delivers it anyway)."""
        ...

    def publishers(self, topic: str) -> dict[str, str]:
        """Every node publishing on `topic` now, this one included: its `node_id` -> a description for messages
        (its name, and where the middleware says, its process and host).

        Raises:
            LinkError: the middleware could not be asked."""
        ...

    def lost(self) -> str | None:
        """Why the middleware can no longer be trusted (e.g. the ROS 1 master stopped answering), else None.
        Cheap: a transport that must poll does so on its own thread."""
        ...

    def close(self) -> None:
        """Leave the middleware; publishers and subscriptions stop."""
        ...


def open_transport(uri: RobotUri, node: str) -> Transport:
    """This process's node called `node` on the robot's middleware.

    Raises:
        LinkError: the middleware's library is missing or the robot cannot be reached.
    """
    if uri.scheme == ROS1:
        from trials.robot.ros1 import Ros1Transport

        return Ros1Transport(uri, node)
    from trials.robot.ros2 import Ros2Transport

    return Ros2Transport(uri, node)
