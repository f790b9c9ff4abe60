"""The robot's own navigation stack as an arm, live against the software robot over a real ROS 1 master (move_base,
through actionlib) and over DDS (Nav2's NavigateToPose): a stand-in stack, its own process, gets the row's goal and
drives the robot through the toolkit's relay; its goal is cancelled on every stop and zero is the last command the base
hears; in a blinded three-arm study with a pip-installed plug-in nothing public tells the arms apart."""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.support.blinding import assert_names_nothing, assert_the_key_unblinds_to_what_drove, trials
from tests.support.example_plugin import NAME
from tests.support.live_rig import TRIALS, Rig, assert_stopped_and_kept, design, live_rig, robot_over, set_robot_keys, wait_for
from tests.support.system_packages import need
from trials.outcomes import read_outcomes
from trials.robot.ros1 import DIST_PACKAGES
from trials.robot.ros1_navigation import INSTALL
from trials.study import OUTCOMES, StudyFolder

pytestmark = pytest.mark.slow

ARMS = ("Lattice", NAME, "NavStack")
#: What each controller's sealed record holds every step.
OWN_RECORD = {"Lattice": "expansions", NAME: "nearest_person_m", "NavStack": "navigation_stack"}
#: Any controller's name, module or package, or the stack arm's own words.
NAMED = re.compile(rb"lattice|sbpl|gapkeeper|gap_keeper|lab_planner|lab-planner|navstack|navigation stack|move_base|navigate_to_pose",
                   re.IGNORECASE)
#: nav2_msgs/action/NavigateToPose as Nav2 (Jazzy) defines it: goal, result and feedback.
NAVIGATE_TO_POSE = """geometry_msgs/PoseStamped pose
string behavior_tree
---
uint16 NONE=0
uint16 error_code
string error_msg
---
geometry_msgs/PoseStamped current_pose
builtin_interfaces/Duration navigation_time
builtin_interfaces/Duration estimated_time_remaining
int16 number_of_recoveries
float32 distance_remaining
"""


def start_stack(rig: Rig, heard: Path, *options: str) -> None:
    """The stand-in navigation stack in the rig, recording what it hears in `heard`."""
    if rig.uri.startswith("ros1://"):
        need(all(Path(DIST_PACKAGES, package).is_dir() for package in ("actionlib", "move_base_msgs")),
             "ROS 1's actionlib and move_base_msgs (Debian 12)", INSTALL)
    rig.start([TRIALS[0], "-m", "tests.support.nav_stack_server", rig.uri, str(heard), *options], "stack.log")
    wait_for(Path(f"{heard}.ready"), "the stand-in navigation stack", rig.processes)


def heard_by_stack(heard: Path) -> list[dict]:
    return [json.loads(line) for line in heard.read_text(encoding="utf-8").splitlines()] if heard.exists() else []


