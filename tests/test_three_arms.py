"""A blinded study of three arms end to end in the simulator: NaviGAN-R, the lattice planner and a lab's planner from a
package the toolkit has never seen (the example plug-in, pip-installed into a folder of its own). No public file or
console line names a controller, the key unblinds each arm to the controller that really drove it, and the report has
the planned k-arm analysis. Live, with the robot's own navigation stack as the third arm: tests/test_nav_stack_live.py."""

from __future__ import annotations

import json
import re

import pytest

from tests.support.blinding import assert_names_nothing, assert_the_key_unblinds_to_what_drove, trials
from tests.support.example_plugin import NAME, install_example
from tests.support.registration import recorded_digest
from trials.study import StudyFolder

pytestmark = pytest.mark.slow

ARMS = ("NaviGAN-R", "Lattice", NAME)
#: Any of the three controllers' names, their modules or their packages.
NAMED = re.compile(rb"navigan|lattice|sbpl|gapkeeper|gap_keeper|lab_planner|lab-planner", re.IGNORECASE)
#: What each controller's own record holds every step, in the sealed part: the evidence of which one drove.
OWN_RECORD = {"NaviGAN-R": "forces", "Lattice": "expansions", NAME: "nearest_person_m"}


def test_three_arms_in_the_simulator(tmp_path):
    env = install_example(tmp_path / "site")
    study = StudyFolder(tmp_path / "study")
    design = trials(env, "design", "--arms", ",".join(ARMS), "--seed", "21", "--power", "0", "--study", str(study.root))
    assert study.read_design()["blinding"]["arms"] == ["A", "B", "C"]
    counts = [row["Controller"] for row in study.read_plan()]
    assert sorted(counts) == ["A"] * 6 + ["B"] * 6 + ["C"] * 6  # 18 runs, balanced
    run = trials(env, "run", "--blind", "--study", str(study.root))
    respond = trials(env, "respond", "--simulate", "--study", str(study.root))
    report = trials(env, "report", "--study", str(study.root))
    assert_names_nothing(study, [design, run, respond, report], NAMED)
    assert_the_key_unblinds_to_what_drove(study, [row["run_code"] for row in study.read_plan()], OWN_RECORD)
    primary = json.loads(study.path("report/report.json").read_text(encoding="utf-8"))["primary"]
    assert primary["arms"] == ["A", "B", "C"] and primary["k_arms"]["correction"] == "Holm"
    assert [(p["first"], p["second"]) for p in primary["k_arms"]["pairs"]] == [("A", "B"), ("A", "C"), ("B", "C")]
    assert primary["p"] == primary["k_arms"]["global"]["p"] and 0.0 < primary["p"] <= 1.0
    # opened against the pre-registration's digest, the report names the controllers that drove
    trials(env, "report", "--unblind", "--commitment", recorded_digest(study.root), "--study", str(study.root))
    opened = json.loads(study.path("report/report.json").read_text(encoding="utf-8"))["primary"]
    arms = study.read_sealed().arms
    assert opened["arms"] == [arms[label] for label in ("A", "B", "C")]
    assert {(p["first"], p["second"]) for p in opened["k_arms"]["pairs"]} == {(arms[a], arms[b]) for a, b in (("A", "B"), ("A", "C"), ("B", "C"))}
