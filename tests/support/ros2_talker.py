"""A ROS 2 node in a process of its own, for tests/test_robot_ros2.py: one known value of every kind.

`python -m tests.support.ros2_talker DOMAIN` joins domain DOMAIN on the loopback only, publishes
the static transforms once (latched), prints "ready", then publishes `VALUES` every 50 ms until
its stdin closes (the test's end) or `LIFETIME_S` passes (a test that died), and exits 0.
"""

from __future__ import annotations

import sys
import threading

import numpy as np

from robot_logs.frames import Pose2D
from robot_logs.records import Odometry, Scan, Transform
from trials.robot.ros2 import Ros2Transport
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, RobotUri, Velocity

LIFETIME_S = 300.0
PERIOD_S = 0.05

TOPICS = {SCAN: "/scan", ODOMETRY: "/odom", TF: "/tf", TF_STATIC: "/tf_static", TWIST: "/cmd_vel",
          TWIST_STAMPED: "/cmd_vel_stamped", FLAG: "/trial_active", TEXT: "/trial_note"}

#: Static transforms, published in two calls: a late subscriber must still get both.
STATIC = (
    [Transform(1_700_000_000_000_000_001, "base_link", "laser", Pose2D(0.12, -0.03, np.pi), True)],
    [Transform(1_700_000_000_000_000_002, "base_link", "camera", Pose2D(0.2, 0.0, -1e-3), True)],
)

#: What the talker publishes on each periodic kind: stamps with every nanosecond digit, ranges that are not float32.
VALUES = {
    SCAN: Scan(1_700_000_123_456_789_012, "laser", -2.35619449, 0.004363323, 0.05, 30.0,
               np.concatenate([np.linspace(0.1, 29.9, 1077), [np.inf, np.nan, 0.0, 1.0 / 3.0]])),
    ODOMETRY: Odometry(1_700_000_123_987_654_321, "odom", "base_link", Pose2D(12.25, -3.5, 2.9), 0.4, -0.7),
    TF: [Transform(1_700_000_124_000_000_999, "odom", "base_link", Pose2D(12.25, -3.5, -3.1), False),
         Transform(1_700_000_124_000_001_000, "map", "odom", Pose2D(-1.0, 0.5, 0.25), False)],
    TWIST: Velocity(0.55, -0.35),
    TWIST_STAMPED: Velocity(-0.25, 1.5, 1_700_000_124_500_000_077, "base_footprint"),
    FLAG: True,
    TEXT: "trial 7: héllo",
}


def main(domain: int) -> None:
    """Publish as the module docstring says, on `ros2://DOMAIN` over the loopback."""
    transport = Ros2Transport(RobotUri.parse(f"ros2://{domain}"), "ros2_talker", loopback=True)
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    try:
        static = transport.publisher(TOPICS[TF_STATIC], TF_STATIC)
        for transforms in STATIC:
            static(transforms)
        publish = {kind: transport.publisher(TOPICS[kind], kind) for kind in VALUES}
        print("ready", flush=True)
        for _ in range(int(LIFETIME_S / PERIOD_S)):
            for kind, value in VALUES.items():
                publish[kind](value)
            if stop.wait(PERIOD_S):
                break
    finally:
        transport.close()


if __name__ == "__main__":
    main(int(sys.argv[1]))
