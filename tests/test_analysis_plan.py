"""The analysis plan: study.toml's [analysis] table as `trials design` writes and commits to it, its one-line errors,
its standing in the report's words, the digest recorded at each opening of the key, and its power at design time."""

from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from analysis.ab_table import RunJudgments
from analysis.models import DesignMatrix, Fit, Parameter
from analysis.plan import SENSITIVITY, AnalysisPlan, PlanStatus, default_plan
from analysis.primary import arm_effect, primary_analysis, sensitivity_fit
from analysis.records import StudyData
from tests.support.run_studies import SMALL_SPEC
from trials.analysis_plan import committed_digest, plan_from_table
from trials.cli import main
from trials.study import StudyFolder
from trials.study_data import PLAN_KEY, Opening, load_study, opened_record


@pytest.fixture(scope="module")
def ab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("plan") / "ab"
    assert main(["design", "--ab", "--seed", "3", "--power", "0", "--study", str(root)]) == 0
    return root


def table(root: Path) -> dict[str, object]:
    return tomllib.loads((root / "study.toml").read_text())["analysis"]


def test_design_writes_the_default_plan_and_commits_to_it(ab: Path) -> None:
    written = table(ab)
    assert written == {"outcome": "compliant", "factor": "Controller", "test": "randomization", "model": "Controller", "strata": [],
                       "exploratory": "main + interactions + Pedestrians^2", "alpha": 0.05, "sensitivity": list(SENSITIVITY),
                       "draws": 20000, "seed": 3, "gee_covariance": "mancl-derouen", "gee_alpha": "statsmodels"}
    plan = AnalysisPlan(**{**written, "strata": (), "sensitivity": SENSITIVITY})  # type: ignore[arg-type]
    assert committed_digest(json.loads((ab / "design.json").read_text())) == plan.digest()


def test_a_study_without_arms_plans_the_gee_of_its_model(tmp_path: Path) -> None:
    assert main(["design", "--seed", "2", "--runs", "8", "--starts", "5", "--power", "0", "--study", str(tmp_path)]) == 0
    written = table(tmp_path)
    assert (written["factor"], written["test"], written["model"], written["exploratory"]) == ("", "gee", "main", "")


def test_a_blocked_study_re_randomizes_within_its_blocks(tmp_path: Path) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text('[study]\nname = "b"\nruns = 8\nmodel = "main"\nblocks = 2\n\n[[factors]]\nname = "Controller"\ntype = "categorical"\n'
                    'levels = ["NaviGAN-R", "Lattice"]\n\n[[factors]]\nname = "Pedestrians"\ntype = "discrete"\nlevels = [2, 4]\n')
    assert main(["design", "--spec", str(spec), "--seed", "1", "--power", "0", "--study", str(tmp_path / "s")]) == 0
    written = table(tmp_path / "s")
    assert (written["model"], written["strata"], written["exploratory"]) == ("Controller + Block", ["Block"], "main + Block")


