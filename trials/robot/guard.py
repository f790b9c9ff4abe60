"""The parent's hold on the robot during `trials run --robot`: its own node, with a velocity publisher connected from the
start, that stops the robot when the worker driving it is gone however it died (SIGKILL and the out-of-memory killer
included, which no handler in the worker can catch), and keeps what that run had recorded.

The guard never learns which controller drove: it sends zero velocity, writes the public state, and recovers the
public log from the worker's partial file into runs/aborted/.
"""

from __future__ import annotations

from pathlib import Path

from robot_logs.errors import LogError
from robot_logs.foxglove_log import partial_path, recover
from trials.errors import StudyError
from trials.live_checks import record_check
from trials.robot.live import ABORTED, DRIVING, WAITING, stop_robot, velocity_publisher
from trials.robot.live_state import read_state, write_state
from trials.robot.live_trial import aborted_stamp
from trials.robot.one_driver import node_name, publisher_fault, wait_for_discovery
from trials.robot.settings import RobotSettings
from trials.robot.transport import open_transport
from trials.study import StudyFolder, to_the_minute


class Guard:
    """The parent's node on the robot's middleware.

    Raises (on creation):
        StudyError: the robot cannot be reached (LinkError), its middleware is not installed, or another node drives it.
    """

    def __init__(self, folder: StudyFolder, settings: RobotSettings, blind: bool, session: str) -> None:
        self.folder, self.blind = folder, blind
        self.transport = open_transport(settings.robot_uri, node_name(session, "guard"))
        try:
            # Asked before this session publishes a command, so that a session refused here never disturbs the one driving.
            wait_for_discovery(self.transport)
            fault = publisher_fault(self.transport, settings, session)
        except StudyError:
            self.transport.close()
            raise
        if fault is not None:
            self.transport.close()
            raise StudyError(f"trials run --robot did not start: {fault}")
        self.send = velocity_publisher(self.transport, settings)

    def halt(self) -> None:
        """Zero velocity, sent as a run's own stop sends it."""
        stop_robot(self.send)

    def worker_died(self, code: str | None, why: str) -> str | None:
        """Stop the robot after the driving worker died (`why`); when run `code` was under way (its state waiting or
        driving), mark it aborted and keep its log. Returns the run's failure line (naming where its log went), or None."""
        self.halt()
        state = read_state(self.folder)
        if code is None or state is None or state.get("run_code") != code or state.get("state") not in (WAITING, DRIVING):
            return None
        detail = f"the worker driving the run died ({why})"
        write_state(self.folder, code, ABORTED, detail)
        if state.get("state") == DRIVING:
            record_check(self.folder, code, ABORTED, detail, None, self.blind)
        kept = self._keep_log(code)
        where = f"; its log is {kept}" if kept is not None else "; it had recorded nothing"
        return f"run {code} aborted: {detail}{where}"

    def _keep_log(self, code: str) -> Path | None:
        """The log the dead worker was writing, what of it was complete, moved to runs/aborted/."""
        partial = partial_path(self.folder.run_log(code))
        if not partial.exists():
            return None
        target = self.folder.aborted_log(code, aborted_stamp())
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            recover(partial, target)
        except (LogError, OSError):
            return None
        partial.unlink(missing_ok=True)
        if self.blind:
            to_the_minute(target, target.parent)
        return target

    def close(self) -> None:
        self.transport.close()
