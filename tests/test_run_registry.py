"""The controller registry: one name per controller, each builds its controller, an unknown one is a
one-line error naming the known ones."""

from __future__ import annotations

import numpy as np
import pytest

from robot_logs.physical import T_OBS, T_PRED
from trials.cli import USER_ERRORS
from trials.controllers import registry
from trials.controllers.base import Observation
from trials.controllers.checked import ControllerFault
from trials.controllers.nav_stack import is_nav_stack

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_the_names_are_those_study_files_hold():
    # plan.csv levels, sealed arms and outcomes.csv's controller column of existing studies; the paper's A/B pair
    assert registry.NAMES == ("NaviGAN-R", "Lattice", "SocialForce", "ORCA", "NavStack") and registry.DEFAULT in registry.NAMES
    assert registry.AB_PRESET == ("NaviGAN-R", "Lattice")


@pytest.mark.parametrize("name", [name for name in registry.NAMES if name != registry.NAV_STACK])
def test_every_name_builds_its_controller(name):
    controller = registry.build(name)
    assert controller.name == name
    controller.reset(0)
    alone = Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)), (),
                        np.zeros((0, T_OBS, 2)))
    plan = controller.plan(alone)
    assert plan.waypoints.shape == (T_PRED, 2) and plan.record["controller"] == name
    assert all(isinstance(v, str) for v in controller.details().values())


def test_the_navigation_stack_builds_but_plans_only_on_the_robot():
    stack = registry.build(registry.NAV_STACK)
    assert is_nav_stack(stack) and not is_nav_stack(registry.build(registry.LATTICE))
    alone = Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)), (), np.zeros((0, T_OBS, 2)))
    with pytest.raises(ControllerFault, match=r"^this controller plans on the robot: it runs live only \(trials run --robot URI\)$"):
        stack.plan(alone)


@pytest.mark.parametrize("name", ["SBPL", "lattice", "navigan-r"])
def test_an_unknown_name_is_one_line_listing_the_known_ones(name):
    with pytest.raises(USER_ERRORS) as caught:
        registry.build(name)
    assert str(caught.value) == f"no controller is called {name!r} (known: NaviGAN-R, Lattice, SocialForce, ORCA, NavStack)"
