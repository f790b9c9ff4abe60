"""Each sensor message checked before a live run uses it: the robot's clock either way, a scan's frame and size, odometry
that jumps further than the robot moves, a tf loop or a frame with two parents, and what a blank scan holds; and the
middleware asked who else publishes (one driver per robot, one source per sensor), with a fake middleware whose answers
the test sets."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from robot_logs.frames import FrameTree, Pose2D
from robot_logs.records import Odometry, Scan, Transform
from trials.robot.live import Sensors
from trials.robot.one_driver import new_session, node_name, publisher_fault
from trials.robot.sensor_checks import MAX_SCAN_BEAMS, ClockCheck, OdometryCheck, blank_cause, scan_fault, tf_fault
from trials.robot.settings import RobotSettings
from trials.robot.transport import RobotUri

S = 1_000_000_000


def scan(stamp_ns: int = S, frame: str = "laser", ranges: list[float] | np.ndarray = (1.0,) * 8, range_max: float = 11.0) -> Scan:
    return Scan(stamp_ns=stamp_ns, frame_id=frame, angle_min=-1.0, angle_increment=0.25, range_min=0.03, range_max=range_max,
                ranges=np.asarray(ranges, dtype=float))


def test_the_robot_clock_may_not_step_back_or_run_ahead_of_the_arrivals():
    clock = ClockCheck("scans on /scan", tolerance=0.5)
    assert clock.add(100 * S, 10.0) is None
    assert clock.add(100 * S + S // 10, 10.1) is None
    # Late delivery (stamped 0.1 s apart, arriving 0.45 s apart) is the watchdog's business, not the clock's.
    assert clock.add(100 * S + 2 * S // 10, 10.55) is None
    # Stamped 30 s ahead while 0.05 s passed here: 29.85 s ahead.
    assert clock.add(130 * S + 2 * S // 10, 10.6) == ("the robot's clock jumped 29.95 s ahead: two scans on /scan stamped "
                                                       "30.00 s apart arrived 0.05 s apart")
    # The reference stays the clock as it was: the next honest message passes.
    assert clock.add(100 * S + 3 * S // 10, 10.65) is None
    assert clock.add(70 * S, 10.7) == "the robot's clock stepped back 30.30 s: one of the scans on /scan is stamped before the one before it"
    # Within the tolerance a message stamped slightly before the one before it (two sources' jitter) passes.
    assert clock.add(100 * S, 10.75) is None


def test_odometry_may_move_only_as_far_as_the_robot_can():
    check = OdometryCheck("odometry on /odom", max_speed=1.0)
    assert check.add(0, Pose2D(0.0, 0.0, 0.0)) is None
    # 2 x 1 m/s x 0.5 s + 0.5 m = 1.5 m allowed.
    assert check.add(S // 2, Pose2D(1.49, 0.0, 0.0)) is None
    assert check.add(S, Pose2D(51.49, 0.0, 0.0)) == ("odometry on /odom jumped 50.00 m in 0.50 s, where the robot moves at most "
                                                     "1 m/s (a pose reset or a corrupt message)")
    assert check.add(S, Pose2D(1.6, 0.3, 0.0)) is None


def test_a_scan_too_large_or_in_another_frame_is_refused():
    assert scan_fault(scan(ranges=np.ones(MAX_SCAN_BEAMS)), "laser") is None
    assert scan_fault(scan(ranges=np.ones(100_000)), None) == (
        f"a scan of 100000 beams: more than {MAX_SCAN_BEAMS} cannot be tracked within the watchdog")
    assert scan_fault(scan(frame="/laser"), "laser") is None  # tf's leading slash names the same frame
    assert scan_fault(scan(frame="laser_2"), "laser") == "the scan's frame changed from laser to laser_2"


def test_a_tf_loop_or_a_second_parent_is_refused():
    tree = FrameTree()
    tree.add("odom", "base_link", 0, Pose2D())
    tree.add("base_link", "laser", 0, Pose2D(0.35, 0.0, 0.0), static=True)
    assert tf_fault(tree, "odom", "base_link") is None
    assert tf_fault(tree, "map", "odom") is None
    assert tf_fault(tree, "laser", "odom") == "tf loop: laser -> odom closes a loop (odom is already above laser)"
    assert tf_fault(tree, "base_link", "base_link") == "tf loop: a transform from base_link to itself"
    assert tf_fault(tree, "map", "base_link") == "tf: frame base_link has two parents, odom and map"


@pytest.mark.parametrize("ranges, range_max, cause", [
    ([math.nan] * 8, 11.0, "8 NaN of 8 ranges"),
    ([-1.0] * 8, 11.0, "8 negative of 8 ranges"),
    ([1.0] * 8, 0.0, "range limits [0.03, 0] m are not an interval of distances"),
    ([math.inf] * 6 + [20.0, -2.0], 11.0, "1 negative, 6 without a return, 1 outside [0.03, 11] m of 8 ranges"),
])
def test_a_blank_scan_is_described_by_what_it_holds(ranges, range_max, cause):
    assert blank_cause(scan(ranges=ranges, range_max=range_max)) == cause
    sensors = Sensors(RobotSettings())
    sensors.on_scan(scan(ranges=ranges, range_max=range_max))
    reason = sensors.staleness(1e9)
    assert reason is not None and reason.endswith(f"1 had under 5% valid beams, the last {cause})")


def driving() -> Sensors:
    sensors = Sensors(RobotSettings())
    sensors.on_transforms([Transform(0, "base_link", "laser", Pose2D(0.35, 0.0, 0.0), True)])
    sensors.on_odometry(Odometry(S, "odom", "base_link", Pose2D(), 0.0, 0.0))
    sensors.on_scan(scan(S))
    sensors.begin_drive("laser")
    return sensors


def test_while_driving_every_fault_is_kept_with_its_cause_and_the_message_dropped():
    sensors = driving()
    sensors.on_scan(scan(S + S // 20))
    sensors.on_scan(scan(S + S // 10, frame="laser_2"))
    assert sensors.fault == "the scan's frame changed from laser to laser_2" and sensors.scans.qsize() == 2
    sensors.on_odometry(Odometry(2 * S, "odom", "base_link", Pose2D(50.0, 0.0, 0.0), 0.0, 0.0))
    assert sensors.fault == "the scan's frame changed from laser to laser_2"  # the first cause is kept
    assert sensors.odometry is not None and sensors.odometry.pose.x == 0.0  # the jumped pose was not taken

    sensors.start_run(sensors.stop)  # type: ignore[arg-type]
    assert sensors.fault is None
    sensors.begin_drive("laser")
    sensors.on_transforms([Transform(2 * S, "base_link", "odom", Pose2D(), False)])
    assert sensors.fault == "tf loop: base_link -> odom closes a loop (odom is already above base_link)"
    assert sensors.tree.parent("odom") is None

    sensors.end_drive()
    sensors.fault = None
    # Between runs the robot may be carried to its start: a jump is no fault then.
    sensors.on_odometry(Odometry(3 * S, "odom", "base_link", Pose2D(50.0, 0.0, 0.0), 0.0, 0.0))
    sensors.on_scan(scan(3 * S, frame="laser_2"))
    assert sensors.fault is None and sensors.odometry.pose.x == 50.0


def test_a_scan_from_the_future_stops_the_run_and_is_not_used():
    sensors = driving()
    sensors.on_scan(scan(31 * S))
    assert sensors.fault is not None and sensors.fault.startswith("the robot's clock jumped")
    assert sensors.newest_scan_ns == S and sensors.scans.qsize() == 1


class FakeMiddleware:
    """Who publishes on which topic, as a test sets it."""

    uri = RobotUri.parse("ros1://127.0.0.1:11311")

    def __init__(self, publishers: dict[str, list[str]]) -> None:
        self._publishers = publishers

    def publishers(self, topic: str) -> dict[str, str]:
        return {name: name for name in self._publishers.get(topic, [])}


def test_another_driver_or_a_second_sensor_source_is_named():
    settings = RobotSettings()
    session = new_session()
    ours = [f"/{node_name(session, 'guard')}_1234_1700", f"/{node_name(session, 'run')}_1240_1701"]
    robot = {"/scan": ["/laser_driver"], "/odom": ["/base_driver"]}
    assert publisher_fault(FakeMiddleware({**robot, "/cmd_vel": ours}), settings, session) is None
    other = f"/{node_name(new_session(), 'run')}_999_1702"
    assert publisher_fault(FakeMiddleware({**robot, "/cmd_vel": [*ours, other]}), settings, session) == (
        f"another node commands the robot on /cmd_vel: {other} (one driver per robot: stop it, or the other trials run, first)")
    assert publisher_fault(FakeMiddleware({**robot, "/scan": ["/laser_driver", "/blank"]}), settings, session) == (
        "2 nodes publish on /scan (/blank, /laser_driver): a run cannot tell the robot's own messages")
    no_odometry = replace(settings, odometry_topic="")
    assert publisher_fault(FakeMiddleware({"/scan": ["/laser_driver"], "": ["/a", "/b"]}), no_odometry, session) is None
