"""Design quality against independent computations: the paper's optima, closed forms, brute force."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from designs.bound import approximate_d_optimal
from designs.diagnostics import diagnose
from designs.errors import DesignError
from designs.exchange import candidate_set, optimal_design
from designs.factors import CategoricalFactor, ContinuousFactor, DiscreteFactor
from designs.model import parse_model
from designs.plan import build_plan
from designs.presets import ab, qualitative
from trials.controllers.registry import AB_PRESET as CONTROLLERS


def _model(spec):
    return parse_model(spec.model, spec.design_factors, tuple(f.name for f in spec.fixed_factors))


def _det(model, settings) -> float:
    x = model.matrix(settings)
    return float(np.linalg.det(x.T @ x))


@pytest.mark.parametrize("seed", [0, 1, 7, 2019, 123456789])
def test_qualitative_plan_reaches_the_proven_optimum_from_any_seed(seed):
    model = _model(qualitative())
    design = optimal_design(model, 27, seed=seed)
    assert model.p == 5
    assert design.hits == design.starts == 100 and design.kicks == 0  # every start: no iterated search needed
    assert _det(model, design.settings) == pytest.approx(4_677_120, rel=1e-9)
    assert diagnose(model, design.settings).d_efficiency == pytest.approx(79.9157, abs=1e-4)
    peds, _, distance = design.settings.T
    assert not np.any(np.isclose(peds, 0.0)), "the optimum never uses 4 pedestrians"
    assert not np.any(np.isclose(distance, 0.0)), "the optimum never uses a 2 m crossing distance"


@pytest.mark.parametrize("seed", [0, 3, 42, 99991])
def test_ab_plan_reaches_the_proven_optimum_from_any_seed(seed):
    model = _model(ab(CONTROLLERS))
    design = optimal_design(model, 18, seed=seed)
    assert model.p == 11
    assert design.hits == design.starts == 100 and design.kicks == 0
    assert _det(model, design.settings) == pytest.approx(106_420_469_760, rel=1e-9)
    assert diagnose(model, design.settings).d_efficiency == pytest.approx(55.8707, abs=1e-4)


def test_approximate_design_bounds_of_the_presets():
    for spec, bound in [(qualitative(), 80.2742), (ab(CONTROLLERS), 57.9620)]:
        model = _model(spec)
        result = approximate_d_optimal(model.matrix(candidate_set(model)))
        assert result.d_efficiency == pytest.approx(bound, abs=1e-3)
        assert result.weights.sum() == pytest.approx(1.0)


@pytest.mark.parametrize("model_string, factors", [
    ("main + interactions + quadratic", (ContinuousFactor("A", -1, 1), ContinuousFactor("B", -1, 1), DiscreteFactor("C", (0, 1, 2)))),
    ("main + interactions", (CategoricalFactor("D", ("x", "y", "z")), ContinuousFactor("E", -1, 1))),
])
def test_bound_agrees_with_cvxpy_on_the_same_convex_problem(model_string, factors):
    """cvxpy solves max log det M(w) over the same candidates independently; our certified bound must match it."""
    import cvxpy as cp  # a dev dependency: the library the bound was first computed with, kept as the independent truth
    model = parse_model(model_string, factors)
    rows = model.matrix(candidate_set(model))
    w = cp.Variable(len(rows), nonneg=True)
    problem = cp.Problem(cp.Maximize(cp.log_det(rows.T @ cp.diag(w) @ rows)), [cp.sum(w) == 1])
    problem.solve(solver=cp.SCS, eps=1e-9, max_iters=200_000)
    reference = 100 * math.exp(problem.value / model.p)
    result = approximate_d_optimal(rows)
    assert result.d_efficiency == pytest.approx(reference, rel=1e-4)
    assert result.d_efficiency >= reference * (1 - 1e-5)  # a bound: never below the optimum


def test_bound_of_one_factor_quadratic_is_the_known_approximate_optimum():
    """Quadratic on {-1, 0, 1}: the approximate D-optimum puts 1/3 on each point, det M = 4/27."""
    model = parse_model("main + quadratic", (ContinuousFactor("A", -1, 1),))
    result = approximate_d_optimal(model.matrix(candidate_set(model)))
    np.testing.assert_allclose(result.weights, [1 / 3] * 3, atol=1e-6)
    assert result.d_efficiency == pytest.approx(100 * (4 / 27) ** (1 / 3), rel=1e-7)
    assert result.d_efficiency >= 100 * (4 / 27) ** (1 / 3) * (1 - 1e-12)  # the certified bound never falls below the optimum


def test_plan_reports_efficiency_relative_to_the_bound():
    plan = build_plan(ab(CONTROLLERS))
    assert plan.d_efficiency_vs_bound == pytest.approx(100 * 55.8707 / 57.9620, abs=1e-3)
    assert plan.design.hits >= 1


def test_full_factorial_3x3x3_matches_the_closed_form():
    """Main effects of a full factorial: X'X is block diagonal with known blocks."""
    model = _model(qualitative())
    settings = np.array(list(itertools.product([-1.0, 0.0, 1.0], [0.0, 1.0, 2.0], [-1.0, 0.0, 1.0])))
    n = 27
    # intercept n; each numeric column n * mean(x^2) = n * 2/3; the effect-coded block n/3 (I + J), det 3 (n/3)^2
    closed_form = n * (n * 2 / 3) ** 2 * 3 * (n / 3) ** 2
    assert closed_form == 2_125_764
    d = diagnose(model, settings)
    assert d.det_xtx == pytest.approx(closed_form)
    assert d.d_efficiency == pytest.approx(100 * closed_form ** (1 / 5) / n)
    assert d.d_efficiency == pytest.approx(68.2558, abs=1e-4)


