"""Scenarios from plan rows: the layout of the three walking patterns, seeded variation, bad values."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.run_studies import Straight
from trials.errors import StudyError
from trials.scenario import Settings, build_scenario, settings_from_row
from trials.sim.closed_loop import NoSink, SimConfig, simulate
from trials.sim.perception import PositionNoise, PositionPerception
from trials.sim.robot import RobotLimits

FRONT = RobotLimits().half_length


def drive(settings: Settings, seed: int, speed: float = 0.8):
    """Run the scenario with a robot driving straight at `speed`; returns scenario, times, poses, positions."""
    scenario = build_scenario(settings, seed)
    result = simulate(scenario, Straight(speed), PositionPerception(PositionNoise(), seed), NoSink(), SimConfig(), seed)
    trace = result.trace
    return scenario, np.array(trace.time), np.array(trace.pose), np.array(trace.pedestrians)


def crossing_gaps(scenario, poses, positions) -> list[float]:
    """For each crosser, how far ahead of the robot's front bumper it crossed the robot's path (y = 0)."""
    gaps = []
    for walker in scenario.walkers:
        if walker.role != "crossing":
            continue
        y = positions[:, walker.id, 1]
        k = np.flatnonzero(np.sign(y) != np.sign(y[0]))
        assert len(k), f"pedestrian {walker.id} never crossed"
        gaps.append(positions[k[0], walker.id, 0] - (poses[k[0], 0] + FRONT))
    return gaps


def test_parallel_layout():
    scenario = build_scenario(Settings(4, "Parallel", 2.0), seed=1)
    assert scenario.robot_start == (0.0, 0.0, 0.0) and scenario.goal == (10.0, 0.0) and scenario.cone == (10.0, 0.75)
    lanes = sorted(w.start[1] for w in scenario.walkers)
    np.testing.assert_allclose(lanes, [-1.5, -0.5, 0.5, 1.5], atol=0.15)
    for walker in scenario.walkers:
        assert walker.role == "oncoming" and walker.cross_x is None
        assert 10.7 <= walker.start[0] <= 12.5
        assert walker.goal == (-5.0, walker.start[1])
        assert 0.0 <= walker.delay_s <= 0.5


def test_crossing_layout():
    scenario = build_scenario(Settings(4, "Crossing", 2.0), seed=1)
    crossers = scenario.walkers
    assert [w.role for w in crossers] == ["crossing"] * 4
    # the first half from the left, 1 m apart from max(5, d + 3.5) = 5.5 m on
    np.testing.assert_allclose([w.cross_x for w in crossers], [5.5, 6.5, 7.5, 8.5], atol=0.1)
    assert [np.sign(w.start[1]) for w in crossers] == [1, 1, -1, -1]
    for walker in crossers:
        assert 2.0 <= abs(walker.start[1]) <= 2.3
        assert walker.goal == (walker.start[0], -np.sign(walker.start[1]) * 2.0)
    far = build_scenario(Settings(2, "Crossing", 3.0), seed=1)
    np.testing.assert_allclose([w.cross_x for w in far.walkers], [6.5, 7.5], atol=0.1)


def test_parallel_crossing_layout():
    scenario = build_scenario(Settings(6, "ParallelCrossing", 1.0), seed=2)
    oncoming = [w for w in scenario.walkers if w.role == "oncoming"]
    crossers = [w for w in scenario.walkers if w.role == "crossing"]
    assert len(oncoming) == 3 and len(crossers) == 3
    np.testing.assert_allclose([w.start[1] for w in oncoming], [3.2, -3.2, 4.0], atol=0.15)
    np.testing.assert_allclose([w.cross_x for w in crossers], [5.0, 6.0, 7.0], atol=0.1)


def test_variation_is_seeded_and_recorded():
    a = build_scenario(Settings(6, "ParallelCrossing", 2.0), seed=5)
    assert a == build_scenario(Settings(6, "ParallelCrossing", 2.0), seed=5)
    b = build_scenario(Settings(6, "ParallelCrossing", 2.0), seed=6)
    assert [w.speed for w in a.walkers] != [w.speed for w in b.walkers]
    speeds = [w.speed for seed in range(40) for w in build_scenario(Settings(6, "Parallel", 2.0), seed).walkers]
    assert 0.9 <= min(speeds) and max(speeds) <= 1.5 and abs(np.mean(speeds) - 1.2) < 0.03
    record = a.variation()
    assert len(record) == 6 and record[0]["speed"] == round(a.walkers[0].speed, 4)
    assert set(record[0]) == {"id", "role", "start", "goal", "speed", "delay_s", "cross_x", "timing_s"}


@pytest.mark.parametrize("direction", ["Crossing", "ParallelCrossing"])
@pytest.mark.parametrize("distance", [1.0, 2.0, 3.0])
def test_crossers_cross_at_the_distance_in_front_of_the_robot(direction, distance):
    scenario, _, poses, positions = drive(Settings(6, direction, distance), seed=int(10 * distance))
    gaps = np.array(crossing_gaps(scenario, poses, positions))
    assert abs(np.median(gaps) - distance) < 0.3, gaps
    assert np.all(np.abs(gaps - distance) < 0.8), gaps


@pytest.mark.parametrize("speed", [0.5, 1.0])
def test_a_lone_crosser_is_on_time_at_any_robot_speed(speed):
    for distance in (1.0, 2.5, 4.5):
        scenario, _, poses, positions = drive(Settings(1, "Crossing", distance), seed=3, speed=speed)
        (gap,) = crossing_gaps(scenario, poses, positions)
        assert abs(gap - distance) < 0.3, (distance, gap)


def test_parallel_walkers_come_toward_the_robot_and_pass_it_on_their_lanes():
    scenario, _, poses, positions = drive(Settings(4, "Parallel", 2.0), seed=4)
    for walker in scenario.walkers:
        path = positions[:, walker.id]
        assert path[-1, 0] < poses[-1, 0] - 5.0  # met the robot and walked on past it
        assert np.all(np.diff(path[:, 0]) < 0.05)  # always toward the robot
        passing = np.argmin(np.abs(path[:, 0] - poses[:, 0]))
        assert abs(path[passing, 1] - poses[passing, 1]) > 0.6  # beside the robot, not through it
        assert abs(path[-1, 1] - walker.start[1]) < 1.0  # and back near its lane


def test_parallel_crossing_outer_walkers_keep_their_parallel_paths():
    scenario, _, poses, positions = drive(Settings(6, "ParallelCrossing", 2.0), seed=8)
    for walker in scenario.walkers:
        if walker.role == "oncoming":
            path = positions[:, walker.id]
            assert np.all(np.abs(path[:, 1]) > 2.5) and np.all(np.abs(path[:, 1] - walker.start[1]) < 0.6)
            assert path[-1, 0] < 1.0
    gaps = crossing_gaps(scenario, poses, positions)
    assert len(gaps) == 3 and abs(np.median(gaps) - 2.0) < 0.3


@pytest.mark.parametrize("count,direction,distance", [(0, "Crossing", 2.0), (1, "Parallel", 2.0), (3, "ParallelCrossing", 1.5),
                                                      (9, "Crossing", 0.5), (8, "Parallel", 6.0)])
def test_values_outside_the_presets_run(count, direction, distance):
    scenario, times, _, positions = drive(Settings(count, direction, distance), seed=1, speed=1.0)
    assert len(scenario.walkers) == count and positions.shape == (len(times), count, 2)
    assert times[-1] < 60.0


def test_settings_from_a_plan_row():
    row = {"order": "1", "run_code": "AAAAA", "Pedestrians": "6", "Direction": "Crossing", "CrossingDistance": "1.5", "Controller": "A"}
    assert settings_from_row(row, "row 1") == Settings(6, "Crossing", 1.5)
    assert settings_from_row({"Pedestrians": "2.0"}, "row 1") == Settings(2, "Crossing", 2.0)  # defaults for the rest
    assert settings_from_row({**row, "Block": "2"}, "row 1") == Settings(6, "Crossing", 1.5)  # a blocked plan's column is the analysis's


@pytest.mark.parametrize("column,value,message", [
    ("Direction", "Diagonal", "Direction 'Diagonal' is not one of Parallel, ParallelCrossing, Crossing"),
    ("Pedestrians", "2.5", "Pedestrians '2.5' must be a whole number from 0 to 20"),
    ("Pedestrians", "-2", "Pedestrians '-2' must be a whole number"),
    ("Pedestrians", "many", "Pedestrians 'many' is not a number"),
    ("CrossingDistance", "0", "CrossingDistance '0' must be above 0 and at most 10 m"),
    ("CrossingDistance", "nan", "CrossingDistance 'nan' is not a finite number"),
    ("Lighting", "dark", "factor 'Lighting' cannot be simulated"),
])
def test_bad_values_name_the_row(column, value, message):
    row = {"Pedestrians": "2", "Direction": "Parallel", "CrossingDistance": "2", column: value}
    with pytest.raises(StudyError, match="^plan.csv line 7: ") as caught:
        settings_from_row(row, "plan.csv line 7")
    assert message in str(caught.value)
