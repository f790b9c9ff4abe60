"""Checks of each sensor message against the ones before it during a live run: the robot's clock, the scan's frame and
size, odometry that moves further than the robot can, and tf that would make a frame's parents loop.

Each check answers the reason to stop the robot, naming the cause, or None. They are pure: `trials.robot.live.Sensors`
calls them from the middleware's threads and keeps the first reason as its fault.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_logs.frames import FrameTree, Pose2D, frame_name
from robot_logs.records import Scan

#: Beams a scan may have. Planar lidars give up to a few thousand (0.1 degree over 270 degrees is 2,700); a scan ten
#: times larger than any of them cannot be a laser's, and tracking one takes longer than the watchdog allows.
MAX_SCAN_BEAMS = 20_000
#: Odometry may move at most this factor of the robot's top speed between two messages, plus `ODOMETRY_SLACK_M`: a
#: wheel slipping or a base pushed stays within it, a pose reset or a corrupted message does not.
ODOMETRY_SPEED_FACTOR, ODOMETRY_SLACK_M = 2.0, 0.5


def blank_cause(scan: Scan) -> str:
    """Why a scan has no usable beams, in words: its limits, or what its ranges hold."""
    ranges = np.asarray(scan.ranges, dtype=float)
    if not len(ranges):
        return "no ranges"
    if not (math.isfinite(scan.range_min) and math.isfinite(scan.range_max) and 0.0 <= scan.range_min < scan.range_max):
        return f"range limits [{scan.range_min:g}, {scan.range_max:g}] m are not an interval of distances"
    with np.errstate(invalid="ignore"):
        counts = {"NaN": int(np.isnan(ranges).sum()), "negative": int((ranges < 0).sum()),
                  "without a return": int(np.isinf(ranges).sum()),
                  f"outside [{scan.range_min:g}, {scan.range_max:g}] m": int(((ranges >= 0) & np.isfinite(ranges) &
                                                                             ((ranges < scan.range_min) | (ranges > scan.range_max))).sum())}
    return ", ".join(f"{n} {what}" for what, n in counts.items() if n) + f" of {len(ranges)} ranges"


@dataclass
class ClockCheck:
    """The robot's clock against this computer's monotonic one, message by message on one topic: the stamps of two
    messages may differ from their arrival times by at most `tolerance` seconds (a late message is the watchdog's)."""

    what: str
    tolerance: float
    last: tuple[int, float] | None = None

    def add(self, stamp_ns: int, arrived: float) -> str | None:
        last, self.last = self.last, (stamp_ns, arrived)
        if last is None:
            return None
        stamped = (stamp_ns - last[0]) * 1e-9
        between = arrived - last[1]
        if stamped < -self.tolerance:
            self.last = last  # the reference stays the clock as it was
            return f"the robot's clock stepped back {-stamped:.2f} s: one of the {self.what} is stamped before the one before it"
        if stamped - between > self.tolerance:
            self.last = last
            return (f"the robot's clock jumped {stamped - between:.2f} s ahead: two {self.what} stamped {stamped:.2f} s apart "
                    f"arrived {between:.2f} s apart")
        return None


def scan_fault(scan: Scan, frame: str | None) -> str | None:
    """Why a scan cannot be used in a run whose laser is `frame` (None: not known yet), else None."""
    if len(scan.ranges) > MAX_SCAN_BEAMS:
        return f"a scan of {len(scan.ranges)} beams: more than {MAX_SCAN_BEAMS} cannot be tracked within the watchdog"
    if frame is not None and frame_name(scan.frame_id) != frame_name(frame):
        return f"the scan's frame changed from {frame_name(frame)} to {frame_name(scan.frame_id) or '(empty)'}"
    return None


@dataclass
class OdometryCheck:
    """Odometry that moves further between two messages than the robot can at `max_speed` is a jump, not motion."""

    what: str
    max_speed: float
    last: tuple[int, Pose2D] | None = None

    def add(self, stamp_ns: int, pose: Pose2D) -> str | None:
        last, self.last = self.last, (stamp_ns, pose)
        if last is None:
            return None
        seconds = max((stamp_ns - last[0]) * 1e-9, 0.0)
        moved = math.hypot(pose.x - last[1].x, pose.y - last[1].y)
        reach = ODOMETRY_SPEED_FACTOR * self.max_speed * seconds + ODOMETRY_SLACK_M
        if moved <= reach:
            return None
        self.last = last
        return (f"{self.what} jumped {moved:.2f} m in {seconds:.2f} s, where the robot moves at most "
                f"{self.max_speed:g} m/s (a pose reset or a corrupt message)")


def tf_fault(tree: FrameTree, parent: str, child: str) -> str | None:
    """Why the transform `parent` -> `child` cannot join the tree, else None: it would close a loop, or give `child` a
    second parent."""
    parent, child = frame_name(parent), frame_name(child)
    if parent == child:
        return f"tf loop: a transform from {parent} to itself"
    known = tree.parent(child)
    if known is not None and known != parent:
        return f"tf: frame {child} has two parents, {known} and {parent}"
    if child in tree.chain(parent):
        return f"tf loop: {parent} -> {child} closes a loop ({child} is already above {parent})"
    return None
