"""Staging and checking live runs without a robot: the start and goal of a row in each kind of frame, the start
tolerance, the start mark's file, the manipulation check's count, and live_checks.csv's reader and its refusals."""

from __future__ import annotations

import math

import pytest

from robot_logs.frames import Pose2D
from tests.support.console import design_study
from trials.errors import StudyError
from trials.live_checks import FILE, flag_of, read_check_log, read_checks, record_check, record_decision
from trials.robot.people_check import PeopleCounter
from trials.robot.settings import RobotSettings
from trials.robot.staging import MARK_FILE, Stage, StagedScene, StartMark, off_start, read_mark, row_scenario, stage_of, write_mark
from trials.study import StudyFolder


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> StudyFolder:
    return StudyFolder(design_study(tmp_path_factory.mktemp("staging") / "study"))


def test_a_rows_start_and_goal_in_each_frame(study, tmp_path):
    row = {"Direction": "Parallel"}
    settings = RobotSettings(start=(1.0, 0.5, 0.2), goals={"Parallel": (9.0, 0.5)})
    assert stage_of(RobotSettings(goal_frame="start"), row, study) is None
    assert stage_of(RobotSettings(goal_frame="map", start=(1.0, 0.5, 0.2)), row, study) == Stage("map", Pose2D(1.0, 0.5, 0.2), (10.0, 0.0))
    folder = StudyFolder(tmp_path)
    with pytest.raises(StudyError, match=r"no start mark in .*trials run --robot URI --mark"):
        stage_of(settings, row, folder)
    write_mark(folder, StartMark("odom", Pose2D(2.0, -1.0, math.pi / 2), "2026-12-05T10:00:00+00:00"))
    assert read_mark(folder) == StartMark("odom", Pose2D(2.0, -1.0, round(math.pi / 2, 5)), "2026-12-05T10:00:00+00:00")
    staged = stage_of(settings, row, folder)
    # The mark faces +y: 1 m ahead of it is +y, 0.5 m to its left is -x; the goal 9 m ahead and 0.5 m left of the mark.
    assert staged is not None and staged.frame == "odom"
    assert (staged.start.x, staged.start.y, staged.start.yaw) == pytest.approx((1.5, 0.0, math.pi / 2 + 0.2), abs=1e-4)
    assert staged.goal == pytest.approx((1.5, 8.0), abs=1e-4)  # the mark's yaw is kept to 5 decimals
    folder.path(MARK_FILE).write_text('{"frame": "odom", "pose": [1, "x", 0]}')
    with pytest.raises(StudyError, match=r"start_mark.json: field 'pose' must be \[x, y, yaw\]"):
        read_mark(folder)


def test_the_start_tolerance_in_metres_and_radians():
    stage = Stage("map", Pose2D(1.0, 2.0, 0.0), (11.0, 2.0))
    assert off_start(Pose2D(1.2, 2.1, 0.3), stage, (0.3, 0.35)) is None
    assert off_start(Pose2D(1.0, 2.84, 0.0), stage, (0.3, 0.35)) == (
        "the robot stands 0.84 m and 0 deg from its start (1.00, 2.00) facing 0 deg in map (tolerance 0.3 m, 20 deg)")
    assert "and 23 deg from its start" in off_start(Pose2D(1.0, 2.0, -0.4), stage, (0.3, 0.35))
    assert "and 180 deg" in off_start(Pose2D(1.0, 2.0, math.pi), stage, (0.3, 0.35))


def test_the_staged_scene_places_the_walkers_at_the_start():
    scenario = row_scenario(None, "", 3)
    scene = StagedScene.of(scenario, Stage("map", Pose2D(5.0, 0.0, math.pi), (-5.0, 0.0)), "ABCDE")
    lines = scene.lines()
    assert lines[0] == "Crossing, 4 pedestrians, crossing distance 2 m; positions in metres in map"
    assert lines[1] == "robot: start (5.00, 0.00) facing 180 deg, goal (-5.00, 0.00)"
    walker = scenario.walkers[0]
    x, y = 5.0 - walker.start[0], -walker.start[1]  # turned half round about the start
    assert lines[2].startswith(f"walker 1 (crossing): from ({x:.2f}, {y:.2f}) to ") and len(lines) == 2 + len(scenario.walkers)


