"""Live runs in a walled room over a real ROS 1 master: the software robot (`trials robot-sim`) stands in a room and
has a bumper, and a witness node hears every velocity command. A goal beyond a wall, a stalled base, a base that takes
another message type, scans that turn blank and a killed worker each end with a zero velocity as the last command
heard and the run aborted or flagged (never counted as clean data), and the bumper never touches the wall; a base that takes
TwistStamped is driven to its goal."""

from __future__ import annotations

import math
import time

import pytest

from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.run_log import ROBOT_STATE, SCAN
from tests.support.live_rig import TRIALS, assert_stopped_and_kept, design, first_code, live_rig, ros1_env, set_robot_keys
from trials.live_checks import read_checks
from trials.outcomes import read_outcomes
from trials.study import OUTCOMES

pytestmark = pytest.mark.slow

#: How far a run's closest gap may be from the ground truth (m): the person tracker's own error at 1-2 m, about 0.03 m
#: toward the laser, and the minimum of noisy estimates reading low.
GAP_TOLERANCE_M = 0.08
#: The room's far wall (y, m) and the robot's half footprint (m): a Husky's 0.99 x 0.67 m.
WALL_Y, HALF_LENGTH, HALF_WIDTH = 4.0, 0.495, 0.335


def test_a_goal_beyond_a_wall_stops_the_robot_before_it_touches_the_wall(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    # The goal 8 m to the left of the start, 4 m beyond the room's side wall: only the wall stands between.
    set_robot_keys(study.root, goal="[2.0, 8.0]", timeout="30.0")
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), (f"--room=-6,-5,16,{WALL_Y:g}",)) as rig:
        run = rig.trials_run("--only", code)
        ended = run.wait(timeout=300)
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() > 0
        assert rig.wall_contacts() == []
    # The controller, given the wall, holds the robot off it until the timeout (flagged, for the operator to decide); or
    # the protective field holds it and the run is aborted, pending. Either way it is no clean datum.
    check = read_checks(study)[code]
    if ended == 0:
        (row,) = read_outcomes(study.path(OUTCOMES))
        assert row.status == "timeout" and check.flag.startswith("timeout") and check.undecided
        log = study.run_log(code)
    else:
        assert ended == 1 and check.ending == "aborted" and "protective stop held 3 s" in check.flag, rig.output()
        [log] = (study.root / "runs" / "aborted").glob(f"{code}-*.mcap")
    states = [m.data for m in FoxgloveReader(log).messages([ROBOT_STATE.name])]
    # The footprint's corner nearest the wall, at every recorded pose: it came near, and stayed off it.
    reach = max(s["y"] + abs(HALF_LENGTH * math.sin(s["theta"])) + abs(HALF_WIDTH * math.cos(s["theta"])) for s in states)
    assert WALL_Y - 1.5 < reach < WALL_Y - 0.02, reach


@pytest.mark.parametrize("robot, reason", [
    (("--fault", "stall@3"), "stall: the commands of the last 2 s would have moved it"),
    (("--cmd-vel-type", "TwistStamped"), "the base does not respond to Twist on /cmd_vel"),
])
def test_a_base_that_does_not_move_as_commanded_ends_the_run(tmp_path, master, robot, reason):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), robot) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, reason)


def test_a_base_that_takes_twiststamped_is_driven_to_its_goal(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    set_robot_keys(study.root, cmd_vel_type='"TwistStamped"', cmd_vel_frame='"base_footprint"')
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), heard_type="TwistStamped") as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() > 20
        assert rig.wall_contacts() == []
    (row,) = read_outcomes(study.path(OUTCOMES))
    assert row.status in ("goal", "collision") and row.path_length_m > 1.0, row


