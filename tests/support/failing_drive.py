"""Drive one run with a log that fails mid-run (its 40th state raises), to show that an exception stops the robot.
Prints `raised: <message>` once the exception has come out of `LiveRun.drive`.

    python -m tests.support.failing_drive URI RUN_CODE
"""

from __future__ import annotations

import sys

from trials.controllers import registry
from trials.robot.live import LiveRun, LiveSink, RobotLink, StopRequest
from trials.robot.one_driver import new_session
from trials.robot.settings import RobotSettings


class FailingLog(LiveSink):
    """A log whose disk fills up after 40 states."""

    def __init__(self) -> None:
        self.states = 0

    def state(self, *args: object) -> None:
        self.states += 1
        if self.states == 40:
            raise OSError(28, "No space left on device")


if __name__ == "__main__":
    uri, code = sys.argv[1:3]
    settings = RobotSettings(uri=uri, sensor_wait=120.0)
    live = LiveRun(RobotLink.open(settings, new_session()), StopRequest())
    assert live.wait(code, None) is None
    controller = registry.build(registry.LATTICE)
    controller.reset(0)
    try:
        live.drive(controller, (10.0, 0.0), FailingLog())
    except OSError as exc:
        print(f"raised: {exc}", flush=True)
    live.link.close()
