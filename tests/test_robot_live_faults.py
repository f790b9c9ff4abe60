"""A robot that sends bad data is never driven on it: over a real ROS 1 master (and DDS for the cases that ask the
middleware who publishes), each fault the software robot stages, a second node publishing scans, and a second `trials
run` on the same robot stop the robot with a reason naming the cause, and the run is kept aside, never recorded as data."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

from tests.support.live_rig import TRIALS, assert_stopped_and_kept, design, first_code, live_rig, ros1_env
from trials.outcomes import read_outcomes
from trials.study import OUTCOMES

pytestmark = pytest.mark.slow

#: Each staged fault (from 3 s after the run's announcement) and what the run's reason must say.
FAULTS = {
    "clock-back@3": "the robot's clock stepped back",
    "clock-ahead@3": "the robot's clock jumped",
    "scan-future@3": "the robot's clock jumped",
    "odometry-jump@3": "odometry on /odom jumped 50.",
    "frame-change@3": "the scan's frame changed from laser to laser_2",
    "tf-loop@3": "tf loop: base_link -> odom closes a loop",
    "scans-huge@3": "a scan of 100",
    "scans-blank@3": "the last 768 NaN of 768 ranges",  # the fitted lidar's 768 beams
    "scans-late@3": "the robot's clock stepped back",  # the laser's stamps turn 1 s late
    "odometry-stale@3": "stale odometry",
}


@pytest.mark.parametrize("fault", FAULTS)
def test_a_robot_sending_bad_data_is_stopped_with_the_cause(tmp_path, master, fault):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), ("--fault", fault)) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, FAULTS[fault])


def test_a_second_node_publishing_scans_stops_the_run(tmp_path, middleware):
    uri, env = middleware
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(uri, study.root, env) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        rig.start([TRIALS[0], "-m", "tests.support.blank_scanner", uri, "/scan"], "scanner.log")
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, "2 nodes publish on /scan")


def test_a_second_trials_run_on_the_same_robot_is_refused_and_never_disturbs_the_first(tmp_path, middleware):
    uri, env = middleware
    first = design(tmp_path / "first" / "study", uri)
    second = design(tmp_path / "second" / "study", uri)
    with live_rig(uri, first.root, env) as rig:
        run = rig.trials_run("--only", first_code(first))
        rig.wait_state("driving")
        refused = subprocess.run([*TRIALS, "run", "--robot", uri, "--study", str(second.root), "--only", first_code(second)],
                                 env=env, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
        assert refused.returncode == 2, refused.stdout + refused.stderr
        assert "did not start: another node commands the robot on /cmd_vel: " in refused.stderr, refused.stderr
        assert "navtrials_" in refused.stderr.split("/cmd_vel: ")[1], refused.stderr  # the first session's nodes, by name
        assert len(refused.stderr.strip().splitlines()) == 1, refused.stderr
        assert run.wait(timeout=300) == 0, rig.output()  # the first session drove its run to its end
        (row,) = read_outcomes(first.path(OUTCOMES))
        assert row.status in ("goal", "collision"), row
        assert read_outcomes(second.path(OUTCOMES)) == [] and not (second.root / "runs" / "aborted").exists()
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0)


def test_a_killed_session_does_not_keep_the_next_one_from_driving(tmp_path, master):
    """A ROS 1 master keeps a killed node's registrations; the next session asks each listed node whether it still runs."""
    uri, _ = master
    study = design(tmp_path / "study", uri)
    first, second = (row["run_code"] for row in study.read_plan()[:2])
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        run = rig.trials_run("--only", first)
        rig.wait_state("driving")
        worker = rig.worker(run)
        for pid in (run.pid, worker):
            os.kill(pid, signal.SIGKILL)
        run.wait()
        again = rig.trials_run("--only", second)
        assert again.wait(timeout=300) == 0, rig.output()
    assert {row.run_code for row in read_outcomes(study.path(OUTCOMES))} == {second}