def test_the_people_count_holds_a_second_before_it_counts():
    counter = PeopleCounter()
    for k in range(40):  # 4 s at 10 scans a second: 2 people, then 3 for 0.5 s (a false track), then 3 for 1.2 s
        t = k * 0.1
        counter.add(t, 3 if 1.0 <= t < 1.5 or 2.5 <= t < 3.75 else 2)
    check = counter.check(6, 0.5)
    assert (check.seen, check.seen_at_s, check.needed, check.met) == (3, 2.5, 3, True)
    assert counter.check(7, 0.5).describe() == "condition not met: at most 3 tracked at once (from 2.5 s), the row asks 7 (at least 4)"
    assert PeopleCounter().check(2, 0.5).describe() == "condition not met: at most 0 tracked at once, the row asks 2 (at least 1)"


def test_checks_flags_and_decisions(study, tmp_path):
    folder = StudyFolder(tmp_path)
    (tmp_path / "design.json").symlink_to(study.path("design.json"))
    (tmp_path / "plan.csv").symlink_to(study.path("plan.csv"))
    counted = PeopleCounter().check(4, 0.5)
    assert flag_of("goal", "", None) == "" and flag_of("collision", "", None) == ""
    assert flag_of("timeout", "after 60 s", None) == "timeout: after 60 s"
    record_check(folder, "AAAAA", "goal", "", counted, blind=True)
    record_check(folder, "BBBBB", "aborted", "stall: ...", None, blind=True)
    checks = read_checks(folder)
    assert checks["AAAAA"].flag.startswith("condition not met") and checks["AAAAA"].undecided
    assert (checks["BBBBB"].decision, checks["BBBBB"].condition_met) == ("rerun", None)
    with pytest.raises(StudyError, match="was aborted: it is no data"):
        record_decision(folder, "BBBBB", "stands", "fine", blind=True)
    with pytest.raises(StudyError, match="has no live check"):
        record_decision(folder, "CCCCC", "stands", "fine", blind=True)
    with pytest.raises(StudyError, match="decision must be one of stands, rerun"):
        record_decision(folder, "AAAAA", "keep", "fine", blind=True)
    record_decision(folder, "AAAAA", "stands", "two walkers came, the tracker merged them", blind=True)
    record_check(folder, "AAAAA", "goal", "", PeopleCounter().check(0, 0.5), blind=True)  # rerun later: a new attempt
    log = read_check_log(folder)
    assert [(c.run_code, c.decision, bool(c.flag)) for c in log] == [("AAAAA", "stands", True), ("BBBBB", "rerun", True), ("AAAAA", "", False)]
    with pytest.raises(StudyError, match="is not flagged"):
        record_decision(folder, "AAAAA", "rerun", "again", blind=True)
    assert all(c.recorded_utc.endswith(":00+00:00") for c in log)  # blinded: to the minute
    path = folder.path(FILE)
    path.write_text(path.read_text() + "AAAAA,2026-12-05T10:00:00+00:00,goal,4,2,1.0,maybe,,,\n")
    with pytest.raises(StudyError, match=r"line 6 of live_checks.csv: condition must be empty, 'met' or 'not met', got 'maybe'"):
        read_checks(folder)


def test_status_names_the_undecided_and_mark_needs_a_robot(study, capsys):
    from trials.cli import main

    assert main(["run", "--mark", "--study", str(study.root)]) == 2
    assert "--mark measures the start mark on a robot: give --robot URI" in capsys.readouterr().err
    record_check(study, study.read_plan()[0]["run_code"], "timeout", "after 60 s", None, blind=True)
    assert main(["status", "--study", str(study.root)]) == 0
    code = study.read_plan()[0]["run_code"]
    assert f"live checks: 1 run(s); flagged without a decision: {code} (`trials deviation" in capsys.readouterr().out
    assert main(["deviation", code, "--stands", "--reason", "the robot waited for a walker who stood still", "--study", str(study.root)]) == 0
    assert main(["status", "--study", str(study.root)]) == 0
    assert "live checks: 1 run(s); no flagged run awaits a decision" in capsys.readouterr().out
