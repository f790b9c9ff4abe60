"""A real ROS 1 master (Debian's `rosmaster`) on a free loopback port, for tests of the ROS 1 transport.

Use the fixture `ros1_master` (the master's `RobotUri`) by listing this module in a `pytest_plugins`,
or `master_process` where a test must stop the master itself. rospy allows one node per process, so
the nodes of a test run as subprocesses (see `tests.support.ros1_echo`).
"""

from __future__ import annotations

import shutil
import socket
import subprocess
import time
import xmlrpc.client
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.support.ros1_echo import environment
from tests.support.system_packages import need
from trials.robot.ros1 import DIST_PACKAGES, INSTALL
from trials.robot.transport import ROS1, RobotUri

#: Seconds a master has to start answering (a loaded 2-core machine starts Python slowly).
START_TIMEOUT_S = 60.0


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _answers(uri: RobotUri) -> bool:
    try:
        with socket.create_connection((uri.host, uri.port), timeout=1.0), xmlrpc.client.ServerProxy(uri.master_uri) as master:
            return master.getPid("/tests")[0] == 1
    except (OSError, xmlrpc.client.Error):
        return False


@contextmanager
def master_process(ros_home: Path) -> Iterator[tuple[RobotUri, subprocess.Popen]]:
    """A running `rosmaster --core` on 127.0.0.1 only, logging under `ros_home`; killed on exit.

    A port another process takes between the pick and the bind makes the master exit; that is retried.
    """
    rosmaster = shutil.which("rosmaster")
    need(rosmaster is not None and Path(DIST_PACKAGES, "rospy").is_dir(), "ROS 1 (rosmaster and rospy from Debian 12)", INSTALL)
    assert rosmaster is not None
    ros_home.mkdir(parents=True, exist_ok=True)
    for _ in range(3):
        uri = RobotUri(ROS1, host="127.0.0.1", port=_free_port())
        env = environment(ros_home) | {"ROS_IP": uri.host, "ROS_MASTER_URI": uri.master_uri}
        with open(ros_home / f"rosmaster-{uri.port}.out", "wb") as out:
            master = subprocess.Popen([rosmaster, "--core", "-p", str(uri.port)], env=env, stdout=out, stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + START_TIMEOUT_S
            while master.poll() is None and not _answers(uri):
                assert time.monotonic() < deadline, f"rosmaster on port {uri.port} did not answer within {START_TIMEOUT_S} s"
                time.sleep(0.05)
            if master.poll() is None:
                yield uri, master
                return
        finally:
            master.kill()
            master.wait()
    pytest.fail(f"rosmaster did not start; see {ros_home}/rosmaster-*.out")


@pytest.fixture
def ros1_master(tmp_path: Path) -> Iterator[RobotUri]:
    """The URI of a fresh ROS 1 master on a free 127.0.0.1 port, its ROS_HOME in tmp_path."""
    with master_process(tmp_path / "ros_master") as (uri, _):
        yield uri


@pytest.fixture
def master(tmp_path: Path) -> Iterator[tuple[RobotUri, subprocess.Popen]]:
    """A fresh ROS 1 master for a live-run rig, and its process (to kill it), ROS_HOME in tmp_path/ros."""
    with master_process(tmp_path / "ros") as running:
        yield running
