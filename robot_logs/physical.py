"""Physical facts every package shares, each stated once: the robot, a pedestrian, NaviGAN's clock, comfort distances.

This module is the bottom layer: it imports nothing, and the simulator, the controllers, the log
reader, NaviGAN and the analysis take these numbers from here rather than restating them.
"""

from __future__ import annotations

#: The robot every run drives, a ClearPath Husky: half its length and width (m), centred on the robot.
ROBOT_HALF_LENGTH_M = 0.495
ROBOT_HALF_WIDTH_M = 0.335
#: The Husky's outline in its own frame (m), corners counter-clockwise from the rear right.
ROBOT_FOOTPRINT = (
    (-ROBOT_HALF_LENGTH_M, -ROBOT_HALF_WIDTH_M),
    (ROBOT_HALF_LENGTH_M, -ROBOT_HALF_WIDTH_M),
    (ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M),
    (-ROBOT_HALF_LENGTH_M, ROBOT_HALF_WIDTH_M),
)
#: The Husky's top forward speed (m/s).
ROBOT_SPEED_M_S = 1.0

#: A pedestrian's body as a disc (m): a footprint-to-centre distance below it is contact.
PEDESTRIAN_RADIUS_M = 0.25

#: NaviGAN's planning step (s), the 2.5 Hz frame rate of ETH/UCY, and its observed and predicted horizons (steps).
STEP_S = 0.4
T_OBS = 8
T_PRED = 12

#: A run reaches its goal when the robot's centre is this close to it (m).
GOAL_TOLERANCE_M = 0.5

#: Proxemic distances (m) between the robot's footprint and a person's body: intimate and personal space.
INTIMATE_M = 0.5
PERSONAL_M = 1.2
