"""Live runs over a real ROS 1 master: `trials run --robot` drives the software robot (`trials robot-sim`), each in its own
process, through real TCPROS. A blinded run reaches its goal with nobody holding the key, its log holds the robot's own
scans and tf and no controller output, and its sealed record the plans; every way a run can go wrong (the robot killed,
the master stopped, scans late, odometry stale, SIGTERM, the e-stop topic) ends with a zero velocity as the last command
a witness heard, the run aborted with its reason, and its log kept."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest

from robot_logs import run_log as fmt
from robot_logs.foxglove_log import FoxgloveReader
from tests.support.live_rig import TRIALS, Rig, live_rig, repository_env
from tests.support.ros1_echo import environment
from tests.support.ros1_master import master_process
from trials.outcomes import read_outcomes
from trials.robot.transport import RobotUri
from trials.sealed_runs import read_sealed_run
from trials.study import OUTCOMES, StudyFolder

pytestmark = pytest.mark.slow


def design(folder: Path, uri: RobotUri, *flags: str) -> StudyFolder:
    subprocess.run([*TRIALS, "design", *flags, "--robot", str(uri), "--seed", "5", "--study", str(folder)], check=True,
                   capture_output=True, env=repository_env())
    return StudyFolder(folder)


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


@pytest.fixture
def master(tmp_path: Path):
    with master_process(tmp_path / "ros") as running:
        yield running


def env_for(tmp_path: Path) -> dict[str, str]:
    return {**repository_env(), **environment(tmp_path / "ros")}


def test_a_blinded_live_run_reaches_its_goal_and_names_no_controller(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri, "--ab")
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0)
        assert rig.moving_commands() > 20
    (row,) = read_outcomes(study.path(OUTCOMES), True)
    assert (row.run_code, row.status, row.perception) == (code, "goal", "live")
    assert 5.0 < row.duration_s < 40.0 and row.path_length_m > 8.0
    reader = FoxgloveReader(study.run_log(code))
    assert {fmt.SCAN.name, fmt.ROBOT_TF.name, fmt.ROBOT_STATE.name, fmt.PEDESTRIANS.name} <= set(reader.topics)
    assert not {t.name for t in fmt.CONTROLLER_TOPICS} & set(reader.topics)
    metadata = reader.metadata[fmt.RUN_METADATA]
    assert "controller" not in metadata and metadata["perception"] == "live"
    # Real stamps: the log starts at the robot's clock (this machine's), moved back to its minute in a blinded study.
    start_ns = int(metadata["robot_start_stamp_ns"])
    assert start_ns % 60_000_000_000 == 0 and abs(start_ns * 1e-9 - time.time()) < 600
    robot_tf = [m.data for m in reader.messages([fmt.ROBOT_TF.name])]
    assert {(t["parent_frame_id"], t["child_frame_id"]) for t in robot_tf} >= {("odom", "base_link"), ("base_link", "laser")}
    sealed = read_sealed_run(study, code)
    assert sealed["controller"] in ("NaviGAN-R", "Lattice") and len(sealed["topics"][fmt.PLAN.name]) >= 10
    for public in [*study.root.rglob("*.csv"), *study.root.rglob("*.json"), *study.root.rglob("*.mcap")]:
        if "sealed" not in public.parts:
            data = public.read_bytes()
            assert b"NaviGAN" not in data and b"Lattice" not in data, public


@pytest.mark.parametrize("fault, reason", [("scans-late@3", "stale scans"), ("odometry-stale@3", "stale odometry")])
def test_late_scans_or_stale_odometry_stop_the_robot(tmp_path, master, fault, reason):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path), ("--fault", fault)) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, reason)


def test_a_killed_robot_stops_the_run(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        robot = rig.processes[1]
        robot.kill()
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, "stale scans")


def test_a_stopped_master_stops_the_run(tmp_path, master):
    uri, process = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        process.kill()
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, "master")


def test_sigterm_stops_the_robot_and_keeps_the_log(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        run.send_signal(signal.SIGTERM)
        run.wait(timeout=120)
        assert_stopped_and_kept(rig, study, code, "SIGTERM")


def test_the_estop_topic_stops_the_robot(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        press = subprocess.Popen([TRIALS[0], "-m", "tests.support.press_estop", str(uri), "/e_stop"], env=rig.env)
        try:
            assert run.wait(timeout=300) == 1, rig.output()
        finally:
            press.kill()
            press.wait()
        assert_stopped_and_kept(rig, study, code, "e-stop on /e_stop")



def test_an_exception_in_the_loop_stops_the_robot(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, env_for(tmp_path)) as rig:
        failing = subprocess.run([TRIALS[0], "-m", "tests.support.failing_drive", str(uri), code], env=rig.env, capture_output=True,
                                 text=True, timeout=300)
        assert "raised: [Errno 28] No space left on device" in failing.stdout, failing.stderr[-2000:]
        time.sleep(0.5)
        assert rig.moving_commands() > 0
        assert rig.last_heard() == (0.0, 0.0)