def decoded_goal(request_hex: str) -> object:
    """A NavigateToPose goal request as sent over DDS, decoded by rosbags from the .action text: past the 4-byte CDR
    encapsulation and rmw_cyclonedds_cpp's 16-byte request header, the SendGoal request of nav2_msgs."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    goal, _, _ = NAVIGATE_TO_POSE.split("---\n")
    store.register({**get_types_from_msg(goal, "nav2_msgs/action/NavigateToPose_Goal"),
                    **get_types_from_msg("unique_identifier_msgs/UUID goal_id\nnav2_msgs/action/NavigateToPose_Goal goal",
                                         "nav2_msgs/action/NavigateToPose_SendGoal_Request")})
    raw = bytes.fromhex(request_hex)
    return store.deserialize_cdr(raw[:4] + raw[20:], "nav2_msgs/action/NavigateToPose_SendGoal_Request")


def test_a_blinded_three_arm_study_with_the_robots_navigation_stack(tmp_path, plugin_env):
    uri, env = plugin_env
    study = StudyFolder(tmp_path / "study")
    # Six runs, two per arm, the controller the model's one factor: the whole study is driven, then reported.
    design_run = trials(env, "design", "--arms", ",".join(ARMS), "--runs", "6", "--model", "Controller", "--robot", uri, "--seed", "5",
                        "--power", "0", "--study", str(study.root))
    set_robot_keys(study.root, goal_frame='"odom"', goal="[5.0, 0.0]")  # a short way: six runs in about a minute
    codes = [row["run_code"] for row in study.read_plan()]
    heard = tmp_path / "stack.jsonl"
    with live_rig(uri, study.root, env) as rig:  # the stand-in stack is there for every run, whichever arm drives
        start_stack(rig, heard)
        run = rig.trials_run("--blind", operator=True)
        out, _ = run.communicate(b"\n" * (len(codes) - 1), timeout=900)  # the operator goes on after each row
        assert run.returncode == 0, rig.output()
        time.sleep(0.5)
        assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() > 100
        consoles = [design_run, subprocess.CompletedProcess([], 0, rig.output().encode(), b"")]
    finished = {row.run_code: row for row in read_outcomes(study.path(OUTCOMES), True)}
    assert set(finished) == set(codes) and all(row.status in ("goal", "collision") for row in finished.values())
    assert all(row.perception == "software-robot" for row in finished.values())
    consoles += [trials(env, "respond", "--simulate", "--allow-simulated", "--study", str(study.root)),
                 trials(env, "report", "--study", str(study.root))]
    primary = json.loads(study.path("report/report.json").read_text(encoding="utf-8"))["primary"]
    assert primary["arms"] == ["A", "B", "C"] and primary["k_arms"]["correction"] == "Holm"
    assert [(p["first"], p["second"]) for p in primary["k_arms"]["pairs"]] == [("A", "B"), ("A", "C"), ("B", "C")]
    assert_names_nothing(study, consoles, NAMED)
    assert_the_key_unblinds_to_what_drove(study, codes, OWN_RECORD)
    # The stack heard one goal per row of its arm, each the row's goal: (5, 0) in the odometry frame, facing away from
    # the start (0, 0); and after each a cancel, the run's end.
    arms = study.read_sealed().arms
    stack_rows = [row["run_code"] for row in study.read_plan() if arms[row["Controller"]] == "NavStack"]
    entries = heard_by_stack(heard)
    goals = [e for e in entries if "goal" in e]
    assert len(goals) == len(stack_rows) == 2
    for goal in goals:
        assert goal["goal"]["frame"] == "odom" and math.hypot(goal["goal"]["x"] - 5.0, goal["goal"]["y"]) < 0.05
        assert abs(goal["goal"]["yaw"]) < 0.05
        assert any("cancel" in e and e["wall_ns"] > goal["wall_ns"] for e in entries)
        if uri.startswith("ros2://"):
            request = decoded_goal(goal["request"])
            assert request.goal.pose.header.frame_id == "odom" and request.goal.behavior_tree == ""
            assert math.hypot(request.goal.pose.pose.position.x - 5.0, request.goal.pose.pose.position.y) < 0.05
            assert len(request.goal_id.uuid) == 16 and any(request.goal_id.uuid)


def press_estop(rig: Rig, run: subprocess.Popen) -> None:
    rig.start([TRIALS[0], "-m", "tests.support.press_estop", rig.uri, "/e_stop"], "estop.log")


def terminate(rig: Rig, run: subprocess.Popen) -> None:
    run.send_signal(signal.SIGTERM)


#: Stop rules tried on a stack driving the robot: the stop, the reason the run gives, the stand-in stack's options.
RULES = {
    "a stack that gives up": (None, "no plan within 1 s", ("--give-up-after", "3")),
    "the e-stop topic": (press_estop, "e-stop on /e_stop", ()),
    "SIGTERM": (terminate, "stopped by SIGTERM", ()),
}


@pytest.mark.parametrize(("rule", "kind"), [("a stack that gives up", "ros1"), ("a stack that gives up", "ros2"),
                                             ("the e-stop topic", "ros1"), ("SIGTERM", "ros2")])
def test_every_stop_cancels_the_stacks_goal_and_stops_the_robot(tmp_path, request, rule, kind):
    uri, env = robot_over(kind, request, tmp_path)
    stop, reason, options = RULES[rule]
    folder = tmp_path / "study"
    folder.mkdir()
    study = design(folder, uri, "--arms", "NavStack,Lattice", "--power", "0")
    code = next(row["run_code"] for row in study.read_plan() if study.read_sealed().arms[row["Controller"]] == "NavStack")
    heard = tmp_path / "stack.jsonl"
    with live_rig(uri, study.root, env) as rig:
        start_stack(rig, heard, *options)
        run = rig.trials_run("--only", code, "--blind")
        if stop is not None:
            deadline = time.monotonic() + 240
            while not (rig.heard.exists() and rig.moving_commands() > 20):
                assert time.monotonic() < deadline and run.poll() is None, rig.output()
                time.sleep(0.1)
            stop(rig, run)
        assert run.wait(timeout=300) != 0, rig.output()
        assert_stopped_and_kept(rig, study, code, reason)
        entries = heard_by_stack(heard)
        (goal,) = [e for e in entries if "goal" in e]
        assert any("cancel" in e and e["wall_ns"] > goal["wall_ns"] for e in entries), entries
