"""Controllers from outside the toolkit: a study's `[controllers]` table and installed packages' entry points are found,
built, driven and recorded as the built-in ones are; one that fails to import, raises, answers late or answers outside
the interface is a one-line error or a failed run with its reason, never a traceback."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from robot_logs.physical import T_OBS
from robot_logs.run_log import read_run
from tests.support.example_plugin import EXAMPLE, NAME, SOURCE, install_example
from trials.cli import main
from trials.controllers import registry
from trials.controllers.base import Observation, Plan
from trials.controllers.checked import CheckedController, ControllerFault
from trials.controllers.plugins import STUDY_TABLE, PluginError, Source, read_table
from trials.outcomes import read_outcomes
from trials.study import OUTCOMES, StudyFolder

#: A lab's planner kept in the study folder: straight to the goal at 0.8 m/s; `make_raising` raises on its 5th plan,
#: `make_malformed` answers one way-point too few coordinates, `make_nothing` builds an object with no plan method.
PLANNER = '''
import os
import numpy as np
from trials.controllers.base import Plan

class Straight:
    def __init__(self, fail_at=None, malformed=False):
        self.fail_at, self.malformed, self.plans, self.ended = fail_at, malformed, 0, []

    def details(self):
        return {"speed": 0.8, "controller": "a name of its own", "seed": "its own seed"}  # never replace the run's

    def reset(self, seed):
        self.plans = 0
        print("lab_straight starts a run", flush=True)  # a blinded study must not show this
        os.write(2, b"lab_straight writes to stderr\\n")

    def end(self, status):
        self.ended.append(status)

    def plan(self, observation):
        self.plans += 1
        if self.plans == self.fail_at:
            raise ZeroDivisionError("the lab's bug")
        here = np.asarray(observation.robot_pose[:2], dtype=float)
        to_goal = np.asarray(observation.goal, dtype=float) - here
        points = here + 0.8 * 0.4 * np.arange(1, 13)[:, None] * to_goal / max(np.hypot(*to_goal), 1e-9)
        return Plan(points[:, :1] if self.malformed else points, 0.4, {"plans": self.plans})

def make():
    return Straight()

def make_raising():
    return Straight(fail_at=5)

def make_malformed():
    return Straight(malformed=True)

def make_nothing():
    return object()
'''

SPEC = """
[study]
name = "plug-in"
runs = 6
model = "main"
seed = 11

[[factors]]
name = "Pedestrians"
type = "discrete"
levels = [2, 4]

[[factors]]
name = "Controller"
type = "categorical"
levels = ["Lattice", "{arm}"]

[[factors]]
name = "Direction"
type = "fixed"
value = "Parallel"

[[factors]]
name = "CrossingDistance"
type = "fixed"
value = 2

