"""The approximate (continuous) D-optimal design on the candidate set, and the bound it gives.

    maximise   log det( sum_i w_i x_i x_i' )
    subject to w >= 0,  sum_i w_i = 1

Its optimum bounds every exact design: det(X'X / n) <= det(M(w*)) for any n runs drawn from
the candidates, so 100 * det(M(w*))^(1/p) is the D-efficiency no exact design can beat.

The weights come from the multiplicative algorithm (Silvey, Titterington and Torsney, 1978):
w_i <- w_i d_i / p with d_i = x_i' M(w)^-1 x_i. log det is concave in w with gradient d, so for
any w, log det M(w*) <= log det M(w) + max_i d_i - p (Kiefer and Wolfowitz's equivalence
theorem: the gap is 0 exactly at the optimum). The bound reported adds that gap, so it holds
whether or not the iteration has fully converged; it stops when the gap is below 1e-7.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from designs.errors import DesignError

#: The iteration stops when max d - p, the most log det M(w) can still rise, is below this.
GAP = 1e-7
MAX_ITERATIONS = 20_000


@dataclass(frozen=True)
class ApproximateDesign:
    """Weights on the candidate points, their log det M(w), and the certified gap to the optimum."""

    weights: np.ndarray
    log_det: float
    gap: float
    p: int

    @property
    def d_efficiency(self) -> float:
        """The bound: 100 det(M(w*))^(1/p), from log det M(w) plus the certified gap."""
        return 100.0 * float(np.exp((self.log_det + self.gap) / self.p))


def approximate_d_optimal(rows: np.ndarray) -> ApproximateDesign:
    """The D-optimal weights for candidate model rows (N, p) and the certified bound."""
    n_candidates, p = rows.shape
    weights = np.full(n_candidates, 1.0 / n_candidates)
    sign, _ = np.linalg.slogdet(rows.T @ rows)
    if sign <= 0:
        raise DesignError("the model cannot be estimated from the candidate set (its information matrix is singular)")
    for _ in range(MAX_ITERATIONS):
        information = rows.T @ (weights[:, None] * rows)
        variance = np.einsum("ij,jk,ik->i", rows, np.linalg.inv(information), rows)
        gap = float(variance.max()) - p
        if gap < GAP:
            break
        weights = weights * variance / p
    _, log_det = np.linalg.slogdet(information)
    return ApproximateDesign(weights, float(log_det), max(gap, 0.0), p)
