"""The robot's own navigation stack (move_base on ROS 1, Nav2 on ROS 2) as an arm: live runs only.

It plans nothing here: a live run sends the stack the row's goal and relays the stack's velocity commands to the base
(`trials.robot.navigation`). In the simulator and on logs there is no stack to ask, so a study with this arm runs live.
"""

from __future__ import annotations

from typing import Any

from trials.controllers.base import Observation, Plan
from trials.controllers.checked import ControllerFault


class NavStackController:
    """The marker the live loop recognises; asked to plan, it refuses."""

    name = "NavStack"

    def details(self) -> dict[str, str]:
        return {"drives": "the robot's own navigation stack"}

    def plan(self, observation: Observation) -> Plan:
        raise ControllerFault("this controller plans on the robot: it runs live only (trials run --robot URI)")


def is_nav_stack(controller: Any) -> bool:
    """Whether `controller` (checked or not) is the robot's own navigation stack."""
    return isinstance(getattr(controller, "inner", controller), NavStackController)
