"""A rig for live runs through real middleware: the software robot (`trials robot-sim`) and a witness of the velocity
commands as their own processes, `trials run --robot` as another, and waits on the run's public state file.

Every process is killed when the rig is left. Waits poll with generous deadlines: the machine may be loaded.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from trials.study import LIVE_STATE

#: The `trials` command as this interpreter runs it.
TRIALS = (sys.executable, "-m", "trials.cli")
#: Seconds a live run may take from `trials run` starting to its ending on a loaded machine.
RUN_DEADLINE_S = 240.0


@dataclass
class Rig:
    """The processes of a rig and where they write."""

    uri: str
    study: Path
    env: dict[str, str]
    commands: Path
    heard: Path
    processes: list[subprocess.Popen] = field(default_factory=list)

    def start(self, args: Sequence[str], log: str) -> subprocess.Popen:
        with open(self.study.parent / log, "wb") as out:
            process = subprocess.Popen(list(args), env=self.env, stdout=out, stderr=subprocess.STDOUT)
        self.processes.append(process)
        return process

    def trials_run(self, *extra: str) -> subprocess.Popen:
        """`trials run --robot URI --study DIR ...` as a process (its output in run.log beside the study)."""
        return self.start([*TRIALS, "run", "--robot", self.uri, "--study", str(self.study), *extra], "run.log")

    def output(self, name: str = "run.log") -> str:
        return (self.study.parent / name).read_text(encoding="utf-8", errors="replace")

    def state(self) -> dict[str, str]:
        try:
            return json.loads((self.study / LIVE_STATE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}

    def wait_state(self, *states: str, deadline_s: float = RUN_DEADLINE_S) -> dict[str, str]:
        """The state file once its state is one of `states`."""
        deadline = time.monotonic() + deadline_s
        while (state := self.state()).get("state") not in states:
            assert time.monotonic() < deadline, f"no state {states} within {deadline_s} s: {state}; {self.output()[-2000:]}"
            time.sleep(0.1)
        return state

    def last_heard(self) -> tuple[float, float]:
        """The last velocity command the witness heard."""
        lines = self.heard.read_text(encoding="utf-8").splitlines()
        assert lines, "the witness heard no velocity command"
        _, linear, angular = lines[-1].split(",")
        return float(linear), float(angular)

    def moving_commands(self) -> int:
        return sum(1 for line in self.heard.read_text(encoding="utf-8").splitlines() if float(line.split(",")[1]) != 0.0)


def wait_for(path: Path, what: str, processes: Sequence[subprocess.Popen], deadline_s: float = 120.0) -> None:
    deadline = time.monotonic() + deadline_s
    while not path.exists():
        dead = [p for p in processes if p.poll() is not None]
        assert not dead, f"{what}: a process exited with {dead[0].returncode} before it was ready"
        assert time.monotonic() < deadline, f"{what} was not ready within {deadline_s} s"
        time.sleep(0.1)


@contextmanager
def live_rig(uri: str, study: Path, env: dict[str, str], robot: Sequence[str] = ()) -> Iterator[Rig]:
    """The software robot on `uri` laying out `study`'s scenes (with `robot`'s extra options), and the witness."""
    rig = Rig(uri, study, {**env, "PYTHONUNBUFFERED": "1"}, study.parent / "commands.csv", study.parent / "heard.csv")
    try:
        rig.start([sys.executable, "-m", "tests.support.witness", uri, "/cmd_vel", str(rig.heard)], "witness.log")
        rig.start([*TRIALS, "robot-sim", "--ros", uri, "--study", str(study), "--scan-rate", "20",
                   "--commands", str(rig.commands), *robot], "robot.log")
        wait_for(rig.heard.with_name(rig.heard.name + ".ready"), "the witness", rig.processes)
        yield rig
    finally:
        for process in reversed(rig.processes):
            if process.poll() is None:
                process.kill()
            process.wait()


def repository_env() -> dict[str, str]:
    """The environment of the rig's processes: this one, with the repository importable (tests.support)."""
    root = str(Path(__file__).resolve().parents[2])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (root, os.environ.get("PYTHONPATH"))))}
