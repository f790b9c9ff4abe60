"""A plug-in driving the robot live, over a real ROS 1 master and over DDS: one that stops answering is stopped by the
plan timeout, and one that raises stops the robot; either way zero is the last command heard and the run is kept aside,
never recorded as data."""

from __future__ import annotations

import json
import time

import pytest

from tests.support.live_rig import assert_stopped_and_kept, design, live_rig, set_robot_keys
from trials.outcomes import read_outcomes
from trials.study import ALLOCATION, OUTCOMES

pytestmark = pytest.mark.slow

#: Plans toward the goal at 0.8 m/s; after its 8th plan `make_stalling` thinks for a minute, `make_raising` raises.
PLANNER = '''
import time
import numpy as np
from trials.controllers.base import Plan

class Lab:
    def __init__(self, then):
        self.then, self.plans = then, 0

    def reset(self, seed):
        self.plans = 0

    def plan(self, observation):
        self.plans += 1
        if self.plans > 8:
            self.then()
        here = np.asarray(observation.robot_pose[:2], dtype=float)
        to_goal = np.asarray(observation.goal, dtype=float) - here
        return Plan(here + 0.32 * np.arange(1, 13)[:, None] * to_goal / max(np.hypot(*to_goal), 1e-9))

def fail():
    raise RuntimeError("the lab's planner broke")

def make_stalling():
    return Lab(lambda: time.sleep(60.0))

def make_raising():
    return Lab(fail)
'''


def lab_study(tmp_path, uri: str, arm: str):
    """A blinded study of the lattice planner and the lab's planner `arm`, its first row driven by the lab's."""
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "lab_planner_live.py").write_text(PLANNER, encoding="utf-8")
    (folder / "study.toml").write_text(f'[controllers]\n{arm} = "lab_planner_live:make_{arm.lower()}"\n', encoding="utf-8")
    study = design(folder, uri, "--arms", f"Lattice,{arm}", "--power", "0")
    set_robot_keys(folder, plan_timeout="0.5")
    label = next(label for label, name in json.loads(study.path(ALLOCATION).read_text())["arms"].items() if name == arm)
    return study, next(row["run_code"] for row in study.read_plan() if row["Controller"] == label)


def test_a_plug_in_that_stops_answering_is_stopped_by_the_plan_timeout(tmp_path, middleware):
    uri, env = middleware
    study, code = lab_study(tmp_path, uri, "Stalling")
    with live_rig(uri, study.root, env) as rig:
        run = rig.trials_run("--only", code, "--blind")
        assert run.wait(timeout=300) == 1, rig.output()
        assert_stopped_and_kept(rig, study, code, "no plan within 0.5 s")


def test_a_plug_in_that_raises_stops_the_robot(tmp_path, middleware):
    uri, env = middleware
    study, code = lab_study(tmp_path, uri, "Raising")
    with live_rig(uri, study.root, env) as rig:
        run = rig.trials_run("--only", code, "--blind")
        assert run.wait(timeout=300) == 1, rig.output()
        state = rig.wait_state("aborted")
        assert state["detail"] == "an exception stopped the run"
        time.sleep(0.5)  # commands in flight reach the witness
        assert rig.last_heard() == (0.0, 0.0) and rig.moving_commands() > 0
        assert "broke" not in rig.output() and "lab_planner_live" not in rig.output()  # blinded: sealed, not shown
        assert len(list((study.root / "runs" / "aborted").glob(f"{code}-*.mcap"))) == 1
        assert code not in {row.run_code for row in read_outcomes(study.path(OUTCOMES), True)}
