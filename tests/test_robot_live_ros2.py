"""Live runs over ROS 2 (DDS on the loopback, each node its own process): a blinded run reaches its goal naming no
controller, and a killed robot, late scans and a stale odometry each end with a zero velocity as the last command a
witness heard, the run aborted with its reason, and its log kept."""

from __future__ import annotations

import os
import random
import time

import pytest

from tests.support.live_rig import assert_stopped_and_kept, check_blinded_run, design, first_code, live_rig, repository_env
from trials.robot.ros2 import LOOPBACK_ENV

pytestmark = pytest.mark.slow


@pytest.fixture
def uri() -> str:
    """A ROS 2 domain of this test alone (parallel test processes must not hear each other)."""
    return f"ros2://{random.Random(f'{os.getpid()}-{time.time_ns()}').randrange(1, 200)}"


def env() -> dict[str, str]:
    return {**repository_env(), LOOPBACK_ENV: "1"}


def test_a_blinded_live_run_drives_to_its_end_and_names_no_controller(tmp_path, uri):
    check_blinded_run(design(tmp_path / "study", uri, "--ab"), uri, env())


@pytest.mark.parametrize("fault, reason", [("scans-late@3", "the robot's clock stepped back"), ("odometry-stale@3", "stale odometry")])
def test_late_scans_or_stale_odometry_stop_the_robot(tmp_path, uri, fault, reason):
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(uri, study.root, env(), ("--fault", fault)) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, reason)


def test_a_killed_robot_stops_the_run(tmp_path, uri):
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(uri, study.root, env()) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(2.0)
        rig.processes[1].kill()
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, "stale scans")
