"""A second node publishing scans on the robot's scan topic (every range NaN, stamped now, 20 Hz) until it is killed: a
stray driver or a bag played by mistake, whose scans a run cannot tell from the robot's own.

    python -m tests.support.blank_scanner URI TOPIC
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from robot_logs.records import Scan
from trials.robot.transport import SCAN, RobotUri, open_transport

if __name__ == "__main__":
    publish = open_transport(RobotUri.parse(sys.argv[1]), "stray_scanner").publisher(sys.argv[2], SCAN)
    while True:
        publish(Scan(time.time_ns(), "laser", -math.pi / 2, math.pi / 360, 0.05, 30.0, np.full(361, np.nan)))
        time.sleep(0.05)
