"""A node that holds the e-stop topic at true, as a robot's e-stop button does, until it is killed.

    python -m tests.support.press_estop URI TOPIC
"""

from __future__ import annotations

import sys
import time

from trials.robot.transport import FLAG, RobotUri, open_transport

if __name__ == "__main__":
    press = open_transport(RobotUri.parse(sys.argv[1]), "navtrials_estop").publisher(sys.argv[2], FLAG, latched=True)
    while True:
        press(True)
        time.sleep(0.1)
