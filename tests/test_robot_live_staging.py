"""Staging live runs over a real ROS 1 master with the software robot: the start mark measured on the robot, a row
started from its start pose relative to it, a robot left off its start refused, and a row whose walkers never came
flagged, decided and rerun (the protocol-deviation log), counted per arm in the report."""

from __future__ import annotations

import json
import math
import subprocess

import pytest

from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.run_log import EVENTS, ROBOT_STATE
from tests.support.live_rig import TRIALS, design, first_code, live_rig, ros1_env, set_robot_keys
from trials.live_checks import FILE, read_check_log, read_checks
from trials.outcomes import read_outcomes
from trials.study import OUTCOMES

pytestmark = pytest.mark.slow


def trials(rig, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*TRIALS, *args, "--study", str(rig.study)], env=rig.env, capture_output=True, text=True, timeout=300)


def test_rows_start_and_end_relative_to_the_measured_start_mark(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri, frame="mark")
    # Every row starts 1 m ahead and 0.5 m to the left of the mark, turned 0.3 rad, and ends 8 m ahead of the mark.
    set_robot_keys(study.root, start="[1.0, 0.5, 0.3]", goal="[8.0, 0.5]")
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path)) as rig:
        unmarked = rig.trials_run("--only", code)
        assert unmarked.wait(timeout=300) == 1
        assert "no start mark" in rig.output() and "trials run --robot URI --mark" in rig.output()
        assert not (study.root / OUTCOMES).exists() and rig.moving_commands() == 0
        marked = trials(rig, "run", "--robot", str(uri), "--mark")
        assert marked.returncode == 0, marked.stderr
        mark = json.loads((study.root / "start_mark.json").read_text(encoding="utf-8"))
        assert mark["frame"] == "odom" and max(abs(v) for v in mark["pose"]) < 0.05, mark  # the software robot stands at odom's origin
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
    events = [m.data for m in FoxgloveReader(study.run_log(code)).messages([EVENTS.name])]
    gx, gy = (float(v) for v in events[0]["detail"].split("(")[1].split(")")[0].split(","))
    assert math.hypot(gx - 8.0, gy - 0.5) < 0.06, events[0]  # the goal, placed by the mark
    first = next(FoxgloveReader(study.run_log(code)).messages([ROBOT_STATE.name])).data
    assert math.hypot(first["x"] - 1.0, first["y"] - 0.5) < 0.35 and abs(first["theta"] - 0.3) < 0.35, first


def test_a_robot_left_off_its_start_is_not_driven(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri)
    set_robot_keys(study.root, start="[2.0, 0.0]", sensor_wait="4.0")
    code = first_code(study)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), ("--unstaged", "robot")) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 1, rig.output()
        assert "no start after 4 s: the robot stands 2.00 m and 0 deg from its start (2.00, 0.00) facing 0 deg in odom" in rig.output()
        assert rig.moving_commands() == 0 and rig.last_heard() == (0.0, 0.0)
    assert not (study.root / OUTCOMES).exists() and not (study.root / FILE).exists()  # never started: no data, nothing to decide


def test_a_row_whose_walkers_never_came_is_flagged_decided_and_rerun(tmp_path, master):
    uri, _ = master
    study = design(tmp_path / "study", uri, "--ab")
    code = next(row["run_code"] for row in study.read_plan() if int(row["Pedestrians"]) >= 4)
    with live_rig(str(uri), study.root, ros1_env(tmp_path), ("--unstaged", "walkers")) as rig:
        run = rig.trials_run("--only", code)
        assert run.wait(timeout=300) == 0, rig.output()
    (row,) = read_outcomes(study.path(OUTCOMES), True)
    check = read_checks(study)[code]
    assert (check.ending, check.seen, check.condition_met, check.decision) == (row.status, 0, False, "")
    assert f"condition not met: at most 0 tracked at once, the row asks {check.asked} (at least {math.ceil(check.asked / 2)})" in check.flag
    assert check.recorded_utc.endswith(":00+00:00")  # a blinded study's times, to the minute
    listed = trials(rig, "deviation")
    assert listed.returncode == 0 and f"{code}  condition not met" in listed.stdout and "1 undecided" in listed.stdout
    refused = trials(rig, "deviation", code, "--rerun")
    assert refused.returncode == 2 and "needs its reason" in refused.stderr
    stands = trials(rig, "deviation", code, "--stands", "--reason", "the walkers were late; the robot drove among none")
    assert stands.returncode == 0, stands.stderr
    report = trials(rig, "report")
    assert report.returncode == 0, report.stderr
    text = (study.root / "report" / "report.md").read_text(encoding="utf-8")
    assert "## Live runs: manipulation checks and deviations" in text and "the walkers were late" in text
    assert "| all arms | 1 | 0 | 1 | 1 | 0 | 0 |" in text, text  # 1 of 18 runs finished: the blinded report pools the arms
    looked = trials(rig, "report", "--interim", "the deviation log, by arm")
    assert looked.returncode == 0, looked.stderr
    arm = next(r["Controller"] for r in study.read_plan() if r["run_code"] == code)
    assert f"| {arm} | 1 | 0 | 1 | 1 | 0 | 0 |" in (study.root / "report" / "report.md").read_text(encoding="utf-8")
    decided = trials(rig, "deviation", code, "--rerun", "--reason", "the walkers were not staged")
    assert decided.returncode == 0, decided.stderr
    assert read_outcomes(study.path(OUTCOMES), True) == [] and not study.run_log(code).exists()  # pending again, kept in superseded/
    assert [c.decision for c in read_check_log(study)] == ["rerun"] and "rerun" in trials(rig, "deviation").stdout
