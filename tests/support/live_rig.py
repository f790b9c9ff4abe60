"""A rig for live runs through real middleware: the software robot (`trials robot-sim`) and a witness of the velocity
commands as their own processes, `trials run --robot` as another, and waits on the run's public state file.

Every process is killed when the rig is left. Waits poll with generous deadlines: the machine may be loaded.
"""

from __future__ import annotations

import json
import os
import random
import re
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from robot_logs import run_log as fmt
from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.physical import PEDESTRIAN_RADIUS_M
from tests.support.example_plugin import install_example
from trials.outcomes import read_outcomes
from trials.robot.ros2 import LOOPBACK_ENV
from trials.sealed_runs import read_sealed_run
from trials.sim.robot import RobotLimits, footprint_gaps
from trials.study import LIVE_STATE, OUTCOMES, StudyFolder

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
    contacts: Path
    truth: Path
    processes: list[subprocess.Popen] = field(default_factory=list)

    def start(self, args: Sequence[str], log: str) -> subprocess.Popen:
        with open(self.study.parent / log, "wb") as out:
            process = subprocess.Popen(list(args), env=self.env, stdout=out, stderr=subprocess.STDOUT)
        self.processes.append(process)
        return process

    def trials_run(self, *extra: str, operator: bool = False) -> subprocess.Popen:
        """`trials run --robot URI --study DIR ...` as a process (its output in run.log beside the study); with
        `operator`, its standard input a pipe the test answers on, else closed."""
        with open(self.study.parent / "run.log", "wb") as out:
            process = subprocess.Popen([*TRIALS, "run", "--robot", self.uri, "--study", str(self.study), *extra], env=self.env,
                                       stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.PIPE if operator else subprocess.DEVNULL)
        self.processes.append(process)
        return process

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

    def true_gaps(self, start_ns: int, end_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """From the software robot's ground truth (`--truth`), between two stamps: the (K,) stamps and the (K,) gaps from
        the robot's footprint to the nearest walker's 0.25 m disc, as a run measures them."""
        stamps, gaps = [], []
        for line in self.truth.read_text(encoding="utf-8").splitlines():
            values = [float(v) for v in line.split(",")]
            if start_ns <= int(values[0]) <= end_ns and len(values) > 4:
                stamps.append(int(values[0]))
                gaps.append(footprint_gaps(np.array(values[1:4]), np.array(values[4:]).reshape(-1, 2), RobotLimits(), PEDESTRIAN_RADIUS_M).min())
        return np.array(stamps), np.array(gaps)

    def wall_contacts(self) -> list[str]:
        """Each time the software robot's bumper touched a wall (`wall_ns,x,y`)."""
        return self.contacts.read_text(encoding="utf-8").splitlines() if self.contacts.exists() else []

    def worker(self, run: subprocess.Popen) -> int:
        """The pid of the worker process `trials run` spawned to drive the robot."""
        for status in Path("/proc").glob("[0-9]*/status"):
            try:
                fields = dict(line.split(":\t", 1) for line in status.read_text().splitlines() if ":\t" in line)
                command = (status.parent / "cmdline").read_bytes()
            except OSError:
                continue
            if fields.get("PPid", "").strip() == str(run.pid) and b"spawn_main" in command and b"resource_tracker" not in command:
                return int(status.parent.name)
        raise AssertionError(f"no worker process of trials run (pid {run.pid})")


def wait_for(path: Path, what: str, processes: Sequence[subprocess.Popen], deadline_s: float = 120.0) -> None:
    deadline = time.monotonic() + deadline_s
    while not path.exists():
        dead = [p for p in processes if p.poll() is not None]
        assert not dead, f"{what}: a process exited with {dead[0].returncode} before it was ready"
        assert time.monotonic() < deadline, f"{what} was not ready within {deadline_s} s"
        time.sleep(0.1)


@contextmanager
def live_rig(uri: str, study: Path, env: dict[str, str], robot: Sequence[str] = (), heard_type: str = "Twist") -> Iterator[Rig]:
    """The software robot on `uri` laying out `study`'s scenes (with `robot`'s extra options), and the witness of the
    velocity commands of type `heard_type`."""
    rig = Rig(uri, study, {**env, "PYTHONUNBUFFERED": "1"}, study.parent / "commands.csv", study.parent / "heard.csv",
              study.parent / "contacts.csv", study.parent / "truth.csv")
    try:
        rig.start([sys.executable, "-m", "tests.support.witness", uri, "/cmd_vel", str(rig.heard), heard_type], "witness.log")
        rig.start([*TRIALS, "robot-sim", "--ros", uri, "--study", str(study), "--scan-rate", "20",
                   "--commands", str(rig.commands), "--contacts", str(rig.contacts), "--truth", str(rig.truth), *robot],
                  "robot.log")
        wait_for(rig.heard.with_name(rig.heard.name + ".ready"), "the witness", rig.processes)
        yield rig
    finally:
        for process in reversed(rig.processes):
            if process.poll() is None:
                process.kill()
            process.wait()


def ros2_uri() -> str:
    """A ROS 2 domain of its own for one test (tests run side by side)."""
    return f"ros2://{random.Random(f'{os.getpid()}-{time.time_ns()}').randrange(1, 200)}"


@pytest.fixture(params=["ros1", "ros2"])
def middleware(request, tmp_path) -> tuple[str, dict[str, str]]:
    """A robot URI and the environment of its rig's processes, over each middleware: a real ROS 1 master, and DDS."""
    return robot_over(request.param, request, tmp_path)


def robot_over(kind: str, request: pytest.FixtureRequest, tmp_path: Path) -> tuple[str, dict[str, str]]:
    """A robot URI over `kind` ("ros1": a real master of the test's own, "ros2": a DDS domain) and its rig's environment."""
    if kind == "ros2":
        return ros2_uri(), {**repository_env(), LOOPBACK_ENV: "1"}
    uri, _ = request.getfixturevalue("master")
    return str(uri), ros1_env(tmp_path)


def repository_env() -> dict[str, str]:
    """The environment of the rig's processes: this one, with the repository importable (tests.support)."""
    root = str(Path(__file__).resolve().parents[2])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, (root, os.environ.get("PYTHONPATH"))))}


