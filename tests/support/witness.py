"""A witness node: subscribes to the velocity command topic through the project's transport and appends every command
it hears to a file as `wall_ns,linear,angular` lines, so a test can tell the last command a live run sent even after
the robot's process is gone.

    python -m tests.support.witness URI TOPIC FILE [TYPE]

TYPE is the command's message type, Twist (the default) or TwistStamped.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

from trials.robot.transport import TWIST_KINDS, RobotUri, Velocity, open_transport


def main(uri: str, topic: str, out: str, kind: str = "Twist") -> None:
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with Path(out).open("a", encoding="utf-8", buffering=1) as file:

        def heard(velocity: Velocity) -> None:
            file.write(f"{time.time_ns()},{velocity.linear!r},{velocity.angular!r}\n")

        transport = open_transport(RobotUri.parse(uri), "navtrials_witness")
        transport.subscribe(topic, TWIST_KINDS[kind], heard)
        Path(out + ".ready").touch()
        stop.wait()
        transport.close()


if __name__ == "__main__":
    main(*sys.argv[1:5])
