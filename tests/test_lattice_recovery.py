"""The lattice controller's recovery ladder: each rung on a constructed situation, the expansion
budget, and (slow) the A/B plan's lattice runs over 20 seeds, none of which may time out."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from robot_logs.physical import ROBOT_FOOTPRINT, T_PRED
from robot_logs.run_log import read_run
from tests.support.lattice_scene import observe
from trials.cli import main
from trials.controllers.lattice import LatticeController
from trials.controllers.registry import LATTICE
from trials.errors import USER_ERRORS
from trials.lattice.crowd import circumscribed_radius, escape_point
from trials.pool import WorkerPool
from trials.runner import RunDone, RunOptions, RunTask, StudyRun, setup_worker
from trials.study import RUNS, StudyFolder

#: A row of people 1.2 m in front of a robot that faces +y, with its goal 10 m along +x.
ROW_AHEAD = [((x, 1.2), (0.0, 0.0)) for x in np.arange(-2.0, 2.01, 0.4)]


def test_a_path_that_starts_by_turning_in_place_moves_at_once(fresh):
    # no room for an arc under the row: the path turns 90 degrees in place (1.6 s at the lattice's
    # turn rate), then drives along +x; the way-points leave that turn to the follower
    plan = fresh.plan(observe(robot=(0.0, 0.0, math.pi / 2), peds=ROW_AHEAD))
    assert plan.record["rung"] == "margin" and plan.record["status"] == "solved"
    assert np.hypot(*plan.waypoints[0]) > 0.3
    assert np.diff(plan.waypoints[:3, 0]) == pytest.approx([0.4, 0.4], abs=1e-3)
    assert plan.waypoints[1:3, 1] == pytest.approx([0.05, 0.05], abs=1e-3)


def test_start_in_collision_backs_off_straight_away_from_the_person(fresh):
    # 0.4 m ahead is inside the bare body's inscribed zone; someone within the turning circle leaves
    # only straight moves, and straight back gains the most: 0.4 m to 0.9 m
    plan = fresh.plan(observe(peds=[((0.4, 0.0), (0.0, 0.0))]))
    record = plan.record
    assert record["rung"] == "escape" and record["status"] == "start_in_collision" and not record["holding"]
    assert record["margin"] == 0.0 and record["escape_to"] == pytest.approx([-0.5, 0.0])
    # 0.5 m/s, 0.4 s apart, stopping 0.5 m back
    assert plan.waypoints[:4, 0] == pytest.approx([-0.2, -0.4, -0.5, -0.5])
    assert plan.waypoints[:, 1] == pytest.approx(0.0, abs=1e-12)


def test_boxed_in_front_and_back_holds_still(fresh):
    # people 0.4 m ahead and behind: every straight move ends nearer one of them
    plan = fresh.plan(observe(peds=[((0.4, 0.0), (0.0, 0.0)), ((-0.4, 0.0), (0.0, 0.0))]))
    assert plan.record["rung"] == "hold" and plan.record["holding"]
    assert np.array_equal(plan.waypoints, np.zeros((T_PRED, 2)))


def test_walled_in_by_the_margin_plans_with_the_bare_bodies(fresh):
    # 24 people on a 1.2 m ring: with the margin the robot's own cell is all it can reach; without it,
    # the cell 0.3 m nearer the goal
    ring = [(1.2 * np.array([np.cos(a), np.sin(a)]), (0.0, 0.0)) for a in np.linspace(0, 2 * np.pi, 24, endpoint=False)]
    plan = fresh.plan(observe(peds=ring))
    record = plan.record
    assert record["rung"] == "no_margin" and record["margin"] == 0.0 and record["goal_moved"]
    assert record["target"] == pytest.approx([0.35, 0.05])
    assert plan.waypoints[-1] == pytest.approx([0.35, 0.05])


def test_standing_on_the_nearest_reachable_cell_to_a_covered_goal_waits():
    bare = LatticeController(comfort_margin=0.0)
    bare.reset(1)
    covered = [((10.0, 0.0), (0.0, 0.0))]
    first = bare.plan(observe(peds=covered))
    assert first.record["rung"] == "margin" and first.record["goal_moved"]
    x, y = first.record["target"]
    there = bare.plan(observe(robot=(x, y, 0.0), peds=covered))
    assert there.record["rung"] == "wait" and there.record["holding"] and there.record["status"] == "solved"
    assert np.allclose(there.waypoints, [x, y])


def test_escape_point_turns_toward_the_most_room_when_no_one_is_close():
    # one person 2 m ahead and 0.5 m left: the direction nearest straight away from them (-157.5
    # degrees of the 16) gains most
    pose = np.array([0.0, 0.0, 0.0])
    point = escape_point(pose, np.array([[2.0, 0.5]]), turn_clearance=0.9)
    away = math.radians(-157.5)
    assert point == pytest.approx([0.5 * math.cos(away), 0.5 * math.sin(away)], abs=1e-12)
    # two people ahead and behind, 1 m away: the sides gain most (to hypot(1, 0.5) = 1.118 m), the
    # first counterclockwise from ahead wins the tie
    point = escape_point(pose, np.array([[1.0, 0.0], [-1.0, 0.0]]), turn_clearance=0.9)
    assert point == pytest.approx([0.0, 0.5], abs=1e-12)


def test_escape_point_near_someone_only_drives_straight():
    # a person 0.6 m to the left: turning in place would sweep into them, so the sideways escape
    # (0.6 to 1.1 m) is out; 45 degrees back and right is the best straight move
    pose = np.array([0.0, 0.0, 0.0])
    turn = circumscribed_radius(ROBOT_FOOTPRINT) + 0.3
    point = escape_point(pose, np.array([[0.0, 0.6]]), turn_clearance=turn)
    assert turn > 0.6 and point == pytest.approx(0.5 * np.array([-math.sqrt(0.5), -math.sqrt(0.5)]), abs=1e-12)
    assert escape_point(pose, np.zeros((0, 2)), turn_clearance=turn) is None


def test_expansion_budget_stops_the_search_at_that_count_every_time():
    limited = LatticeController(budget_expansions=50)
    plans = []
    for _ in range(2):
        limited.reset(1)
        plans.append(limited.plan(observe(peds=[((5.0, 0.0), (0.0, 0.0))])))
    record = plans[0].record
    assert record["status"] == "partial" and record["expansions"] == 50
    assert record["message"].startswith("no path to the goal within 50 expansions")
    assert np.array_equal(plans[0].waypoints, plans[1].waypoints)
    assert limited.details() == {"search_budget": "50 expansions"}


class StudyRows:
    """A pool worker's task handler: runs one plan row, (study folder, run code), of any study, with
    the runner's worker for that study built on its first row."""

    def __init__(self) -> None:
        self.studies: dict[str, tuple[StudyRun, Callable[[RunTask], RunDone]]] = {}

    def __call__(self, task: tuple[str, str]) -> str:
        root, code = task
        if root not in self.studies:
            study = StudyRun.open(StudyFolder(Path(root)), blind_flag=False)
            self.studies[root] = study, setup_worker(root, study.name, study.blind, study.levels, RunOptions())
        study, worker = self.studies[root]
        return worker(study.task(code)).outcome.status