@pytest.mark.parametrize(("line", "message"), [
    ('test = "t"', "[analysis]: test must be one of 'randomization', 'gee', got 't'"),
    ('factor = "Pedestrians"', "[analysis]: factor must be \"\" or a categorical factor of the study (Direction, Controller), got 'Pedestrians'"),
    ('model = "Pedestrians"', "[analysis]: model 'Pedestrians' must hold the compared factor 'Controller'"),
    ('strata = ["Controller"]', "[analysis]: strata must be a list of distinct names from Pedestrians, Direction, got ['Controller']"),
    ("alpha = 0.9", "[analysis]: alpha must be a number in (0, 0.5], got 0.9"),
    ('sensitivity = ["gee", "firth"]', "[analysis]: sensitivity must be a list of distinct names from gee-small-sample"),
    ("draws = 10", "[analysis]: draws must be a whole number in [100, 200000], got 10"),
    ('gee_alpha = "R"', "[analysis]: gee_alpha must be one of 'statsmodels', 'geepack', got 'R'"),
    ("colour = 1", "[analysis]: unknown key 'colour' (expected outcome, factor, test"),
])
def test_a_bad_key_is_one_line_naming_file_table_and_key(ab: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                         line: str, message: str) -> None:
    spec = tmp_path / "spec.toml"
    text = re.sub(r"\[analysis\].*", "", (ab / "study.toml").read_text(), flags=re.S)
    spec.write_text(text.replace('arms = [\n    "A",\n    "B",\n]', 'levels = ["NaviGAN-R", "Lattice"]') + f"[analysis]\n{line}\n")
    assert main(["design", "--spec", str(spec), "--study", str(tmp_path / "new")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"spec.toml {message}" in err
    assert not (tmp_path / "new" / "plan.csv").exists()


def test_the_report_says_how_the_plan_stands(ab: Path) -> None:
    plan = AnalysisPlan("compliant", "Controller", "randomization", "Controller", (), "main", 0.05, SENSITIVITY, 20000, 3)
    changed = AnalysisPlan("compliant", "Controller", "gee", "Controller", (), "main", 0.05, SENSITIVITY, 20000, 3)
    assert "the one committed to in design.json" in PlanStatus(plan, True, plan.digest()).describe()
    assert PlanStatus(changed, True, plan.digest()).describe().startswith("**The analysis plan changed while the sealed key is closed")
    after = PlanStatus(changed, True, plan.digest(), (plan.digest(),))
    assert after.changed_after_opening and "it was changed after the sealed key was opened" in after.describe()
    before = PlanStatus(changed, True, plan.digest(), (changed.digest(),))
    assert not before.changed_after_opening and "before the sealed key was first opened" in before.describe()
    unknown = PlanStatus(changed, True, plan.digest(), (None,))
    assert unknown.changed_after_opening and "cannot be ruled out" in unknown.describe()
    assert "commits to no plan" in PlanStatus(plan, False, None).describe()


def test_each_opening_of_the_key_records_the_plan_in_force(ab: Path) -> None:
    folder = StudyFolder(ab)
    record = json.loads(opened_record(folder, "c" * 64, "2026-01-01T00:00:00+00:00", Opening("18 of 18 runs finished", None), "test"))
    assert record["openings"][0][PLAN_KEY] == committed_digest(folder.read_design())


@pytest.mark.slow  # a design's power search and `trials power` on the same seeds, about 20 s
def test_design_time_power_of_the_planned_test_is_trials_powers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root, spec = tmp_path / "small", tmp_path / "spec.toml"
    spec.write_text(SMALL_SPEC.format(name="small-ab", blind="true"))
    assert main(["design", "--spec", str(spec), "--study", str(root), "--seed", "4", "--power", "12"]) == 0
    printed = capsys.readouterr().out
    at_design = dict(re.findall(r"^  (\d+) runs  power (\d\.\d{3})", printed, flags=re.M))
    assert list(at_design) == ["6", "12", "18", "24"][:len(at_design)] and len(at_design) >= 2
    sizes = ",".join(at_design)
    assert main(["power", "--study", str(root), "--out", str(tmp_path / "out"), "--seed", "4", "--simulations", "12", "--runs", sizes]) == 0
    record = json.loads((tmp_path / "out" / "power.json").read_text())
    by_power = {str(plan["runs"]): f"{plan['planned']['power']:.3f}" for plan in record["plans"]}
    assert by_power == at_design  # the same data sets: identical, not just within Monte Carlo error
    assert record["planned_test"] == "run-level randomization test of Controller, alpha 0.05"


def test_the_plans_gee_conventions_reach_its_gee_fits() -> None:
    plan = AnalysisPlan("compliant", "Controller", "randomization", "Controller", (), "", 0.05, SENSITIVITY, 20000, 3)
    geepack = AnalysisPlan(**{**plan.table(), "strata": (), "sensitivity": SENSITIVITY, "gee_alpha": "geepack",  # type: ignore[arg-type]
                              "gee_covariance": "kauermann-carroll"})
    arm = np.repeat([1.0, -1.0], 6)
    dm = DesignMatrix(np.column_stack([np.ones(12), arm]), ["Intercept", "Controller[A]"], [("Intercept", [0]), ("Controller", [1])])
    yes, total = np.array([4, 5, 3, 5, 4, 2, 2, 1, 3, 0, 2, 1.0]), np.full(12, 5.0)
    ours, theirs = (sensitivity_fit(p, "gee-small-sample", dm, yes, total) for p in (plan, geepack))
    assert "Mancl" in ours.method and "geepack" not in ours.method
    assert "geepack" in theirs.method and "Kauermann" in theirs.method
    # geepack's moment estimate divides by the plain counts, statsmodels' by the counts less the 2 columns.
    assert theirs.summary["within-run correlation"] != pytest.approx(ours.summary["within-run correlation"], rel=1e-4)
    independence = sensitivity_fit(geepack, "gee-independence", dm, yes, total)
    assert "independence" in independence.method and "Kauermann" in independence.method


def test_a_design_seed_past_2_to_the_53_is_a_plan_seed_too(ab: Path) -> None:
    folder = StudyFolder(ab)
    spec = load_study(folder, False, "2026-01-01T00:00:00+00:00").spec
    big = default_plan(spec, 2**63 - 1)
    assert plan_from_table(big.table(), spec, 0, "here").seed == 2**63 - 1


def test_a_plan_committed_again_after_the_key_was_opened_under_another_is_flagged() -> None:
    opened = AnalysisPlan("compliant", "Controller", "randomization", "Controller", (), "main", 0.05, SENSITIVITY, 20000, 3)
    now = AnalysisPlan("compliant", "Controller", "gee", "Controller", (), "main", 0.05, SENSITIVITY, 20000, 3)
    recommitted = PlanStatus(now, True, now.digest(), (opened.digest(),))  # e.g. `trials design --augment` after the opening
    assert recommitted.matches and recommitted.changed_after_opening
    assert recommitted.describe().startswith("**The analysis plan changed after the sealed key was opened")
    # an opening that recorded no plan (an earlier release) casts no doubt on a plan that is the committed one
    assert not PlanStatus(now, True, now.digest(), (None,)).changed_after_opening


def _judged(data: StudyData, arms_judged: dict[str, int]) -> list[RunJudgments]:
    """4 of 5 judgments yes for each run of the arms named, at most that many runs of each."""
    taken: dict[str, int] = {}
    judged = []
    for run in data.runs:
        if taken.get(run.arm, 0) < arms_judged.get(run.arm, 0):
            taken[run.arm] = taken.get(run.arm, 0) + 1
            judged.append(RunJudgments(run.code, run.arm, 2, 4 if run.arm == "A" else 1, 5))
    return judged


def test_an_interim_report_whose_strata_hold_one_arm_each_keeps_its_primary_section(ab: Path) -> None:
    data = load_study(StudyFolder(ab), False, "2026-01-01T00:00:00+00:00")
    strata = ("Direction",)
    plan = AnalysisPlan("compliant", "Controller", "randomization", "Controller + Direction", strata, "", 0.05, ("gee-small-sample",), 20000, 3)
    judged = _judged(data, {"A": 9, "B": 9})
    by_direction: dict[str, set[str]] = {}
    runs = {run.code: run for run in data.runs}
    for j in judged:
        by_direction.setdefault(runs[j.code].values["Direction"], set()).add(j.arm)
    # keep, per Direction, the runs of one arm only: no stratum holds both arms
    keep = {direction: "AB"[i % 2] for i, direction in enumerate(sorted(by_direction))}
    lone = [j for j in judged if j.arm == keep[runs[j.code].values["Direction"]]]
    assert {j.arm for j in lone} == {"A", "B"}, "the plan should leave both arms among the kept strata"
    result = primary_analysis(data, lone, plan)
    assert math.isnan(result.p_value) and result.randomization is None
    assert result.notes and result.notes[0].startswith("The randomization test cannot be made on these judgments: no stratum holds runs of both arms")
    full = primary_analysis(data, judged, plan)
    assert full.randomization is not None and 0.0 < full.p_value < 0.05


def test_arm_effects_keep_a_missing_interval_end_missing() -> None:
    column = Parameter("Controller[A]", 0.5, math.nan, math.nan, math.nan, math.nan, 1.0)
    fit = Fit("judged", "a fit", 18, 90, "z", "Wald", [column], [])
    effect = arm_effect(fit, "Controller")
    assert effect is not None and effect.estimate == pytest.approx(math.e)
    assert math.isnan(effect.low) and effect.high == pytest.approx(math.exp(2.0))


def test_a_planned_gee_test_of_a_three_level_factor_gives_its_p_value(ab: Path) -> None:
    data = load_study(StudyFolder(ab), False, "2026-01-01T00:00:00+00:00")
    plan = AnalysisPlan("compliant", "Direction", "gee", "Direction", (), "", 0.05, ("gee-small-sample",), 20000, 3)
    judged = [RunJudgments(run.code, run.arm, 2, 1 + i % 4, 5) for i, run in enumerate(data.runs)]
    result = primary_analysis(data, judged, plan)
    assert len(result.arms) == 3 and result.odds_ratio is None
    gee = result.sensitivity[0][1]
    assert result.p_value == next(e.p_value for e in gee.effects if e.term == "Direction") and 0.0 < result.p_value < 1.0


def test_design_states_no_runs_needed_from_too_few_data_sets(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One data set gives a power of 0 or 1: a plan size that "reaches" 0.8 from it has not shown anything."""
    root, spec = tmp_path / "small", tmp_path / "spec.toml"
    spec.write_text(SMALL_SPEC.format(name="small-ab", blind="true"))
    assert main(["design", "--spec", str(spec), "--study", str(root), "--seed", "4", "--power", "1"]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"^  6 runs  power [01]\.000 \(Wilson 95 % (0\.000-0\.793|0\.207-1\.000)\)$", printed, flags=re.M), printed
    assert ("  runs needed for power 0.8: not stated from 1 data sets per plan size (at least 100 are needed for the power's "
            "interval to be narrow enough)") in printed
    capsys.readouterr()
    assert main(["design", "--spec", str(spec), "--study", str(tmp_path / "again"), "--seed", "4", "--power", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["planned_power"]["needed_runs"] is None
