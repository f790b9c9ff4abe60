"""The controllers the runner drives: a head-on pedestrian deflects them; NaviGAN-R's wrapper and weights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navigan.errors import NaviganError
from trials.controllers.base import Observation
from trials.controllers.lattice import LatticeController
from trials.controllers.navigan_r import REACH_M, NaviganRController
from trials.scenario import Scenario, Settings, Walker
from trials.sim.closed_loop import NoSink, SimConfig, simulate
from trials.sim.perception import PositionNoise, PositionPerception
from trials.sim.social_force import SocialForceParams

STOPS_SHORT = ("in closed loop the shipped all-scenes NaviGAN-R slows and stops before a walker who does not give "
               "way, its plans swinging from one side to the other, instead of stepping aside (issue 3)")


pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def navigan() -> NaviganRController:
    return NaviganRController()


@pytest.fixture(scope="module")
def lattice() -> LatticeController:
    return LatticeController()


def observation(pedestrian_ahead: float | None, pose=(0.0, 0.0, 0.0)) -> Observation:
    """The robot at `pose` after driving 1 m/s along its heading toward a goal 10 m ahead; optionally
    someone walking straight at it at 1.2 m/s, now `pedestrian_ahead` metres in front (0.1 m to its left)."""
    x, y, theta = pose
    forward, left = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
    back = (7 - np.arange(8))[:, None]
    robot = np.array([x, y]) - back * 0.4 * forward
    if pedestrian_ahead is None:
        ids, people = (), np.zeros((0, 8, 2))
    else:
        ids, people = (0,), (np.array([x, y]) + pedestrian_ahead * forward + 0.1 * left + back * 0.48 * forward)[None]
    return Observation(0.0, np.array(pose), np.array([1.0, 0.0]), np.array([x, y]) + 10.0 * forward, robot, ids, people)


def lateral_change(controller, ahead: float) -> float:
    controller.reset(1)
    alone = controller.plan(observation(None)).waypoints
    controller.reset(1)
    met = controller.plan(observation(ahead)).waypoints
    return float(np.abs(met[:, 1] - alone[:, 1]).max())


@pytest.mark.parametrize("ahead", [2.0, 3.0, 4.0])
def test_a_head_on_pedestrian_deflects_the_lattice_plan(lattice, ahead):
    assert lateral_change(lattice, ahead) > 0.5


@pytest.mark.parametrize("ahead", [2.0, 3.0, 4.0])
def test_a_head_on_pedestrian_deflects_the_navigan_r_plan(navigan, ahead):
    assert lateral_change(navigan, ahead) > 0.5


def swerve(controller) -> float:
    """How far the robot's path moves to the right, away from a walker coming straight at it (0.1 m to
    its left, 0.8 m/s) who does not give way, compared with the same run alone."""
    walker = Walker(0, "oncoming", (9.0, 0.1), (-5.0, 0.1), 0.8)
    config = SimConfig(social=SocialForceParams(robot_strength=0.0, fluctuation=0.0))
    paths = []
    for walkers in ((), (walker,)):
        scenario = Scenario(Settings(len(walkers), "Parallel", 2.0), 0, (0.0, 0.0, 0.0), (10.0, 0.0), (10.0, 0.75), walkers)
        controller.reset(0)
        result = simulate(scenario, controller, PositionPerception(PositionNoise(0.0, 0.0), 0), NoSink(), config, 0)
        paths.append(np.array(result.trace.pose)[:, :2])
    alone, met = paths
    steps = min(len(alone), len(met))
    return float((alone[:steps, 1] - met[:steps, 1]).max())


def test_the_lattice_swerves_in_closed_loop(lattice):
    assert swerve(lattice) > 0.25


@pytest.mark.xfail(reason=STOPS_SHORT)  # strict (pyproject.toml): once NaviGAN-R swerves, the pass fails until the mark goes
def test_navigan_r_swerves_in_closed_loop(navigan):
    assert swerve(navigan) > 0.25


def test_navigan_r_plans_in_the_robots_frame(navigan):
    """Turning and shifting the whole scene turns and shifts the plan with it."""
    navigan.reset(5)
    plain = navigan.plan(observation(3.0))
    pose = (4.0, -2.0, 2.0)
    navigan.reset(5)
    moved = navigan.plan(observation(3.0, pose))
    c, s = math.cos(2.0), math.sin(2.0)
    expected = plain.waypoints @ np.array([[c, s], [-s, c]]) + pose[:2]
    np.testing.assert_allclose(moved.waypoints, expected, atol=1e-4)
    forces = np.array(plain.record["forces"]) @ np.array([[c, s], [-s, c]])
    np.testing.assert_allclose(moved.record["forces"], forces, atol=1e-4)


def test_navigan_r_plan_and_record(navigan):
    navigan.reset(3)
    plan = navigan.plan(observation(3.0))
    assert plan.waypoints.shape == (12, 2) and plan.step == 0.4
    record = plan.record
    assert record["controller"] == "NaviGAN-R" and record["plan_seconds"] > 0
    np.testing.assert_allclose(plan.waypoints, np.array(record["intention"]) + np.array(record["forces"]), atol=1e-4)
    assert record["subgoal"] == pytest.approx([REACH_M, 0.0])  # 4.8 m toward the goal, whatever its distance
    assert plan.waypoints[-1, 0] > 3.0  # heading for the goal
    navigan.reset(3)
    np.testing.assert_array_equal(navigan.plan(observation(3.0)).waypoints, plan.waypoints)  # seeded


def test_missing_or_corrupt_weights_are_refused(tmp_path):
    with pytest.raises(NaviganError, match="no checkpoint at"):
        NaviganRController(tmp_path / "absent.pt")
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(b"not a checkpoint")
    with pytest.raises(NaviganError, match="is not a readable checkpoint"):
        NaviganRController(corrupt)