def test_a_killed_worker_leaves_the_robot_stopped_and_the_run_aborted_with_its_log(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri, "--ab")
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        run = rig.trials_run("--only", code)
        rig.wait_state("driving")
        time.sleep(3.0)
        worker = rig.worker(run)
        rig.start(["kill", "-9", str(worker)], "kill.log").wait()
        assert run.wait(timeout=300) == 2, rig.output()  # the command stops: a worker process died
        state = rig.wait_state("aborted")
        assert state["detail"] == "the worker driving the run died (SIGKILL)", state
        time.sleep(0.5)
        assert rig.moving_commands() > 0 and rig.last_heard() == (0.0, 0.0)
        failure = study.run_failure(code).read_text(encoding="utf-8")
    [kept] = (study.root / "runs" / "aborted").glob(f"{code}-*.mcap")
    assert failure.startswith(f"run {code} aborted: the worker driving the run died") and str(kept) in failure
    reader = FoxgloveReader(kept)  # what the worker had written, recovered into a finished log
    assert len(list(reader.messages([SCAN.name]))) > 20 and len(list(reader.messages([ROBOT_STATE.name]))) > 20
    assert kept.stat().st_mtime_ns % 60_000_000_000 == 0  # a blinded study's public times are to the minute
    assert not study.run_log(code).exists() and not list((study.root / "runs").glob(".*partial"))
    assert read_outcomes(study.path(OUTCOMES), True) == []


def test_the_closest_gap_and_the_collision_call_agree_with_the_ground_truth(tmp_path, master):
    """The laser's scans reach the computer 0.25 s after their stamps, as a real laser driver's do; odometry comes at
    once. Pairing the people a scan saw with the robot where odometry has it since read the closest gap 0.13-0.18 m low
    (4 runs of this study's Parallel rows); paired with the robot where it stood at the scan's stamp, it is within
    0.04 m of the software robot's ground truth there."""
    uri, _ = master
    study = design(tmp_path / "study", uri)
    code = first_code(study)  # Parallel, 2 walkers coming toward the robot on lanes 0.5 m either side of its path
    with live_rig(str(uri), study.root, ros1_env(tmp_path), ("--scan-latency", "0.25")) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
        (row,) = read_outcomes(study.path(OUTCOMES))
        start = int(FoxgloveReader(study.run_log(code)).metadata["run"]["robot_start_stamp_ns"])
        _, gaps = rig.true_gaps(start, start + int(row.duration_s * 1e9))
    assert row.min_distance_m is not None and abs(row.min_distance_m - gaps.min()) <= GAP_TOLERANCE_M, (row.min_distance_m, gaps.min())
    assert (row.status == "collision") == (gaps.min() <= 0.0), (row.status, gaps.min())


def test_without_only_the_next_row_waits_for_the_operator(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    first, second = [row["run_code"] for row in study.read_plan()[:2]]
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        run = rig.trials_run("--only", first, second, operator=True)
        deadline = time.monotonic() + 240
        while f"Next: order 2, {second}" not in rig.output():
            assert time.monotonic() < deadline and run.poll() is None, rig.output()
            time.sleep(0.2)
        heard = rig.moving_commands()
        time.sleep(3.0)  # the robot stands while the operator stages the row
        assert rig.moving_commands() == heard and rig.last_heard() == (0.0, 0.0)
        assert run.communicate(b"q\n", timeout=60) is not None and run.returncode == 0, rig.output()
    assert [row.run_code for row in read_outcomes(study.path(OUTCOMES))] == [first]


def test_an_estop_ends_the_session_and_a_held_one_keeps_every_later_row_from_starting(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    first, second = [row["run_code"] for row in study.read_plan()[:2]]
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        run = rig.trials_run("--only", first, second, operator=True)
        rig.wait_state("driving")
        time.sleep(2.0)
        rig.start([TRIALS[0], "-m", "tests.support.press_estop", rig.uri, "/e_stop"], "estop.log")  # held down, latched
        run.communicate(b"\n", timeout=300)  # an operator ready to go on: the session must not
        assert run.returncode == 1 and "E-STOP: this session stopped there" in rig.output(), rig.output()
        assert f"Next: order 2, {second}" not in rig.output()
        heard = rig.moving_commands()
        again = rig.trials_run("--only", second)  # a new session while the button is still held
        assert again.wait(timeout=300) == 1 and "did not start: e-stop on /e_stop (held)" in rig.output(), rig.output()
        assert rig.moving_commands() == heard and rig.last_heard() == (0.0, 0.0)
    assert read_outcomes(study.path(OUTCOMES)) == [] and set(read_checks(study)) == {first}