@pytest.mark.parametrize("levels", [(2, 2, 2), (2, 3, 4), (3, 5)])
def test_categorical_full_factorials_match_the_closed_form(levels):
    """det(X'X) = N^p * prod_k k^(2-k) for effect coding, main effects."""
    factors = tuple(CategoricalFactor(f"F{i}", tuple(f"l{j}" for j in range(k))) for i, k in enumerate(levels))
    model = parse_model("main", factors)
    settings = np.array(list(itertools.product(*(range(k) for k in levels))), dtype=float)
    n = len(settings)
    expected = n**model.p * math.prod(k ** (2 - k) for k in levels)
    assert diagnose(model, settings).det_xtx == pytest.approx(expected, rel=1e-9)


def test_two_level_factorial_is_orthogonal_with_hand_values():
    """2^2 factorial, main effects: X'X = 4I, so D = A = G = 100 and APV = (1 + 1/3 + 1/3) / 4."""
    factors = (ContinuousFactor("A", -1, 1), ContinuousFactor("B", -1, 1))
    model = parse_model("main", factors)
    settings = np.array(list(itertools.product([-1.0, 1.0], repeat=2)))
    d = diagnose(model, settings)
    assert (d.d_efficiency, d.a_efficiency, d.g_efficiency) == pytest.approx((100.0, 100.0, 100.0))
    assert d.average_prediction_variance == pytest.approx(5 / 12)
    assert d.max_prediction_variance == pytest.approx(3 / 4)
    assert d.standard_errors["A"] == pytest.approx(0.5)
    assert d.correlations[0, 1] == pytest.approx(0.0)


def test_power_matches_the_noncentral_f_of_scipy_stats():
    """2^3 factorial, main effects: var(b) = 1/8, so lambda = 8 snr^2 on (1, n - p) df."""
    factors = tuple(ContinuousFactor(name, 0, 1) for name in "ABC")
    model = parse_model("main", factors)
    settings = np.array(list(itertools.product([-1.0, 1.0], repeat=3)))
    for snr in (0.5, 1.0):
        d = diagnose(model, settings, snr=snr)
        df = 8 - 4
        expected = stats.ncf.sf(stats.f.ppf(0.95, 1, df), 1, df, 8 * snr**2)
        assert d.parameter_power["A"] == pytest.approx(expected, rel=1e-9)
        assert {t.term: t.power for t in d.term_power}["B"] == pytest.approx(expected, rel=1e-9)


def test_saturated_design_gets_one_error_df_as_jmp_does():
    model = parse_model("main", (ContinuousFactor("A", -1, 1),))
    d = diagnose(model, np.array([[-1.0], [1.0]]))
    assert d.error_df == 1
    assert d.parameter_power["A"] == pytest.approx(stats.ncf.sf(stats.f.ppf(0.95, 1, 1), 1, 1, 2.0), rel=1e-9)


