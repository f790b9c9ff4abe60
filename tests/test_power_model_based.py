"""Model-based power (trials/power/model_based.py): the anticipated coefficients on both scales, and the
simulated Gaussian power against design.json's analytic (JMP) power on the paper's A/B plan."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.special import expit

from designs.diagnostics import diagnose
from trials.cli import main
from trials.errors import StudyError
from trials.power import model_based
from trials.power.plans import designed_plan, own_plan, study_spec
from trials.power.seeds import SEED_BITS, derived
from trials.power.summary import estimate
from trials.power.verdicts import gaussian_verdict
from trials.study import StudyFolder


@pytest.fixture(scope="module")
def ab_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ab")
    assert main(["design", "--ab", "--runs", "18", "--seed", "3", "--study", str(folder)]) == 0
    return StudyFolder(folder)


def test_logit_coefficients_give_the_asked_shares_to_the_controller_arms(ab_study):
    spec, _ = study_spec(ab_study)
    plan = own_plan(ab_study)
    beta = model_based.coefficients(plan, spec, model_based.Anticipated(0.67, 0.75, terms=("Controller",)))
    column = plan.model.columns.index("Controller[A]")
    assert expit(beta.logit[0] + beta.logit[column]) == pytest.approx(0.75)
    assert expit(beta.logit[0] - beta.logit[column]) == pytest.approx(0.67)
    others = np.delete(np.arange(plan.model.p), [0, column])
    assert np.all(beta.logit[others] == 0.0)
    # Every run's chance without run effects is 0.75 in arm A and 0.67 in arm B.
    chance = expit(plan.model.matrix(plan.settings) @ beta.logit)
    arms = np.array(plan.arm_of_runs())
    assert np.allclose(chance[arms == "A"], 0.75) and np.allclose(chance[arms == "B"], 0.67)


def test_an_unknown_term_is_refused(ab_study):
    spec, _ = study_spec(ab_study)
    with pytest.raises(StudyError, match="'Speed' is not a term"):
        model_based.coefficients(own_plan(ab_study), spec, model_based.Anticipated(terms=("Speed",)))


def test_judgments_per_run_follow_the_pedestrians_unless_set(ab_study):
    plan = own_plan(ab_study)
    assert list(model_based.judgments_per_run(plan, None)) == plan.pedestrians()
    assert set(model_based.judgments_per_run(plan, 5)) == {5}


@pytest.mark.parametrize("runs", [18, pytest.param(24, marks=pytest.mark.slow)])  # 6-7 s each; the quick loop keeps one
def test_simulated_gaussian_power_agrees_with_the_analytic_power(ab_study, runs):
    """Without clustering, the Monte Carlo power of each term's F test matches JMP's noncentral-F power
    (design.json's for the study's own plan, `diagnose`'s for a 24-run plan designed from its spec)."""
    spec, _ = study_spec(ab_study)
    plan = own_plan(ab_study) if runs == 18 else designed_plan(ab_study, runs, 7)
    analytic = {t.term: t.power for t in diagnose(plan.model, plan.settings, alpha=spec.alpha, snr=spec.snr, anticipated=spec.anticipated).term_power
                if t.term != "Intercept"}
    if runs == 18:
        recorded = json.loads(ab_study.path("design.json").read_text())["diagnostics"]["power"]["terms"]
        assert analytic == pytest.approx({t["term"]: t["power"] for t in recorded if t["term"] in analytic})
    beta = model_based.coefficients(plan, spec, model_based.Anticipated())
    rng = np.random.default_rng(derived(5, "test", runs))
    simulations = 1000
    verdicts = [gaussian_verdict(plan, model_based.draw(plan, beta, model_based.Anticipated(), rng)[2]) for _ in range(simulations)]
    assert 0.3 < min(analytic.values()) and max(analytic.values()) < 0.995  # powers where Monte Carlo error is informative
    for term, power in analytic.items():
        simulated = estimate((v.term_p[term] for v in verdicts), spec.alpha)
        assert abs(simulated.power - power) < 4 * math.sqrt(power * (1 - power) / simulations), term


def test_derived_seeds_stay_below_2_to_the_53_and_differ_by_part():
    seeds = [derived(2**53 - 1, "campaign", 18, c) for c in range(200)]
    assert max(seeds) < 2**SEED_BITS and len(set(seeds)) == 200
    assert derived(1, "campaign", 18, 0) == derived(1, "campaign", 18, 0) != derived(2, "campaign", 18, 0)


def test_data_sets_without_a_test_are_counted_apart_from_non_rejections():
    """Separated judgments leave a fit that does not exist: its data set counts as not rejecting, and says so."""
    e = estimate([math.nan, math.nan, math.nan, 0.01, 0.2, 0.03], 0.05)
    assert (e.rejected, e.total, e.untested) == (2, 6, 3)
    assert e.power == pytest.approx(2 / 6) and e.power_when_tested == pytest.approx(2 / 3)
    assert e.text().endswith("[no test on 3 of 6 data sets (the fit does not exist), counted as not rejecting; 0.667 of the 3 tested rejected]")
    assert estimate([0.01, 0.2], 0.05).text() == "0.500 (0.095-0.905)"  # every data set tested: nothing to add
