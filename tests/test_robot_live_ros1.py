"""Live runs over a real ROS 1 master: `trials run --robot` drives the software robot (`trials robot-sim`), each in its own
process, through real TCPROS. A blinded run reaches its goal with nobody holding the key, its log holds the robot's own
scans and tf and no controller output, and its sealed record the plans; every way a run can go wrong (the robot killed,
the master stopped, scans late, odometry stale, SIGTERM, the e-stop topic) ends with a zero velocity as the last command
a witness heard, the run aborted with its reason, and its log kept."""

from __future__ import annotations

import signal
import subprocess
import time

import pytest

from tests.support.live_rig import TRIALS, assert_stopped_and_kept, check_blinded_run, design, first_code, live_rig, ros1_env, set_robot_keys

pytestmark = pytest.mark.slow


def test_a_blinded_live_run_drives_to_its_end_and_names_no_controller(tmp_path, master):
    uri, _ = master
    check_blinded_run(design(tmp_path / "study", uri, "--ab"), str(uri), ros1_env(tmp_path))


#: What stops a run midway, as done to the rig (the robot is its second process), `trials run` and the master, and the
#: reason the run must give. The e-stop node holds the topic at true, as a robot's button does.
INTERRUPTIONS = {
    "robot killed": (lambda rig, run, master: rig.processes[1].kill(), "stale scans"),
    "master stopped": (lambda rig, run, master: master.kill(), "master"),
    "SIGTERM": (lambda rig, run, master: run.send_signal(signal.SIGTERM), "SIGTERM"),
    "e-stop topic": (lambda rig, run, master: rig.start([TRIALS[0], "-m", "tests.support.press_estop", rig.uri, "/e_stop"], "estop.log"),
                     "e-stop on /e_stop"),
}


@pytest.mark.parametrize("interruption", INTERRUPTIONS)
def test_a_run_stopped_midway_stops_the_robot_and_keeps_its_log(tmp_path, master, interruption):
    uri, process = master
    interrupt, reason = INTERRUPTIONS[interruption]
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        interrupt(rig, run, process)
        assert run.wait(timeout=300) != 0, rig.output()  # the run stays pending
        assert_stopped_and_kept(rig, study, code, reason)


def test_an_exception_in_the_loop_stops_the_robot(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        failing = subprocess.run([TRIALS[0], "-m", "tests.support.failing_drive", str(uri), code], env=rig.env, capture_output=True,
                                 text=True, timeout=300)
        assert "raised: [Errno 28] No space left on device" in failing.stdout, failing.stderr[-2000:]
        time.sleep(0.5)
        assert rig.moving_commands() > 0
        assert rig.last_heard() == (0.0, 0.0)


def test_a_run_without_sensors_never_starts(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    set_robot_keys(study.root, sensor_wait="3.0")
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        rig.processes[1].kill()  # no robot: no scan, odometry or transform ever comes
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        state = rig.wait_state("aborted")
        assert state["detail"] == "no start after 3 s: still waiting for a scan on /scan, odometry on /odom", state
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() == 0  # told to stand still, never to move
    assert "did not start: no start after 3 s" in study.run_failure(code).read_text(encoding="utf-8")
    assert not study.run_log(code).exists() and not (study.root / "runs" / "aborted").exists()