@pytest.mark.slow
def test_the_ab_plans_lattice_runs_neither_freeze_nor_drive_into_anyone_over_20_seeds(tmp_path, capsys):
    # The lattice arm only (9 of each plan's 18 runs): NaviGAN-R never froze, and all 360 runs take
    # too long. Before the fix 5 of these 180 runs stood until the timeout (seeds 6, 10, 12, 15
    # and 20). One pool of two workers serves all 20 studies, so the workers start once.
    tasks = []
    for seed in range(1, 21):
        root = tmp_path / f"ab-{seed}"
        assert main(["design", "--ab", "--seed", str(seed), "--study", str(root)]) == 0
        folder = StudyFolder(root)
        folder.path(RUNS).mkdir()  # `trials run` makes it when it takes the study's lock
        arm = next(label for label, level in folder.read_sealed().arms.items() if level == LATTICE)
        tasks += [((str(root), row["run_code"]), (str(root), row["run_code"]))
                  for row in folder.read_plan() if row["Controller"] == arm]
    capsys.readouterr()
    with WorkerPool(2, StudyRows, (), USER_ERRORS) as pool:
        pool.ready()
        statuses = dict(pool.run(tasks))
    assert len(statuses) == 180
    # None stands until the timeout (the freeze this guards against), and none drives into anyone: a contact (seed 17
    # has one, a head-on walker) is the walker's, reaching a robot that had braked to a stop.
    others = {(Path(root).name, code): status for (root, code), status in statuses.items() if status != "goal"}
    assert set(others.values()) <= {"collision"}
    for (root, code), status in statuses.items():
        if status == "collision":
            speed = read_run(StudyFolder(Path(root)).path(RUNS) / f"{code}.mcap").velocity[-1, 0]
            assert abs(speed) < 0.05, (root, code, speed)
