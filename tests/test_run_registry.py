"""The controller registry: one name per controller, each builds its controller, an unknown one is a
one-line error naming the known ones."""

from __future__ import annotations

import numpy as np
import pytest

from robot_logs.physical import T_OBS, T_PRED
from trials.cli import USER_ERRORS
from trials.controllers import registry
from trials.controllers.base import Observation

pytestmark = pytest.mark.usefixtures("one_torch_thread")


def test_the_names_are_those_study_files_hold():
    # plan.csv levels, sealed arms and outcomes.csv's controller column of existing studies; the paper's A/B pair
    assert registry.NAMES == ("NaviGAN-R", "Lattice", "SocialForce", "ORCA") and registry.DEFAULT in registry.NAMES
    assert registry.AB_PRESET == ("NaviGAN-R", "Lattice")


@pytest.mark.parametrize("name", registry.NAMES)
def test_every_name_builds_its_controller(name):
    controller = registry.build(name)
    assert controller.name == name
    controller.reset(0)
    alone = Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)), (),
                        np.zeros((0, T_OBS, 2)))
    plan = controller.plan(alone)
    assert plan.waypoints.shape == (T_PRED, 2) and plan.record["controller"] == name
    assert all(isinstance(v, str) for v in controller.details().values())


@pytest.mark.parametrize("name", ["SBPL", "lattice", "navigan-r"])
def test_an_unknown_name_is_one_line_listing_the_known_ones(name):
    with pytest.raises(USER_ERRORS) as caught:
        registry.build(name)
    assert str(caught.value) == f"no controller is called {name!r} (known: NaviGAN-R, Lattice, SocialForce, ORCA)"
