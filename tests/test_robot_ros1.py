"""The ROS 1 transport against a real rosmaster and real TCPROS, each node in its own process
(rospy allows one per process): values arrive exactly as published, a stopped master is noticed,
an unreachable one fails fast, and rospy keeps quiet on the terminal."""

from __future__ import annotations

import json
import os
import queue
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robot_logs.frames import Pose2D
from tests.support.ros1_echo import PATIENCE_S, SAMPLES, environment
from trials.robot import ros1
from trials.robot.transport import FLAG, ODOMETRY, SCAN, TEXT, TF, TF_STATIC, TWIST, TWIST_STAMPED, LinkError, RobotUri

REPO = Path(__file__).resolve().parents[1]


class Node:
    """A `tests.support.ros1_echo` process; its stdout lines (JSON) are read on a thread, its stderr kept in a file."""

    def __init__(self, mode: str, uri: RobotUri | str, env: dict[str, str], folder: Path) -> None:
        self.stderr = folder / f"{mode}.stderr"
        with open(self.stderr, "w") as err:
            self.process = subprocess.Popen([sys.executable, "-m", "tests.support.ros1_echo", mode, str(uri)], cwd=REPO, env=env,
                                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err, text=True)
        self.lines: queue.Queue[str | None] = queue.Queue()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line)
        self.lines.put(None)

    def next(self, timeout: float = PATIENCE_S) -> dict[str, Any]:
        """The next JSON line the node prints (every line it prints must be one)."""
        line = self.lines.get(timeout=timeout)
        assert line is not None, f"the {self.process.args[3]} node exited early: {self.stderr.read_text()}"
        return json.loads(line)

    def stop(self) -> None:
        """Close its stdin, which tells a talker to stop."""
        assert self.process.stdin is not None
        self.process.stdin.close()

    def finish(self) -> str:
        """Stop it, wait for it to exit cleanly with nothing more on stdout; its stderr."""
        self.stop()
        assert self.process.wait(PATIENCE_S) == 0, self.stderr.read_text()
        assert self.lines.get(timeout=PATIENCE_S) is None, "unexpected output after the last line"
        return self.stderr.read_text()

    def kill(self) -> None:
        """Kill it if still running, and close its pipes."""
        self.process.kill()
        self.process.wait()
        self.reader.join(PATIENCE_S)
        for pipe in (self.process.stdin, self.process.stdout):
            if pipe is not None:
                pipe.close()


@pytest.fixture
def nodes(tmp_path: Path) -> Iterator[list[Node]]:
    """Driver processes a test starts, killed at teardown if still running."""
    started: list[Node] = []
    yield started
    for node in started:
        node.kill()


def start(nodes: list[Node], mode: str, uri: RobotUri | str, env: dict[str, str], folder: Path) -> Node:
    nodes.append(Node(mode, uri, env, folder))
    return nodes[-1]


def f32(value: float) -> float:
    return float(np.float32(value))


def assert_pose(got: dict[str, float], want: Pose2D) -> None:
    """Positions exactly (float64 on the wire), heading through the quaternion to 1e-9 rad."""
    assert (got["x"], got["y"]) == (want.x, want.y)
    assert abs(got["yaw"] - want.yaw) < 1e-9


