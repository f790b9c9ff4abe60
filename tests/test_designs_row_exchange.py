"""The numpy row exchange that opens small D-optimal designs on the grid: every start ends where no single run's
exchange raises det(X'X) (checked by trying every allowed point in every run), blocks, covariates, restrictions and
kept runs stay as the compiled exchange keeps them, and a design found this way never loads numba."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from designs.constraints import compile_restrictions
from designs.exchange import _Search, candidate_set, optimal_design
from designs.factors import BlockFactor, CategoricalFactor, ContinuousFactor, CovariateFactor, DiscreteFactor
from designs.model import parse_model
from designs.row_exchange import WORK_LIMIT, RowExchange, pass_work

FACTORS = (DiscreteFactor("P", (2, 4, 6)), CategoricalFactor("D", ("a", "b", "c")), ContinuousFactor("X", 0, 1))


def _log_det(model, settings: np.ndarray) -> float:
    x = model.matrix(settings)
    return float(np.linalg.slogdet(x.T @ x)[1])


def _no_single_exchange_gains(model, settings: np.ndarray, rules, frozen: np.ndarray, first_free: int) -> bool:
    """Whether replacing any free run by any allowed grid point (its frozen settings kept) leaves det(X'X) no larger."""
    grid = candidate_set(model)
    now = _log_det(model, settings)
    for i in range(first_free, len(settings)):
        trials = grid.copy()
        trials[:, frozen] = settings[i, frozen]
        if rules:
            trials = trials[rules.allowed(trials, model.factors)]
        moved = np.repeat(settings[None], len(trials), axis=0)
        moved[:, i] = trials
        x = model.matrix(moved.reshape(-1, settings.shape[1])).reshape(len(trials), len(settings), -1)
        if np.linalg.slogdet(np.einsum("tnp,tnq->tpq", x, x))[1].max() > now + 1e-9:
            return False
    return True


def _openings(search: _Search, starts: int, runs: int, per_run: dict, kept: np.ndarray) -> np.ndarray:
    rngs = [np.random.default_rng(s) for s in range(starts)]
    return np.stack([search.opening(rng, kept, runs, per_run) for rng in rngs])


@pytest.mark.parametrize("case", ["plain", "restricted", "blocks", "covariate", "kept"])
def test_every_start_ends_where_no_single_exchange_gains(case):
    factors, per_run, kept, disallowed = FACTORS, {}, None, ()
    runs = 18
    if case == "restricted":  # restrictions let a continuous factor move anywhere, so X takes three levels here
        factors = (*FACTORS[:2], DiscreteFactor("X", (0.0, 0.5, 1.0)))
        disallowed = ("D == 'c' and P > 4", "X > 0.8 and P < 3")
    if case == "blocks":
        factors = (*FACTORS, BlockFactor.of(3))
        per_run = {3: np.arange(runs, dtype=float) // 6}
    if case == "covariate":
        factors = (*FACTORS, CovariateFactor("Age", 20, 60, values=tuple(float(v) for v in np.linspace(20, 60, runs))))
        per_run = {3: np.linspace(-1.0, 1.0, runs)}
    if case == "kept":
        kept = np.array([[-1.0, 0.0, -1.0], [-1.0, 0.0, -1.0], [0.0, 1.0, 1.0]])
    kept = np.zeros((0, len(factors))) if kept is None else kept
    model = parse_model("main + interactions", factors)
    rules = compile_restrictions(disallowed, (), model.factors, "test") if disallowed else None
    search = _Search.of(model, "D", rules, per_run, len(kept))
    rows = search.row_exchange(8, runs)
    assert isinstance(rows, RowExchange)
    settings = _openings(search, 8, runs, per_run, kept)
    opened = settings.copy()
    assert not _no_single_exchange_gains(model, opened[0], rules, search.frozen, len(kept))  # the check can fail
    rows.exchange(settings)
    for start, before in zip(settings, opened):
        assert _log_det(model, start) > _log_det(model, before)
        assert np.array_equal(start[:len(kept)], kept)
        for i, column in per_run.items():
            assert np.array_equal(start[:, i], column)
        if rules:
            assert rules.allowed(start, model.factors).all()
        assert _no_single_exchange_gains(model, start, rules, search.frozen, len(kept))


def test_a_singular_opening_still_reaches_an_estimable_design():
    """Every start of 6 runs for p = 6 opens on points drawn with replacement, most of them singular."""
    model = parse_model("main + interactions", FACTORS[:2])
    search = _Search.of(model, "D", None, {}, 0)
    settings = _openings(search, 20, 6, {}, np.zeros((0, 2)))
    x = model.matrix(settings.reshape(-1, 2)).reshape(20, 6, -1)
    assert (np.linalg.matrix_rank(np.einsum("snp,snq->spq", x, x)) < 6).sum() >= 10
    search.row_exchange(20, 6).exchange(settings)
    assert all(np.isfinite(_log_det(model, start)) and _log_det(model, start) > -10 for start in settings)


def test_only_small_d_designs_on_the_grid_take_the_row_exchange():
    model = parse_model("main + interactions", FACTORS)
    assert _Search.of(model, "D", None, {}, 0).row_exchange(100, 27) is not None
    assert _Search.of(model, "I", None, {}, 0).row_exchange(100, 27) is None  # every continuous factor moves under I
    curved = parse_model("main + quadratic", (ContinuousFactor("X", 0, 1), ContinuousFactor("Y", 0, 1)))
    assert _Search.of(curved, "D", None, {}, 0).row_exchange(100, 12) is None  # X^2's optimum may lie off the grid
    many = parse_model("main + interactions", tuple(CategoricalFactor(f"F{i}", ("a", "b", "c")) for i in range(6)))
    search = _Search.of(many, "D", None, {}, 0)
    assert many.p == 73 and pass_work(many, search.frozen, 100, 80) == 100 * 80 * 3**6 * 73**2 > WORK_LIMIT
    assert search.row_exchange(100, 80) is None


def test_a_small_design_is_found_without_loading_numba():
    """The paper's 27-run plan, searched and diagnosed, in a fresh process: numba and the compiled kernels never load."""
    probe = ("import sys; from designs.plan import build_plan; from designs.presets import qualitative; "
             "from dataclasses import replace; plan = build_plan(replace(qualitative(), seed=3)); "
             "print(round(plan.diagnostics.d_efficiency, 4), plan.design.hits, 'numba' in sys.modules, "
             "'designs.kernels' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["79.9157", "100", "False", "False"]


def test_the_row_exchange_matches_the_compiled_exchange_where_both_run():
    """Both searches of the A/B-like plan reach the same best det(X'X), from the same seeds."""
    factors = (FACTORS[0], FACTORS[1], CategoricalFactor("C", ("A", "B")))
    model = parse_model("main + interactions + P^2", factors)
    design = optimal_design(model, 18, seed=4, starts=40)
    search = _Search.of(model, "D", None, {}, 0)
    compiled = np.stack([search.opening(np.random.default_rng(s), np.zeros((0, 3)), 18, {}) for s in range(40)])
    for settings in compiled:
        search.exchange(settings, search.continuous)
    assert max(_log_det(model, s) for s in compiled) == pytest.approx(design.value, abs=1e-9)