def ros1_env(tmp_path: Path) -> dict[str, str]:
    """The environment of a ROS 1 rig's processes: the repository importable, ROS_HOME where the `master` fixture has it."""
    from tests.support.ros1_echo import environment

    return {**repository_env(), **environment(tmp_path / "ros")}


def design(folder: Path, uri: object, *flags: str, frame: str = "odom") -> StudyFolder:
    """`trials design [flags] --robot URI --seed 5` in `folder`, its rows staged in `frame` (the software robot's odometry
    frame, whose origin is where it starts, unless a test measures a start mark)."""
    subprocess.run([*TRIALS, "design", *flags, "--robot", str(uri), "--seed", "5", "--study", str(folder)], check=True,
                   capture_output=True, env=repository_env())
    set_robot_keys(folder, goal_frame=f'"{frame}"')
    return StudyFolder(folder)


def set_robot_keys(study: Path, **keys: str) -> None:
    """Set keys of study.toml's [robot] table (values as TOML text), replacing the lines `trials design --robot` wrote."""
    spec = study / "study.toml"
    head, table, tail = re.split(r"(\[robot\]\n(?:.*\n)*?)(?=\n\[|\Z)", spec.read_text(encoding="utf-8"), maxsplit=1)
    for key, value in keys.items():
        line = f"{key} = {value}\n"
        table, found = re.subn(rf"^{key} = (?:\[\n(?:    .*\n)*\]|.*)\n", line, table, flags=re.M)  # tomli_w spreads arrays over lines
        table = table if found else table + line
    spec.write_text(head + table + tail, encoding="utf-8")


def first_code(study: StudyFolder) -> str:
    return study.read_plan()[0]["run_code"]


def assert_stopped_and_kept(rig: Rig, study: StudyFolder, code: str, reason: str) -> None:
    """The run aborted for `reason`: zero was the last command heard, its log kept in runs/aborted/, why recorded, no row."""
    state = rig.wait_state("aborted")
    assert reason in state["detail"], state
    time.sleep(0.5)  # commands still in flight reach the witness
    assert rig.last_heard() == (0.0, 0.0)
    assert rig.moving_commands() > 0, "the robot never moved: the fault came before the run drove"
    kept = sorted((study.root / "runs" / "aborted").glob(f"{code}-*.mcap"))
    assert len(kept) == 1
    reader = FoxgloveReader(kept[0])
    assert fmt.ROBOT_STATE.name in reader.topics and fmt.SCAN.name in reader.topics
    events = [m.data for m in reader.messages([fmt.EVENTS.name])]
    assert events[-1]["event"] == "aborted" and reason in events[-1]["detail"]
    assert reason in study.run_failure(code).read_text(encoding="utf-8")
    assert code not in {row.run_code for row in read_outcomes(study.path(OUTCOMES), study.read_design().get("blinding") is not None)}


