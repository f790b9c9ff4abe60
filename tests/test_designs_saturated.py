"""Saturated plans (as many runs as parameters): the 12-run Plackett-Burman plan of 11 two-level factors, whose random
starts are singular and whose every run has leverage 1, so the exchange meets a singular X'X and a singular update core.
Before, seeds 1 and 3 ended in a ZeroDivisionError inside the compiled exchange."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from designs import kernels
from designs.factors import CategoricalFactor
from designs.plan import build_plan
from designs.spec import StudySpec

#: Plackett and Burman's generator of the 12-run plan: its 11 cyclic shifts, then a row of minuses.
GENERATOR = np.array([1, 1, -1, 1, 1, 1, -1, -1, -1, 1, -1], dtype=float)


def plackett_burman_rows() -> np.ndarray:
    """The main-effects model rows of the 12-run Plackett-Burman plan: intercept, then the 11 factors, +-1."""
    rows = [np.roll(GENERATOR, shift) for shift in range(11)] + [-np.ones(11)]
    return np.column_stack([np.ones(12), rows])


def test_a_singular_information_matrix_with_a_positive_determinant_is_singular():
    x = np.random.default_rng(2).choice([-1.0, 1.0], size=(12, 12))
    x[:, 0] = 1.0  # the intercept
    x[11] = x[10]  # two equal runs: rank 11
    info = x.T @ x
    # Exactly singular (two equal runs), whatever sign and size of determinant a BLAS kernel's rounding gives it: on
    # many machines a positive one, which a determinant test took for a regular design.
    assert round(float(np.linalg.svd(x, compute_uv=False)[-1]), 9) == 0.0
    assert kernels._checked_inverse(info)[0]
    assert not kernels._checked_inverse(plackett_burman_rows().T @ plackett_burman_rows())[0]
    inverse = kernels._inverse(x)  # with the ridge: finite, and no larger than its size allows
    assert np.isfinite(inverse).all() and np.abs(inverse).max() < 1e7


def test_the_condition_number_decides_where_its_cheap_bound_does_not():
    """cond(X'X) <= |X'X|_F |(X'X)^-1|_F spares the SVD; where the bound passes the limit but the condition number does
    not (here 15 x 3.2e11 against 3.2e11), the matrix is regular, and it is singular once the condition number passes."""
    small = 10.0 ** -11.5
    info = np.diag(np.r_[np.ones(15), np.full(15, small)])
    assert np.sqrt(np.sum(info**2) * np.sum(np.linalg.inv(info) ** 2)) > 1e12 > np.linalg.cond(info)
    singular, inverse = kernels._checked_inverse(info)
    assert not singular
    np.testing.assert_allclose(np.diag(inverse), np.r_[np.ones(15), np.full(15, 1 / small)], rtol=1e-12)
    assert kernels._checked_inverse(np.diag(np.r_[np.ones(15), np.full(15, 1e-13)]))[0]


def test_an_exchange_with_a_singular_core_leaves_the_inverse_to_be_made_afresh():
    x = plackett_burman_rows()
    inverse = np.linalg.inv(x.T @ x)  # I / 12: every run's leverage x'Vx is exactly 1
    a, b = np.empty(12), np.empty(12)
    old, new = x[0].copy(), x[1].copy()  # orthogonal runs: x'Vy = 0, so the core's determinant is exactly 0
    assert old @ inverse @ old == 1.0 and old @ inverse @ new == 0.0
    kept = inverse.copy()
    assert not kernels._exchange_row(inverse, old, new, b, a)
    assert np.array_equal(inverse, kept)
    moved = x.copy()
    moved[0, 1] = -moved[0, 1]  # one coordinate of a run: a regular exchange, updated in place
    assert kernels._exchange_row(inverse, x[0].copy(), moved[0], b, a)
    np.testing.assert_allclose(inverse, np.linalg.inv(moved.T @ moved), atol=1e-12)


@pytest.mark.slow  # five searches of 100 starts, about 2 s each
def test_the_saturated_plackett_burman_plan_is_found_from_every_seed():
    spec = StudySpec("pb12", tuple(CategoricalFactor(f"X{i}", ("lo", "hi")) for i in range(1, 12)), model="main", runs=12)
    for seed in range(1, 6):
        plan = build_plan(replace(spec, seed=seed))
        assert plan.diagnostics.d_efficiency == pytest.approx(100.0), seed
        x = plan.model.matrix(plan.design.settings)
        np.testing.assert_allclose(x.T @ x, 12 * np.eye(12), atol=1e-9)  # orthogonal, as Plackett and Burman's plan