def assert_transforms(got: list[dict[str, Any]], kind: str) -> None:
    want = SAMPLES[kind][1]
    assert [(t["stamp_ns"], t["parent"], t["child"], t["static"]) for t in got] == [(t.stamp_ns, t.parent, t.child, kind == TF_STATIC) for t in want]
    for one, expected in zip(got, want):
        assert_pose(one["pose"], expected.pose)


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_every_kind_arrives_as_published(ros1_master: RobotUri, nodes: list[Node], tmp_path: Path) -> None:
    """Latched values (published once, before the listener existed) and streamed ones arrive exactly; a
    malformed scan makes lost() say why; nodes listen on loopback only; rospy writes nothing on the
    terminal, only into ROS_HOME/log."""
    env = environment(tmp_path / "ros_home")
    talker = start(nodes, "talk", ros1_master, env, tmp_path)
    assert talker.next()["ready"].startswith("http://127.0.0.1:")
    listener = start(nodes, "listen", ros1_master, env, tmp_path)
    assert listener.next()["ready"].startswith("http://127.0.0.1:")
    heard = listener.next()
    talker.stop()  # both close at once
    assert listener.finish() == ""
    assert talker.finish() == ""
    got = heard["received"]
    assert sorted(got) == sorted(SAMPLES), f"missing: {set(SAMPLES) - set(got)}"
    assert heard["lost"] == "scan on /bad_scan: angle_increment is 0.0, expected a positive number of radians"

    scan, want = got[SCAN], SAMPLES[SCAN][1]
    assert (scan["stamp_ns"], scan["frame_id"]) == (want.stamp_ns, want.frame_id)
    assert [scan[k] for k in ("angle_min", "angle_increment", "range_min", "range_max")] == [
        f32(want.angle_min), f32(want.angle_increment), f32(want.range_min), f32(want.range_max)]
    np.testing.assert_array_equal(np.array(scan["ranges"], dtype=float), want.ranges.astype(np.float32).astype(float))

    odometry, want = got[ODOMETRY], SAMPLES[ODOMETRY][1]
    assert [odometry[k] for k in ("stamp_ns", "frame_id", "child_frame_id", "linear", "angular")] == [
        want.stamp_ns, want.frame_id, want.child_frame_id, want.linear, want.angular]
    assert_pose(odometry["pose"], want.pose)

    assert_transforms(got[TF], TF)
    assert_transforms(got[TF_STATIC], TF_STATIC)
    assert got[TWIST] == {"linear": 0.5, "angular": -0.25, "stamp_ns": 0, "frame_id": ""}
    assert got[TWIST_STAMPED] == {"linear": -0.125, "angular": 1.75, "stamp_ns": 1_700_000_127_000_000_042, "frame_id": "base_footprint"}
    assert got[FLAG] is True
    assert got[TEXT] == SAMPLES[TEXT][1]

    log_file = Path(heard["log_file"])
    assert log_file.parent == tmp_path / "ros_home" / "log"
    assert "init_node" in log_file.read_text()


@pytest.mark.slow  # over 1.5 s: left out of the quick loop
def test_a_stopped_master_is_lost_within_seconds(ros1_master: RobotUri, nodes: list[Node], tmp_path: Path) -> None:
    """TCPROS links outlive the master, so lost() polls it; a second node in the process is refused; the
    log goes to a temporary folder when ROS_LOG_DIR cannot be written; close() after the loss is quick."""
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    env = environment(tmp_path / "ros_home") | {"ROS_LOG_DIR": str(blocker / "log")}
    watcher = start(nodes, "watch", ros1_master, env, tmp_path)
    ready = watcher.next()
    assert ready["lost"] is None
    assert ready["second"] == "this process already opened the ROS 1 node 'ros1_echo_watch': rospy allows one node per process"
    with xmlrpc.client.ServerProxy(ros1_master.master_uri) as master:
        os.kill(master.getPid("/test")[2], signal.SIGKILL)
    stopped = time.monotonic()
    lost = watcher.next()
    noticed = time.monotonic() - stopped
    assert lost["lost"].startswith(f"the ROS 1 master at {ros1_master} stopped answering: ")
    assert noticed < 2.5, f"noticed {noticed:.2f} s after the master stopped"
    assert watcher.next()["close_s"] < ros1.CLOSE_TIMEOUT_S
    assert watcher.finish() == ""
    log_file = Path(lost["log_file"])
    assert log_file.parent.name.startswith("trials-ros1-log-") and log_file.parent.parent == Path(tempfile.gettempdir())
    assert "init_node" in log_file.read_text()
    for path in log_file.parent.iterdir():
        path.unlink()
    log_file.parent.rmdir()


@pytest.mark.parametrize(("listening", "reason"), [pytest.param(False, "Connection refused", id="refused"),
                                                   pytest.param(True, "timed out", id="silent", marks=pytest.mark.slow)])
def test_an_unreachable_master_fails_fast(listening: bool, reason: str, nodes: list[Node], tmp_path: Path) -> None:
    """Nothing on the port: refused at once; a port that accepts but never answers: given up on after
    CHECK_TIMEOUT_S, not waited on forever as rospy's init_node would."""
    with socket.socket() as port:
        port.bind(("127.0.0.1", 0))
        if listening:
            port.listen()
        uri = f"ros1://127.0.0.1:{port.getsockname()[1]}"
        result = start(nodes, "open", uri, environment(tmp_path / "ros_home"), tmp_path).next()
    assert result["error"] == f"cannot reach the ROS 1 master at {uri}: {reason}"
    assert result["seconds"] < 5.0, result


def test_missing_rospy_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rospy", None)
    monkeypatch.setattr(ros1, "DIST_PACKAGES", "/nonexistent/dist-packages")
    with pytest.raises(LinkError, match=r"install Debian 12's with `sudo apt-get install python3-rospy python3-rosmaster .*python3-std-msgs`$"):
        ros1.import_rospy()