def check_blinded_run(study: StudyFolder, uri: str, env: dict[str, str]) -> None:
    """Drive the blinded study's first row live against the software robot: it drives to its end, a zero velocity was the
    last command, the log holds the robot's scans and tf at its real stamps and no controller output, the sealed record
    holds the plans, no public file names a controller, and the outcome and the report say the software robot drove."""
    code = first_code(study)
    with live_rig(uri, study.root, env) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0)
        assert rig.moving_commands() > 20
    (row,) = read_outcomes(study.path(OUTCOMES), True)
    # The run ends as the motion decides: at its goal, or (about 1 run in 18 over ROS 2, measured by
    # benchmarks/bench_live.py, more often on a loaded machine) touching a simulated walker.
    assert (row.run_code, row.perception) == (code, "software-robot") and row.status in ("goal", "collision"), row
    reached = row.status == "goal"
    assert (5.0 if reached else 1.0) < row.duration_s < 40.0 and row.path_length_m > (8.0 if reached else 1.0), row
    reader = FoxgloveReader(study.run_log(code))
    assert [m.data for m in reader.messages([fmt.EVENTS.name])][-1]["event"] == row.status  # the log ends as the row
    assert {fmt.SCAN.name, fmt.ROBOT_TF.name, fmt.ROBOT_STATE.name, fmt.PEDESTRIANS.name} <= set(reader.topics)
    assert not {t.name for t in fmt.CONTROLLER_TOPICS} & set(reader.topics)
    metadata = reader.metadata[fmt.RUN_METADATA]
    assert "controller" not in metadata and metadata["perception"] == "software-robot"  # the software robot said what it is
    # Real stamps: the log starts at the robot's clock (this machine's), moved back to its minute in a blinded study.
    start_ns = int(metadata["robot_start_stamp_ns"])
    assert start_ns % 60_000_000_000 == 0 and abs(start_ns * 1e-9 - time.time()) < 600
    robot_tf = [m.data for m in reader.messages([fmt.ROBOT_TF.name])]
    assert {(t["parent_frame_id"], t["child_frame_id"]) for t in robot_tf} >= {("odom", "base_link"), ("base_link", "laser")}
    sealed = read_sealed_run(study, code)
    # The controller that drove is the one the key allocates to the row's arm: the report's arms are the real drivers.
    arm = study.read_plan()[0]["Controller"]
    assert sealed["arm"] == arm and sealed["controller"] == study.read_sealed().arms[arm]
    assert len(sealed["topics"][fmt.PLAN.name]) >= row.duration_s / 0.8  # planned every 0.4 s, at least half of them
    for public in [*study.root.rglob("*.csv"), *study.root.rglob("*.json"), *study.root.rglob("*.mcap")]:
        if "sealed" not in public.parts:
            data = public.read_bytes()
            assert b"NaviGAN" not in data and b"Lattice" not in data, public
    # The report says the run was the software robot's, a rehearsal, not a real robot's.
    report = subprocess.run([*TRIALS, "report", "--study", str(study.root), "--quiet"], capture_output=True, text=True, env=env)
    assert report.returncode == 0, report.stderr
    markdown = (study.root / "report" / "report.md").read_text(encoding="utf-8")
    assert "How the finished runs were made: 1 driven live on the software robot (`trials robot-sim`, a rehearsal" in markdown
    assert json.loads((study.root / "report" / "report.json").read_text(encoding="utf-8"))["runs"]["made"]["software robot"] == 1


@pytest.fixture
def plugin_env(tmp_path, middleware) -> tuple[str, dict[str, str]]:
    """The robot's URI and its rig's environment with the example plug-in installed."""
    uri, env = middleware
    installed = install_example(tmp_path / "site")
    return uri, {**env, "PYTHONPATH": installed["PYTHONPATH"] + (":" + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")}
