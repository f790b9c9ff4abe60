"""One side of a ROS 1 transport test, run as its own process (rospy allows one node per process).

`python -m tests.support.ros1_echo MODE ROBOT_URI` prints one JSON object a line on stdout:

- `talk`: publishes SAMPLES (the latched ones once, before saying ready; the others every 50 ms)
  and BAD_SCAN until its stdin closes.
- `listen`: subscribes to SAMPLES and BAD_SCAN, and prints the first value of each sample, what
  `lost()` says of the bad scan, and the node's log file.
- `watch`: says ready, tries a second node in the process, then waits for `lost()`, says it, and closes.
- `open`: tries to open a node and prints the LinkError and how long it took.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.records import Odometry, Scan, Transform
from trials.robot.ros1 import Ros1Transport, import_rospy
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, LinkError, RobotUri, Velocity

#: Seconds any wait of a driver may take before it gives up (generous: the test machine may be loaded).
PATIENCE_S = 60.0

#: kind: (topic, value, latched). Stamps of 2023 with odd nanoseconds; ranges with REP 117's inf and NaN.
SAMPLES: dict[str, tuple[str, Any, bool]] = {
    SCAN: ("/scan", Scan(1_700_000_123_456_789_123, "laser", -2.35619449, 0.0043633231, 0.05, 30.0,
                         np.array([0.1, 1.5, np.inf, np.nan, 29.999, 3.0 / 7.0])), False),
    ODOMETRY: ("/odom", Odometry(1_700_000_124_000_000_001, "odom", "base_link", Pose2D(12.345678901, -6.5, 2.9), 0.75, -0.3125), False),
    TF: ("/tf", [Transform(1_700_000_125_999_999_999, "odom", "base_link", Pose2D(1.0, 2.0, -3.1), False),
                 Transform(1_700_000_126_000_000_000, "map", "odom", Pose2D(-0.25, 0.125, 0.001), False)], False),
    TF_STATIC: ("/tf_static", [Transform(1_700_000_000_000_000_007, "base_link", "laser", Pose2D(0.2, 0.0, 3.14159), True)], True),
    TWIST: ("/cmd_vel", Velocity(0.5, -0.25), False),
    TWIST_STAMPED: ("/cmd_vel_stamped", Velocity(-0.125, 1.75, 1_700_000_127_000_000_042, "base_footprint"), False),
    FLAG: ("/trial_active", True, False),
    TEXT: ("/trial_status", "run 3 of 12: ünïcode ✓", True),
}
#: A scan whose angles and beam count disagree (zero increment): the listener's lost() must say so.
BAD_SCAN = ("/bad_scan", Scan(1_700_000_200_000_000_000, "laser", 0.0, 0.0, 0.05, 30.0, np.ones(3)))


def environment(ros_home: Path) -> dict[str, str]:
    """The environment of a test's ROS process: its own ROS_HOME, no ROS settings from outside."""
    return {k: v for k, v in os.environ.items() if not k.startswith("ROS_")} | {"ROS_HOME": str(ros_home), "PYTHONUNBUFFERED": "1"}


def say(**fields: Any) -> None:
    """One JSON line on stdout (records as plain dicts, arrays as lists, inf/NaN as JSON's extensions)."""
    print(json.dumps(fields, default=lambda v: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else np.asarray(v).tolist()), flush=True)


def node_uri() -> str:
    import rospy  # importable once a Ros1Transport exists

    return str(rospy.get_node_uri())


def talk(uri: RobotUri) -> None:
    transport = Ros1Transport(uri, "ros1_echo_talk")
    publishers = {kind: transport.publisher(topic, kind, latched) for kind, (topic, _, latched) in SAMPLES.items()}
    publish_bad_scan = transport.publisher(BAD_SCAN[0], SCAN)
    for kind, (_, value, latched) in SAMPLES.items():
        if latched:
            publishers[kind](value)
    say(ready=node_uri())
    stdin_closed = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stdin_closed.set()), daemon=True).start()
    deadline = time.monotonic() + PATIENCE_S
    while not stdin_closed.wait(0.05) and time.monotonic() < deadline:
        for kind, (_, value, latched) in SAMPLES.items():
            if not latched:
                publishers[kind](value)
        publish_bad_scan(BAD_SCAN[1])
    transport.close()


def listen(uri: RobotUri) -> None:
    transport = Ros1Transport(uri, "ros1_echo_listen")
    received: dict[str, Any] = {}
    everything = threading.Event()

    def keep(kind: str, value: Any) -> None:
        received.setdefault(kind, value)
        if len(received) == len(SAMPLES):
            everything.set()

    for kind, (topic, _, _) in SAMPLES.items():
        transport.subscribe(topic, kind, lambda value, kind=kind: keep(kind, value))
    transport.subscribe(BAD_SCAN[0], SCAN, lambda value: None)
    say(ready=node_uri())
    everything.wait(PATIENCE_S)
    deadline = time.monotonic() + PATIENCE_S
    while transport.lost() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    say(received=dict(received), lost=transport.lost(), log_file=str(transport.log_file))
    transport.close()
    transport.close()


def watch(uri: RobotUri) -> None:
    transport = Ros1Transport(uri, "ros1_echo_watch")
    try:
        Ros1Transport(uri, "ros1_echo_second")
        second = None
    except LinkError as error:
        second = str(error)
    say(ready=node_uri(), lost=transport.lost(), second=second)
    deadline = time.monotonic() + PATIENCE_S
    while transport.lost() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    say(lost=transport.lost(), log_file=str(transport.log_file))
    started = time.monotonic()
    transport.close()
    transport.close()
    say(close_s=time.monotonic() - started)


def try_open(uri: RobotUri) -> None:
    import_rospy()  # timed: the master check, not a slow import on a loaded machine
    started = time.monotonic()
    try:
        Ros1Transport(uri, "ros1_echo_open")
    except LinkError as error:
        say(error=str(error), seconds=time.monotonic() - started)
        return
    say(error=None, seconds=time.monotonic() - started)


if __name__ == "__main__":
    mode, robot = sys.argv[1:3]
    {"talk": talk, "listen": listen, "watch": watch, "open": try_open}[mode](RobotUri.parse(robot))