[controllers]
Mine = "lab_straight:make"
Raising = "lab_straight:make_raising"
Malformed = "lab_straight:make_malformed"
"""


def alone() -> Observation:
    return Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)), (), np.zeros((0, T_OBS, 2)))


def study_with(tmp_path: Path, arm: str) -> StudyFolder:
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "lab_straight.py").write_text(PLANNER, encoding="utf-8")
    (folder / "study.toml").write_text(SPEC.format(arm=arm), encoding="utf-8")
    assert main(["design", "--study", str(folder), "--power", "0", "--quiet"]) == 0
    return StudyFolder(folder)


@pytest.mark.slow
def test_a_study_tables_controller_is_run_and_recorded_as_a_built_in_one(tmp_path):
    study = study_with(tmp_path, "Mine")
    assert main(["run", "--study", str(study.root)]) == 0
    outcomes = read_outcomes(study.path(OUTCOMES), False)
    mine = [row for row in outcomes if row.controller == "Mine"]
    planned = [row["run_code"] for row in study.read_plan() if row["Controller"] == "Mine"]
    assert sorted(row.run_code for row in mine) == sorted(planned) and all(row.status == "goal" for row in mine)
    # the run log names the controller, its details and where it came from
    metadata = read_run(study.run_log(mine[0].run_code)).metadata
    assert metadata["controller"] == "Mine" and metadata["speed"] == "0.8" and metadata["seed"] == str(mine[0].seed)
    assert metadata["source"] == f"{STUDY_TABLE} (lab_straight:make)"


@pytest.mark.slow
def test_a_plug_in_that_raises_fails_its_runs_with_one_line_and_no_traceback(tmp_path, capsys):
    study = study_with(tmp_path, "Raising")
    assert main(["run", "--study", str(study.root)]) == 1
    err = capsys.readouterr()
    assert "Traceback" not in err.out + err.err
    failed = sorted(study.root.glob("runs/*.failed.txt"))
    planned = sorted(row["run_code"] for row in study.read_plan() if row["Controller"] == "Raising")
    assert sorted(p.name.split(".")[0] for p in failed) == planned
    assert {p.read_text() for p in failed} == {"ZeroDivisionError: the lab's bug\n"}
    assert {row.controller for row in read_outcomes(study.path(OUTCOMES), False)} == {"Lattice"}


@pytest.mark.slow
def test_a_malformed_plan_fails_the_run_naming_what_is_wrong(tmp_path):
    study = study_with(tmp_path, "Malformed")
    assert main(["run", "--study", str(study.root)]) == 1
    reasons = {p.read_text() for p in study.root.glob("runs/*.failed.txt")}
    assert reasons == {"the controller's plan has way-points of shape (12, 1), not (K, 2) numbers with K >= 1\n"}


@pytest.mark.slow
def test_what_a_plug_in_prints_never_reaches_the_console_of_a_blinded_study(tmp_path):
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "lab_straight.py").write_text(PLANNER, encoding="utf-8")
    (folder / "study.toml").write_text('[controllers]\nMine = "lab_straight:make"\n', encoding="utf-8")
    trials = [sys.executable, "-m", "trials.cli"]
    subprocess.run([*trials, "design", "--arms", "Lattice,Mine", "--runs", "8", "--model", "Pedestrians + Controller", "--power", "0",
                    "--study", str(folder)], check=True, capture_output=True)
    assert not (folder / "lab_straight.py").read_text().count("Mine")  # the module names itself, not its arm
    run = subprocess.run([*trials, "run", "--blind", "--study", str(folder)], capture_output=True, text=True)
    assert run.returncode == 0 and "8 runs finished" in run.stdout, run.stdout + run.stderr
    assert "lab_straight" not in run.stdout + run.stderr
    assert "Mine" not in StudyFolder(folder).path("study.toml").read_text()  # its [controllers] table went under sealed/
    assert "Mine" in StudyFolder(folder).path("sealed/controllers.toml").read_text()


@pytest.mark.slow
def test_a_study_with_the_robots_navigation_stack_runs_live_only(tmp_path):
    folder = tmp_path / "study"
    trials = [sys.executable, "-m", "trials.cli"]
    subprocess.run([*trials, "design", "--arms", "NavStack,Lattice", "--runs", "8", "--model", "Pedestrians + Controller", "--power", "0",
                    "--study", str(folder)], check=True, capture_output=True)
    run = subprocess.run([*trials, "run", "--blind", "--study", str(folder)], capture_output=True, text=True)
    assert run.returncode == 2, run.stdout + run.stderr
    assert run.stderr.strip().splitlines()[-1].endswith("one of this study's controllers plans on the robot: the study runs live only "
                                                        "(trials run --robot URI)")
    assert "Traceback" not in run.stderr and not list(folder.glob("runs/*.mcap"))


@pytest.mark.slow
@pytest.mark.parametrize(("reference", "expected"), [
    ("absent_module:make", "cannot import 'absent_module': ModuleNotFoundError: No module named 'absent_module'"),
    ("lab_straight:missing", "module 'lab_straight' has no 'missing'"),
    ("lab_straight:make_nothing", "its factory returned object, which has no plan(observation) method"),
])
def test_a_plug_in_that_cannot_be_built_stops_trials_run_in_one_line(tmp_path, capsys, reference, expected):
    study = study_with(tmp_path, "Mine")
    spec = study.path("study.toml")
    spec.write_text(spec.read_text(encoding="utf-8").replace('"lab_straight:make"', f'"{reference}"'), encoding="utf-8")
    capsys.readouterr()
    assert main(["run", "--study", str(study.root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err == f"error: controller 'Mine' from {STUDY_TABLE} ({reference}): {expected}\n"
    assert not list(study.root.glob("runs/*.mcap")) and not study.path(OUTCOMES).exists()


def test_the_table_is_checked_when_read(tmp_path):
    spec = tmp_path / "study.toml"
    spec.write_text('[controllers]\nMine = "no colon"\n', encoding="utf-8")
    with pytest.raises(PluginError, match=r"\[controllers\] Mine: expected \"module:factory\".*got 'no colon'"):
        read_table(spec)
    spec.write_text('[controllers]\n"A,B" = "m:f"\n', encoding="utf-8")
    with pytest.raises(PluginError, match="controller name 'A,B' must be"):
        read_table(spec)


def test_a_name_offered_twice_is_refused_naming_both():
    with pytest.raises(PluginError, match=r"two controllers are called 'Lattice': built-in navtrials.* and study.toml"):
        registry.sources({"Lattice": "lab:make"})


class Slow:
    def plan(self, observation: Observation) -> Plan:
        time.sleep(0.3)
        return Plan(np.zeros((12, 2)))


@pytest.mark.parametrize(("answer", "reason"), [
    ([[0.0, 0.0]] * 12, "the controller answered a list, not a trials.controllers.base.Plan"),
    (Plan(np.full((12, 2), np.nan)), "the controller's plan has a way-point that is not finite"),
    (Plan(np.zeros((0, 2))), "the controller's plan has way-points of shape (0, 2), not (K, 2) numbers with K >= 1"),
    (Plan(np.zeros((12, 2)), step=0.0), "the controller's plan has step 0.0, not a positive number of seconds"),
    (Plan(np.zeros((12, 2)), record=[1]), "the controller's plan has a record of type list, not a dict"),
])
def test_an_answer_outside_the_interface_is_a_fault_naming_no_controller(answer, reason):
    class Answers:
        def plan(self, observation: Observation) -> object:
            return answer

    checked = CheckedController(Answers(), "Mine", Source("Mine", STUDY_TABLE, "lab:make"))
    with pytest.raises(ControllerFault) as caught:
        checked.plan(alone())
    assert str(caught.value) == reason


def test_a_late_plan_is_a_fault_and_only_plan_is_required():
    checked = CheckedController(Slow(), "Slow", Source("Slow", STUDY_TABLE, "lab:make"), limit_s=0.05)
    checked.reset(3)  # Slow has no reset, end or details: they are optional
    checked.end("goal")
    assert checked.details() == {"source": f"{STUDY_TABLE} (lab:make)"}
    with pytest.raises(ControllerFault, match=r"the controller took 0\.\d s to plan \(the limit is 0\.05 s\)"):
        checked.plan(alone())
    assert CheckedController(Slow(), "Slow", Source("Slow", STUDY_TABLE, "lab:make"), limit_s=None).plan(alone()).waypoints.shape == (12, 2)


def test_trials_controllers_lists_and_checks_every_source(tmp_path, capsys):
    study = study_with(tmp_path, "Mine")
    capsys.readouterr()
    assert main(["controllers", "--study", str(study.root)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == ["NaviGAN-R", "Lattice", "SocialForce", "ORCA", "NavStack", "Mine", "Raising",
                                                         "Malformed"]
    assert lines[5].split(None, 1)[1] == f"{STUDY_TABLE} (lab_straight:make)"
    assert main(["controllers", "--study", str(study.root), "--check"]) == 2
    out = capsys.readouterr().out
    assert "Traceback" not in out
    checked = dict(line.split(None, 1) for line in out.splitlines())
    assert checked["Raising"].endswith(" plans" + checked["Raising"].split(" plans", 1)[1])  # its first plan is sound
    assert checked["Malformed"].endswith("FAILS: the controller's plan has way-points of shape (12, 1), not (K, 2) numbers with K >= 1")
    assert all("plans (" in checked[name] for name in ("NaviGAN-R", "Lattice", "SocialForce", "ORCA", "Mine"))
    assert checked["NavStack"].endswith("live only: the robot's stack plans (trials run --robot URI)")


@pytest.mark.slow
def test_an_installed_package_is_found_by_its_entry_point_and_passes_its_own_tests(tmp_path):
    env = install_example(tmp_path / "site")
    listed = subprocess.run([sys.executable, "-m", "trials.cli", "controllers", "--check"], env=env, capture_output=True, text=True)
    assert listed.returncode == 0, listed.stderr
    gap_keeper = next(line for line in listed.stdout.splitlines() if line.startswith(f"{NAME} "))
    assert f"{SOURCE}  plans (" in gap_keeper
    own = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-o", "addopts=", str(EXAMPLE / "tests")],
                         env=env, capture_output=True, text=True, cwd=tmp_path)
    assert own.returncode == 0 and "4 passed" in own.stdout, own.stdout + own.stderr
