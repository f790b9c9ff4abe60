"""The console's live runs: `trials run --robot URI --only CODE --study DIR` as a subprocess, one at a time per
study; its state from runs/live.json; the E-STOP (runs/estop, then SIGTERM to the subprocess).

The subprocess's worker opens the sealed key and drives the robot; the console starts it, reads the public
state file and signals it, so it never learns which controller drove a run. The run's outcome row, log and
failure record are written by `trials run`, as from the command line.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from trials.errors import StudyError
from trials.outcomes import read_outcomes
from trials.robot.live import ABORTED, DRIVING, WAITING
from trials.robot.live_state import read_state
from trials.robot.settings import read_robot_settings
from trials.robot.transport import RobotUri
from trials.runner import LIVE_GRACE_S, lock_state
from trials.study import LIVE_ESTOP, OUTCOMES, SPEC, StudyFolder

#: The state shown from Start until the worker first writes runs/live.json (loading controllers, reaching the robot).
STARTING = "starting"
#: States in which the robot may be moving or about to: E-STOP is offered then.
GOING = (STARTING, WAITING, DRIVING)
#: Seconds the console waits for a stopped live run to end before killing it: `trials run`'s own grace, and margin.
STOP_WAIT_S = LIVE_GRACE_S + 20.0


def run_command(uri: str, code: str, root: Path) -> list[str]:
    """The command line of a live run: `trials run --robot URI --only CODE --study DIR`, quiet (its errors still print)."""
    return [sys.executable, "-m", "trials.cli", "run", "--robot", uri, "--only", code, "--study", str(root), "--quiet"]


def robot_uri(folder: StudyFolder, given: str | None) -> str | None:
    """The robot the console drives runs on: `trials serve --robot URI`, else the uri of study.toml's [robot]
    table; None when the study is not driven live. StudyError for a bad URI or table."""
    if given is not None:
        return str(RobotUri.parse(given))
    settings = read_robot_settings(folder.path(SPEC))
    return settings.uri if settings is not None else None


@dataclass
class LiveProcess:
    """One `trials run --robot` the console started, with runs/live.json and the run's failure record as they
    were then (so the worker's first state is told from an earlier run's), and how it ended once it has."""

    code: str
    process: subprocess.Popen[bytes]
    errors: IO[bytes]
    state_before: dict[str, str] | None
    failure_before: str
    stopped: bool = False
    ended: tuple[bool, str] | None = None
    watcher: threading.Thread = field(init=False)

    @property
    def running(self) -> bool:
        """Until its ending (finished, or aborted and why) has been recorded."""
        return self.ended is None


class LiveRuns:
    """The study's live runs from the console; `on_end(code, finished, reason)` records how each ended."""

    def __init__(self, folder: StudyFolder, uri: str | None, on_end: Callable[[str, bool, str], None]) -> None:
        self.folder, self.uri = folder, uri
        self._on_end = on_end
        self._current: LiveProcess | None = None
        self._lock = threading.Lock()

    @property
    def running(self) -> str | None:
        """The code of the run being driven live from this console, if any."""
        live = self._current
        return live.code if live is not None and live.running else None

    def robot(self) -> str:
        """The robot's URI; StudyError when the study is not driven live."""
        if self.uri is None:
            raise StudyError(f"this study is not driven live: {SPEC} has no [robot] table (`trials design --robot URI` writes one) "
                             "and `trials serve` was not given --robot URI")
        return self.uri

    def start(self, code: str) -> None:
        """Start driving run `code` live; StudyError when the study is not live, or a run is already going."""
        with self._lock:
            uri = self.robot()
            if self.running is not None:
                raise StudyError(f"run {self.running} is being driven live now, and one live run goes at a time: wait for it to end, or press E-STOP")
            lock = lock_state(self.folder)
            if lock.held:
                raise StudyError(f"another `trials run` is running on this study (pid {lock.pid}); wait for it to end")
            before = read_state(self.folder), _failure(self.folder, code)
            errors = tempfile.TemporaryFile()
            # Its own session: a Ctrl-C meant for the console reaches the live run only as the console's stop (`close`).
            process = subprocess.Popen(run_command(uri, code, self.folder.root), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                       stderr=errors, start_new_session=True)
            live = LiveProcess(code, process, errors, *before)
            live.watcher = threading.Thread(target=self._watch, args=(live,), name=f"live-run-{code}", daemon=True)
            self._current = live
            live.watcher.start()

    def estop(self) -> str | None:
        """Stop the live run at once: create runs/estop (which stops any live run of the study, also one started
        from the command line) and send SIGTERM to this console's `trials run`. Returns the run it stopped, if any."""
        path = self.folder.path(LIVE_ESTOP)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.touch()
        with self._lock:
            live = self._current
            if live is None or not live.running:
                return None
            live.stopped = True
            live.process.send_signal(signal.SIGTERM)  # a no-op once the process has exited
            return live.code

    def elsewhere(self) -> str | None:
        """The run runs/live.json says is under way while a `trials run` holds the study (one started elsewhere), if any."""
        written = read_state(self.folder)
        if written is None or written.get("state") not in GOING or not lock_state(self.folder).held:
            return None
        return written.get("run_code")

    def state(self, code: str) -> dict[str, Any]:
        """Run `code`'s live state: runs/live.json's content when it is about this run (run_code, state, detail,
        since_utc), `starting` before the worker has written it, and `running`: whether this console's live run
        of it is still going."""
        live = self._current
        written = read_state(self.folder)
        about = written is not None and written.get("run_code") == code
        shown: dict[str, Any] = {}
        if live is not None and live.code == code:
            if about and written != live.state_before:
                shown = dict(written or {})
                if live.ended is not None and shown.get("state") in (WAITING, DRIVING):  # its process is gone: never live
                    shown.update(state=ABORTED, detail=live.ended[1] or "`trials run --robot` ended while the run was under way")
            elif live.ended is not None:  # it ended before its worker said anything: the console's own reason
                shown = {"state": ABORTED, "detail": live.ended[1]} if not live.ended[0] else {}
            else:
                shown = {"state": STARTING, "detail": "loading the controllers and reaching the robot"}
        elif about:
            shown = dict(written or {})
            if shown.get("state") in (WAITING, DRIVING) and not lock_state(self.folder).held:
                shown.update(state=ABORTED, detail="the `trials run` that drove it is no longer running")
        return {**shown, "run_code": code, "running": live is not None and live.code == code and live.running}

    def close(self) -> str | None:
        """Stop a live run still going (as E-STOP does) and wait until its ending is recorded; the run it stopped, if any."""
        code = self.estop()
        live = self._current
        if code is None or live is None:
            return None
        try:
            live.process.wait(STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            live.process.kill()
        live.watcher.join(STOP_WAIT_S)
        return code

    def _watch(self, live: LiveProcess) -> None:
        """Wait for the live run's process, then record how the run ended."""
        returncode = live.process.wait()
        finished, reason = self._ending(live, returncode)
        try:
            self._on_end(live.code, finished, reason)
        finally:
            with self._lock:
                live.ended = (finished, reason)
            live.errors.close()

    def _ending(self, live: LiveProcess, returncode: int) -> tuple[bool, str]:
        """Whether the run finished (its outcome row is there), else why not, from the best witness: the failure
        `trials run` recorded, the aborted state its worker wrote, its error line, the E-STOP, its exit code."""
        if any(o.run_code == live.code for o in read_outcomes(self.folder.path(OUTCOMES))):
            return True, ""
        failure = _failure(self.folder, live.code)
        if failure and failure != live.failure_before:
            return False, failure
        written = read_state(self.folder)
        if written is not None and written != live.state_before and written.get("run_code") == live.code and written.get("state") == ABORTED:
            return False, written.get("detail", "") or ABORTED
        live.errors.seek(0)
        lines = [line.strip() for line in live.errors.read().decode("utf-8", "replace").splitlines() if line.strip()]
        error = next((line.removeprefix("error: ") for line in reversed(lines) if line.startswith("error: ")), "")
        if error:
            return False, error
        if live.stopped:
            return False, "E-STOP from the console before the run started"
        return False, f"`trials run --robot` ended (exit code {returncode}) without an outcome"


def _failure(folder: StudyFolder, code: str) -> str:
    """The first line of runs/<code>.failed.txt, why the run's last attempt failed ("" when there is none)."""
    try:
        return folder.run_failure(code).read_text(encoding="utf-8").splitlines()[0].strip()
    except (OSError, IndexError, UnicodeDecodeError):
        return ""
