"""The live loop's safety rules, against figures computed independently: the protective field's braking distance, which
beams count as returns, a stall and a deaf base, the sensors that count as missing, and a killed writer's log recovered."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from robot_logs.foxglove_log import FoxgloveReader, partial_path, recover
from robot_logs.frames import Pose2D
from robot_logs.records import Odometry, Scan, Transform
from trials.robot.live import Sensors, StallWatch
from trials.robot.protective_field import OPEN, ProtectiveField, returns_in, valid_returns
from trials.robot.settings import RobotSettings
from trials.sim.robot import RobotLimits, RobotState

HUSKY = RobotLimits()  # 0.99 x 0.67 m
FIELD = ProtectiveField(HUSKY, margin=0.1, reaction_time=0.2, deceleration=1.5)


def scan(ranges: list[float], range_max: float = 11.0) -> Scan:
    return Scan(stamp_ns=1, frame_id="laser", angle_min=-math.pi / 2, angle_increment=math.pi / 2, range_min=0.03,
                range_max=range_max, ranges=np.array(ranges, dtype=float))


def test_the_speed_allowed_stops_the_base_exactly_margin_short_of_a_return():
    for distance in (0.2, 0.4, 1.0, 3.0):
        v = FIELD.speed(distance)
        # travel during the reaction time, then braking at the deceleration: v t + v^2 / (2 a) = d - margin
        assert v * 0.2 + v * v / (2 * 1.5) == pytest.approx(distance - 0.1, abs=1e-12)
    assert FIELD.speed(0.1) == 0.0 and FIELD.speed(0.05) == 0.0 and FIELD.speed(math.inf) == math.inf
    # Under 5 cm/s is a stop: 0.05 * 0.2 + 0.05^2 / 3 = 0.01083 m of free way beyond the margin is needed to move at all.
    assert FIELD.speed(0.1 + 0.0108) == 0.0 and FIELD.speed(0.1 + 0.0109) == pytest.approx(0.05, abs=1e-3)
    assert FIELD.speed(1.0) == pytest.approx(-0.3 + math.sqrt(0.09 + 2.7), abs=1e-12)  # 1.3703 m/s


def test_returns_ahead_limit_forward_speed_and_returns_in_the_margin_stop_everything():
    ahead = FIELD.read(np.array([[0.495 + 1.0, 0.2]]))
    assert (ahead.forward, ahead.backward, ahead.inside) == (pytest.approx(FIELD.speed(1.0)), math.inf, False)
    assert ahead.limit(2.0, 0.5) == (pytest.approx(1.3703, abs=1e-4), 0.5) and ahead.limit(-0.4, 0.0) == (-0.4, 0.0)
    behind = FIELD.read(np.array([[-0.495 - 0.6, -0.3]]))
    assert behind.forward == math.inf and behind.backward == pytest.approx(FIELD.speed(0.6)) and behind.limit(-1.0, 0.0)[0] < -0.5
    close = FIELD.read(np.array([[0.55, 0.0], [3.0, 0.0]]))
    assert close.inside and close.limit(0.8, 1.0) == (0.0, 0.0) and close.blocks(0.3) and close.blocks(-0.3)
    # Beside the lane (wider than the footprint plus margin), or inside the footprint (the robot's own body): no limit.
    assert FIELD.read(np.array([[1.0, 0.335 + 0.11], [0.3, 0.1], [-0.2, -0.3]])) == OPEN
    wall = FIELD.read(np.array([[0.495 + 0.105, 0.0]]))  # just beyond the margin: held still, free to turn and back off
    assert not wall.inside and wall.forward == 0.0 and wall.limit(0.5, 0.3) == (0.0, 0.3) and wall.limit(-0.2, 0.0) == (-0.2, 0.0)
    assert wall.blocks(0.05) and not wall.blocks(-0.05) and not wall.blocks(0.0)


def test_only_finite_ranges_within_the_lasers_limits_are_returns():
    assert valid_returns(scan([math.nan, math.inf, -1.0, 0.01, 5.0, 20.0])).tolist() == [False, False, False, False, True, False]
    assert not valid_returns(scan([1.0, 2.0], range_max=0.0)).any()
    assert not valid_returns(scan([1.0, 2.0], range_max=math.nan)).any()
    # Beams at -90, 0 and +90 degrees from a laser 0.35 m ahead of the base, turned by 90 degrees.
    points = returns_in(scan([1.0, 2.0, math.nan]), Pose2D(0.35, 0.0, math.pi / 2))
    assert points == pytest.approx(np.array([[1.35, 0.0], [0.35, 2.0]]), abs=1e-12)


def ticks(watch: StallWatch, seconds: float, command: tuple[float, float], pose, start: float = 0.0) -> str | None:
    """Feed the watch 20 Hz ticks; `pose(t)` gives x, y, heading. Returns the first reason it gives."""
    for k in range(round(seconds * 20) + 1):
        t = start + k * 0.05
        reason = watch.add(t, RobotState(*pose(t)), command)
        if reason is not None:
            return f"{t:.2f}: {reason}"
    return None


def test_a_base_that_never_moves_does_not_respond_and_one_that_stops_moving_stalls():
    settings = RobotSettings(stall_time=2.0)
    assert ticks(StallWatch(settings), 2.0, (0.0, 0.0), lambda t: (0.0, 0.0, 0.0)) is None  # told to stand still
    deaf = ticks(StallWatch(settings), 3.0, (1.0, 0.0), lambda t: (0.0, 0.0, 0.0))
    assert deaf == ("2.00: the base does not respond to Twist on /cmd_vel: the commands of the last 2 s would have moved it "
                    "2.00 m and turned it 0.00 rad; odometry shows 0.00 m and 0.00 rad")
    assert ticks(StallWatch(settings), 10.0, (1.0, 0.5), lambda t: (t, 0.0, 0.5 * t)) is None  # obeys
    assert ticks(StallWatch(settings), 10.0, (1.0, 0.0), lambda t: (0.3 * t, 0.0, 0.0)) is None  # 30 % of it: slow, not stuck
    stuck = StallWatch(settings)
    assert ticks(stuck, 3.0, (1.0, 0.0), lambda t: (t, 0.0, 0.0)) is None
    later = ticks(stuck, 3.0, (1.0, 0.0), lambda t: (3.0, 0.0, 0.0), start=3.05)
    # The window reaches back to the last tick 2 s before: at 4.55 s it holds [2.50, 4.55], 0.50 m moved of 2.05 commanded.
    assert later == ("4.55: stall: the commands of the last 2 s would have moved it 2.05 m and turned it 0.00 rad; "
                     "odometry shows 0.50 m and 0.00 rad")
    spinning = ticks(StallWatch(settings), 3.0, (0.0, 1.0), lambda t: (0.0, 0.0, 0.0))
    assert spinning is not None and "turned it 2.00 rad; odometry shows 0.00 m and 0.00 rad" in spinning


def test_blank_scans_and_non_finite_odometry_count_as_missing():
    sensors = Sensors(RobotSettings())
    sensors.on_scan(scan([math.nan] * 4))
    sensors.on_scan(scan([1.0] * 4, range_max=0.0))
    assert sensors.scan_seen is None and sensors.blank_scans == 2 and sensors.scans.empty()
    reason = sensors.staleness(1e9)
    assert reason is not None and reason.startswith("stale scans: no valid scan on /scan") and "2 had under 5% valid beams" in reason
    sensors.on_scan(scan([1.0, math.nan, math.nan, math.nan]))  # 25 % of its beams returned: a scan
    assert sensors.scan_seen is not None and sensors.scans.qsize() == 1
    sensors.on_odometry(Odometry(5, "odom", "base_link", Pose2D(math.nan, 0.0, 0.0), 0.0, 0.0))
    sensors.on_odometry(Odometry(6, "odom", "base_link", Pose2D(0.0, 0.0, 0.0), math.inf, 0.0))
    sensors.on_transforms([Transform(7, "odom", "base_link", Pose2D(0.0, math.nan, 0.0), False)])
    assert sensors.odometry is None and sensors.odometry_seen is None and sensors.bad_odometry == 3
    assert sensors.lookup("odom", "base_link", 7) is None
    sensors.on_odometry(Odometry(8, "odom", "base_link", Pose2D(1.0, 2.0, 0.0), 0.5, 0.0))
    assert sensors.odometry is not None and sensors.odometry.pose.x == 1.0


def test_the_settings_share_of_valid_beams_is_honoured():
    sensors = Sensors(replace(RobotSettings(), min_valid_share=0.5))
    sensors.on_scan(scan([1.0, math.nan, math.nan, math.nan]))
    assert sensors.scan_seen is None and sensors.blank_scans == 1


WRITER = """
import os, signal, sys
from robot_logs.foxglove_log import FoxgloveWriter
writer = FoxgloveWriter(sys.argv[1], metadata={"run": {"run_code": "ABCDE"}}, chunk_size=4096)
for k in range(2000):
    writer.write("/robot/state", "navtrials.Plain", {"t": k * 0.05, "x": float(k)}, k * 50_000_000)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_the_log_of_a_killed_writer_is_recovered_up_to_its_last_complete_chunk(tmp_path):
    log = tmp_path / "ABCDE.mcap"
    killed = subprocess.run([sys.executable, "-c", WRITER, str(log)], capture_output=True)
    assert killed.returncode == -9 and not log.exists() and partial_path(log).exists()
    kept = recover(partial_path(log), tmp_path / "kept.mcap")
    reader = FoxgloveReader(tmp_path / "kept.mcap")
    xs = [m.data["x"] for m in reader.messages(["/robot/state"])]
    assert reader.metadata["run"] == {"run_code": "ABCDE"} and len(xs) == kept
    assert 1500 < kept < 2000 and xs == [float(k) for k in range(kept)]  # the first ones, in order; only the last chunks lost
