"""A `trials run` worker's side of live runs: one node on the robot's middleware, the signals that stop a run, the
state it reports (`trials.robot.live_state`), and where an aborted run's files go.

The worker that opened the sealed key drives the robot itself, so nobody on the field needs the key: the
parent process, the console and the state file (`runs/live.json`) see the run code and its state only.
SIGTERM (sent by `trials run` on Ctrl-C or `kill`, by the console's stop, and by Linux when the parent
dies) stops the run in progress as an e-stop does; with no run in progress the worker simply exits.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

from trials.controllers.base import Controller
from trials.errors import EStopped, RunAborted, StudyError
from trials.robot.live import ABORTED, LiveEnd, LiveRun, RobotLink, Sensors, StopRequest, estopped
from trials.robot.live_log import LiveLog
from trials.robot.live_state import write_state
from trials.robot.settings import RobotSettings
from trials.robot.staging import StartMark, stage_of
from trials.robot.transport import open_transport
from trials.study import LIVE_ESTOP, StudyFolder, utc_now


class LiveDriver:
    """One worker's node on the robot's middleware (of `trials run` session `session`), reused for every run it drives;
    `nav_stack`: one of its controllers is the robot's own navigation stack.

    Raises (on creation):
        StudyError: the robot cannot be reached (LinkError) or its middleware is not installed.
    """

    def __init__(self, folder: StudyFolder, settings: RobotSettings, session: str, nav_stack: bool = False) -> None:
        self.folder, self.settings = folder, settings
        self.link = RobotLink.open(settings, session, nav_stack)
        self.stop: StopRequest | None = None
        self.terminated = False
        self._working = False
        # An e-stop ends the session that saw it: a new session (`trials run`, the console's Start) begins released.
        folder.path(LIVE_ESTOP).unlink(missing_ok=True)
        signal.signal(signal.SIGTERM, self._on_signal)

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.terminated = True
        if self.stop is not None:
            self.stop.request(f"stopped by {signal.Signals(signum).name} (Ctrl-C or kill of trials run, or the console's stop)")
        elif not self._working:
            raise SystemExit(128 + signum)

    @contextmanager
    def task(self) -> Iterator[None]:
        """A run's whole task: a SIGTERM during it stops the robot and is obeyed (the worker exits) only once the run's
        files are kept, never halfway through writing them."""
        self._working = True
        try:
            yield
        finally:
            self._working = False
            if self.terminated:
                raise SystemExit(1)

    def drive(self, code: str, row: dict[str, str], controller: Controller, log: LiveLog) -> LiveEnd:
        """Drive row `code` with its (reset) controller, writing `log`. The robot is stopped however the run ends.

        Returns how the run ended; an `aborted` ending (e-stop, stale sensors, a signal, the middleware lost) is the
        caller's to keep aside.

        Raises:
            RunAborted: the run never started (its sensors were not all seen in time, or it was stopped while waiting).
        """
        estop = self.folder.path(LIVE_ESTOP)
        self.stop = StopRequest()
        state: Callable[[str, str], None] = lambda name, detail: write_state(self.folder, code, name, detail)  # noqa: E731
        live = LiveRun(self.link, self.stop, state, estop)
        try:
            try:
                stage = stage_of(self.settings, row, self.folder)
            except StudyError as exc:
                state(ABORTED, str(exc))
                raise RunAborted(f"run {code} did not start: {exc}") from None
            reason = live.wait(code, stage)
            if reason is not None:
                state(ABORTED, reason)
                raise (EStopped if estopped(reason) else RunAborted)(f"run {code} did not start: {reason}")
            end = live.drive(controller, self.settings.goal_for(row), log)
        finally:
            self.stop = None
        return end


def aborted_stamp() -> str:
    """The time in an aborted run's file names: UTC to the second, without colons."""
    return utc_now().replace(":", "").replace("+0000", "Z")


def move_aside(source: Path, target: Path) -> Path | None:
    """Move a finished file to where aborted runs keep theirs (creating the folder); None when there was nothing."""
    if not source.exists():
        return None
    target.parent.mkdir(parents=True, exist_ok=True)
    os.replace(source, target)
    return target


def measure_mark(settings: RobotSettings) -> StartMark:
    """The robot's pose in its odometry frame now, as it stands on the lab's start mark (`trials run --robot URI --mark`).

    Raises:
        StudyError: the robot cannot be reached, or sent no valid odometry within `sensor_wait` seconds.
    """
    import time

    transport = open_transport(settings.robot_uri, "navtrials_mark")
    try:
        sensors = Sensors(settings)
        sensors.attach(transport)
        deadline = time.monotonic() + settings.sensor_wait
        where = f"odometry on {settings.odometry_topic}" if settings.odometry_topic else f"tf from {settings.odometry_frame} to {settings.base_frame}"
        while sensors.odometry_seen is None or time.monotonic() - sensors.odometry_seen > settings.watchdog:
            if time.monotonic() > deadline:
                raise StudyError(f"no start mark measured: no valid {where} from {settings.uri} within {settings.sensor_wait:g} s")
            time.sleep(0.05)
        # The newest odometry after a short wait: a robot just put down may still be sending where it stood before.
        time.sleep(0.5)
        odometry = sensors.odometry
        assert odometry is not None
        return StartMark(settings.odometry_frame, odometry.pose, utc_now())
    finally:
        transport.close()
