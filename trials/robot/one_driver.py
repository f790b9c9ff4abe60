"""One driver per robot, one source per sensor: before and during live runs, who publishes on the robot's topics.

A `trials run --robot` session's nodes (its guard and its worker) share a session tag in their names. Any other node
publishing velocity commands on the robot, another study's `trials run` or a teleoperation node alike, keeps a session
from starting and stops a run under way; so does a second node publishing the scans or odometry a run tracks, whose
messages the run could not tell from the robot's own.
"""

from __future__ import annotations

import secrets
import threading
from collections.abc import Callable

from trials.robot.settings import RobotSettings
from trials.robot.transport import ROS2, LinkError, Transport

#: Seconds a ROS 2 node waits for DDS discovery before it asks who else is on the robot (ROS 1's master knows at once).
DISCOVERY_S = 1.5
#: How often a run asks the middleware who publishes on the robot's topics.
POLL_S = 0.5


def new_session() -> str:
    """A tag for one `trials run` session's node names on the robot: unique across computers and processes."""
    return f"navtrials_{secrets.token_hex(4)}"


def node_name(session: str, role: str) -> str:
    return f"{session}_{role}"


def _ours(description: str, session: str) -> bool:
    return description.lstrip("/").startswith(f"{session}_")


def publisher_fault(transport: Transport, settings: RobotSettings, session: str) -> str | None:
    """Why the robot is not this session's alone to drive now, else None.

    Raises:
        LinkError: the middleware could not be asked.
    """
    drivers = sorted(d for d in transport.publishers(settings.cmd_vel_topic).values() if not _ours(d, session))
    if drivers:
        return (f"another node commands the robot on {settings.cmd_vel_topic}: {', '.join(drivers)} "
                "(one driver per robot: stop it, or the other trials run, first)")
    for topic in filter(None, (settings.scan_topic, settings.odometry_topic)):
        sources = sorted(transport.publishers(topic).values())
        if len(sources) > 1:
            return f"{len(sources)} nodes publish on {topic} ({', '.join(sources)}): a run cannot tell the robot's own messages"
    return None


def wait_for_discovery(transport: Transport) -> None:
    """Give DDS discovery time to find the domain's other nodes before anyone is asked about."""
    if transport.uri.scheme == ROS2:
        threading.Event().wait(DISCOVERY_S)


class PublisherWatch:
    """Asks `publisher_fault` every `POLL_S` seconds on its own thread; `fault` is the latest answer (a middleware that
    cannot be asked is a fault too), told to `on_fault` as it appears."""

    def __init__(self, transport: Transport, settings: RobotSettings, session: str,
                 on_fault: Callable[[str], None] = lambda reason: None) -> None:
        self.transport, self.settings, self.session, self.on_fault = transport, settings, session, on_fault
        self.fault: str | None = None
        self._stop = threading.Event()
        self._check()
        self._thread = threading.Thread(target=self._watch, name="publisher-watch", daemon=True)
        self._thread.start()

    def _check(self) -> None:
        try:
            fault = publisher_fault(self.transport, self.settings, self.session)
        except LinkError as error:
            fault = str(error)
        self.fault = fault
        if fault is not None:
            self.on_fault(fault)

    def _watch(self) -> None:
        while not self._stop.wait(POLL_S):
            self._check()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(POLL_S + 2.0)