def test_categorical_term_power_tests_the_whole_effect():
    """JMP's convention: the anticipated coefficients of D[a], D[b] are +1, -1, so the levels' means are
    +1, -1 and 0; 4 runs each give lambda = 4 (1 + 1 + 0) = 8 on (2, 9) df."""
    factor = CategoricalFactor("D", ("a", "b", "c"))
    model = parse_model("main", (factor,))
    settings = np.repeat([0.0, 1.0, 2.0], 4)[:, None]
    d = diagnose(model, settings)
    expected = stats.ncf.sf(stats.f.ppf(0.95, 2, 9), 2, 9, 8.0)
    assert {t.term: t.power for t in d.term_power}["D"] == pytest.approx(expected, rel=1e-9)
    assert d.anticipated == {"Intercept": 1.0, "D[a]": 1.0, "D[b]": -1.0}
    # A term's own coefficient scales its columns: c = 0.5 quarters lambda.
    half = diagnose(model, settings, anticipated={"D": 0.5})
    assert {t.term: t.power for t in half.term_power}["D"] == pytest.approx(stats.ncf.sf(stats.f.ppf(0.95, 2, 9), 2, 9, 2.0), rel=1e-9)
    assert half.anticipated["D[b]"] == -0.5
    with pytest.raises(DesignError, match=r"\[anticipated\] in the spec: 'E' is not a term of the model"):
        diagnose(model, settings, anticipated={"E": 1.0})


def test_ab_plan_power_with_jmp_coefficients():
    """The 18-run A/B plan: each term's power from scipy.stats' noncentral F on (X'X)^-1 with the
    alternating coefficients; every coefficient +1 gave 0.991, 0.947, 0.991 for the three two-column terms."""
    model = _model(ab(CONTROLLERS))
    settings = optimal_design(model, 18, seed=0).settings
    x = model.matrix(settings)
    inv = np.linalg.inv(x.T @ x)
    power = {t.term: t.power for t in diagnose(model, settings).term_power}
    for name, columns in zip(model.term_names, model.term_slices):
        width = columns.stop - columns.start
        beta = np.array([1.0, -1.0][:width])
        noncentrality = beta @ np.linalg.solve(inv[columns, columns], beta)
        assert power[name] == pytest.approx(stats.ncf.sf(stats.f.ppf(0.95, width, 7), width, 7, noncentrality), rel=1e-9)
    assert (power["Direction"], power["Pedestrians*Direction"], power["Direction*Controller"]) == pytest.approx((0.675, 0.547, 0.675), abs=5e-4)
    assert power["Controller"] == pytest.approx(0.945, abs=5e-4)


def _brute_force_best_det(model, runs: int) -> float:
    candidates = candidate_set(model)
    rows = model.matrix(candidates)
    best = 0.0
    for combo in itertools.combinations_with_replacement(range(len(candidates)), runs):
        x = rows[list(combo)]
        best = max(best, float(np.linalg.det(x.T @ x)))
    return best


@pytest.mark.parametrize(
    ("factors", "expression", "runs"),
    [
        ((DiscreteFactor("P", (2, 4, 6)), CategoricalFactor("C", ("x", "y"))), "main + interactions", 5),
        ((DiscreteFactor("P", (2, 4, 6)),), "main + quadratic", 4),
        ((DiscreteFactor("P", (1, 2, 3)), CategoricalFactor("D", ("a", "b", "c"))), "P + D + P^2", 6),
    ],
)
def test_exchange_matches_brute_force_on_small_problems(factors, expression, runs):
    model = parse_model(expression, factors)
    design = optimal_design(model, runs, seed=11, starts=30)
    assert _det(model, design.settings) == pytest.approx(_brute_force_best_det(model, runs), rel=1e-9)


def test_continuous_factors_leave_the_grid_when_that_is_better():
    """6 runs, full quadratic in two continuous factors: the exact optimum is off the 3x3 grid
    (Box & Draper), so it must beat the best design restricted to grid points."""
    factors = (ContinuousFactor("A", -1, 1), ContinuousFactor("B", -1, 1))
    model = parse_model("main + interactions + quadratic", factors)
    design = optimal_design(model, 6, seed=5, starts=8)
    grid_best = _brute_force_best_det(model, 6)
    assert grid_best == pytest.approx(256.0)
    assert _det(model, design.settings) == pytest.approx(267.737, abs=1e-3)
    off_grid = ~np.isclose(design.settings, np.round(design.settings))
    assert off_grid.any()
    assert np.all(np.abs(design.settings) <= 1.0 + 1e-12)


def test_replicates_are_allowed():
    """One two-level factor, 4 runs: the optimum repeats each level twice."""
    model = parse_model("main", (CategoricalFactor("C", ("x", "y")),))
    design = optimal_design(model, 4, seed=0, starts=5)
    assert sorted(design.settings[:, 0].tolist()) == [0.0, 0.0, 1.0, 1.0]
