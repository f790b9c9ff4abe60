"""The approximate (continuous) D-optimal design on the candidate set, solved with cvxpy.

    maximise   log det( sum_i w_i x_i x_i' )
    subject to w >= 0,  sum_i w_i = 1

Its optimum bounds every exact design: det(X'X / n) <= det(M(w*)) for any n runs drawn from
the candidates, so 100 * det(M(w*))^(1/p) is the D-efficiency no exact design can beat.

cvxpy takes about a second to import, so `solve_in_background` runs the solve in a forked
worker process while the caller searches the exact design.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError


@dataclass(frozen=True)
class ApproximateDesign:
    """Optimal weights on the candidate points and the D-efficiency they reach."""

    weights: np.ndarray
    log_det: float
    p: int

    @property
    def d_efficiency(self) -> float:
        return 100.0 * float(np.exp(self.log_det / self.p))


def approximate_d_optimal(rows: np.ndarray) -> ApproximateDesign:
    """Solve the D-optimal weights for candidate model rows (N, p)."""
    import cvxpy as cp

    n_candidates, p = rows.shape
    w = cp.Variable(n_candidates, nonneg=True)
    information = rows.T @ cp.diag(w) @ rows
    problem = cp.Problem(cp.Maximize(cp.log_det((information + information.T) / 2)), [cp.sum(w) == 1])
    problem.solve(solver=cp.CLARABEL)
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or w.value is None:
        raise DesignError(f"the approximate design could not be solved (solver status: {problem.status})")
    weights = np.clip(w.value, 0.0, None)
    weights /= weights.sum()
    sign, log_det = np.linalg.slogdet(rows.T @ (weights[:, None] * rows))
    if sign <= 0:
        raise DesignError("the model cannot be estimated from the candidate set (its information matrix is singular)")
    return ApproximateDesign(weights, float(log_det), p)


def solve_in_background(rows: np.ndarray) -> Future[ApproximateDesign]:
    """Start `approximate_d_optimal(rows)` in a forked worker; solve here where fork is missing."""
    if "fork" not in multiprocessing.get_all_start_methods():
        future: Future[ApproximateDesign] = Future()
        try:
            future.set_result(approximate_d_optimal(rows))
        except DesignError as exc:
            future.set_exception(exc)
        return future
    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("fork"))
    future = pool.submit(approximate_d_optimal, rows)
    pool.shutdown(wait=False)
    return future
