"""The primary section says what each number is: a stratified difference is called stratum-weighted, unblinded notes
name controllers as the columns do, likelihood tests sit beside likelihood intervals, and an odds ratio from a fit that
treats judgments as independent says so."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from analysis.plan import PlanStatus
from analysis.report import build_report
from analysis.scoring import Rubric
from tests.support.registration import recorded_digest
from tests.support.synthetic_study import judged_ab_study
from trials.study import StudyFolder
from trials.study_data import load_study

pytestmark = pytest.mark.slow
NOW = "2026-12-06T00:00:00+00:00"


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return judged_ab_study(tmp_path_factory.mktemp("wording") / "study")


def _unblinded(root: Path):
    return load_study(StudyFolder(root), True, NOW, recorded_digest(root))


def test_a_stratified_difference_is_named_for_what_it_is(study: Path) -> None:
    data = _unblinded(study)
    assert data.analysis_plan is not None
    stratified = replace(data, analysis_plan=PlanStatus(replace(data.analysis_plan.plan, strata=("Direction",)), True, None))
    markdown = build_report(stratified, Rubric(), "defaults", NOW).markdown()
    assert "| Stratum-weighted difference " in markdown and "stratum-weighted difference " in markdown
    assert "averaged with weights n1 n2 / n" in markdown and "it is not the difference of the two means above" in markdown
    plain = build_report(data, Rubric(), "defaults", NOW).markdown()
    assert "| Difference " in plain and "tratum-weighted" not in plain


def test_likelihood_tests_sit_beside_likelihood_intervals(study: Path) -> None:
    report = build_report(_unblinded(study), Rubric(), "defaults", NOW)
    primary = report.record["primary"]
    fits = {row["analysis"]: row for row in primary["sensitivity"]}
    for name in ("random-intercept", "firth"):
        for column in fits[name]["parameters"]:  # on the log-odds scale: the interval excludes 0 exactly when p < 0.05
            assert (column["low"] > 0.0 or column["high"] < 0.0) == (column["p"] < 0.05), (name, column)
    markdown = report.markdown()
    assert "likelihood-ratio chi-square tests per column and per term, and profile-likelihood intervals" in markdown
    assert "Each row's p is the arm column's own test, made as its interval is" in markdown
    assert "t intervals and t tests on the degrees of freedom the fit states (least squares: the residual df; GEE: its cluster df" in markdown


def test_a_separated_study_names_controllers_and_says_where_its_odds_ratio_comes_from(study: Path) -> None:
    data = _unblinded(study)
    arm_of = {run.code: run.arm for run in data.runs}
    separated = replace(data, responses=[replace(r, compliant=arm_of[r.run_code] == "Lattice") for r in data.responses])
    markdown = build_report(separated, Rubric(), "defaults", NOW).markdown()
    assert "Controller\\[A\\]" not in markdown and "Controller\\[B\\]" not in markdown  # the notes name controllers too
    assert re.search(r"perfectly separated \(along Intercept, Controller\\\[(NaviGAN-R|Lattice)\\\]\)", markdown)
    assert f"it treats the {len(data.responses)} judgments as independent" in markdown
