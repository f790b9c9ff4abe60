"""Fedorov's row exchange of every start at once, in numpy: the opening search of a small D-optimal design whose
factors all stay on their grids.

There the whole search of 100 starts takes milliseconds, less than loading the compiled kernels
(`designs/kernels.py`: numba, and the BLAS check it makes, about 0.5 s) would, so such a design is found without
them. Each start takes its free runs in turn and replaces the run's row x by the trial point y that raises det(X'X)
most, by the factor (1 - x'Vx)(1 + y'Vy) + (x'Vy)^2 with V = (X'X)^-1, as the compiled exchange judges its row swaps;
it passes over the runs until none gains. The trial points of a run are every grid point with the run's frozen
settings (its block or covariate) that the restrictions allow, so they include every move of one coordinate as well.
"""

from __future__ import annotations

import math

import numpy as np

from designs.constraints import Restrictions
from designs.exchange_numerics import CORE_LOST, GAIN_TOLERANCE, MAX_PASSES, RIDGE, SINGULAR_CONDITION
from designs.model import Model

#: The most arithmetic a pass may take here (starts x runs x trial points x p^2 multiply-adds): beyond it the compiled
#: exchange, once loaded, is the faster (a pass of this size takes about 40 ms in numpy).
WORK_LIMIT = 20_000_000
#: Trial points whose gains differ by less than this tie; the first of them is taken, so rounding in the last bits
#: (which differs between BLAS kernels) does not decide between the points of a symmetric design.
_TIE = 1e-9


def pass_work(model: Model, frozen: np.ndarray, starts: int, free_runs: int) -> int:
    """Multiply-adds of one pass over `starts` starts of `free_runs` runs each, every grid point tried in every run."""
    points = math.prod(len(model.grid(i)) for i in range(len(model.factors)) if not frozen[i])
    return starts * free_runs * points * model.p ** 2


class RowExchange:
    """The trial points of each run of one search, and the exchange of many starts over them."""

    def __init__(self, model: Model, grid: np.ndarray, restrictions: Restrictions | None, frozen: np.ndarray,
                 first_free: int):
        """`grid`: every combination of the factors' candidate settings, restrictions not applied (`candidate_set`)."""
        self.model = model
        self.grid = grid
        self.frozen = frozen
        self.first_free = first_free
        self.restrictions = restrictions
        self._rows: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def trials(self, run: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The trial points of a run with the settings `run` (its frozen ones kept) and their model rows."""
        key = run[self.frozen].tobytes()
        if key not in self._rows:
            points = self.grid.copy()
            points[:, self.frozen] = run[self.frozen]
            points = np.unique(points, axis=0)  # the grid's order, each point once
            if self.restrictions:
                points = points[self.restrictions.allowed(points, self.model.factors)]
            self._rows[key] = points, self.model.matrix(points)
        return self._rows[key]

    def exchange(self, settings: np.ndarray) -> None:
        """The row exchange of every start, in place on `settings` (starts, runs, factors)."""
        starts, runs, _ = settings.shape
        x = self.model.matrix(settings.reshape(starts * runs, -1)).reshape(starts, runs, -1)
        active = np.arange(starts)
        for _ in range(MAX_PASSES):
            inv = _inverse(x[active])
            moved = np.zeros(len(active), dtype=bool)
            for i in range(self.first_free, runs):
                points, rows = self.trials(settings[active[0], i])
                if not len(points):
                    continue
                old = x[active, i]
                b = np.einsum("spq,sq->sp", inv, old)
                dx = np.einsum("sp,sp->s", old, b)
                a_all = rows @ inv  # (starts, points, p): V y for every trial point, V symmetric
                dy = np.einsum("snp,np->sn", a_all, rows)
                dxy = b @ rows.T
                ratio = (1.0 - dx)[:, None] * (1.0 + dy) + dxy * dxy
                gain = np.log(np.maximum(ratio, 1e-300))
                top = gain.max(axis=1)
                go = np.flatnonzero(top > GAIN_TOLERANCE)
                if not len(go):
                    continue
                choice = np.argmax(gain[go] >= top[go, None] - _TIE, axis=1)
                y = rows[choice]
                settings[active[go], i] = points[choice]
                x[active[go], i] = y
                inv[go] = _updated(inv[go], old[go], y, a_all[go, choice], b[go], x[active[go]])
                moved[go] = True
            active = active[moved]
            if not len(active):
                return


def _updated(inv: np.ndarray, old: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """V after each start's row `old` (with b = V old) became `y` (with a = V y): the rank-two Woodbury step, or V
    afresh from the new rows `x` where the step's 2 x 2 core is singular to working precision."""
    dy = np.einsum("sp,sp->s", y, a)
    dx = np.einsum("sp,sp->s", old, b)
    dxy = np.einsum("sp,sp->s", b, y)
    det = (1.0 + dy) * (dx - 1.0) - dxy * dxy
    lost = np.abs(det) <= CORE_LOST * np.maximum(np.maximum(np.abs((1.0 + dy) * (dx - 1.0)), dxy * dxy), 1.0)
    safe = np.where(lost, 1.0, det)
    s11, s12, s22 = (dx - 1.0) / safe, -dxy / safe, (1.0 + dy) / safe
    u = np.stack([a, b], axis=2)  # V - U S U' with U = [a b] and S the core's inverse
    core = np.stack([np.stack([s11, s12], axis=1), np.stack([s12, s22], axis=1)], axis=1)
    inv = inv - u @ core @ u.transpose(0, 2, 1)
    if lost.any():
        inv[lost] = _inverse(x[lost])
    return inv


def _inverse(x: np.ndarray) -> np.ndarray:
    """(X'X)^-1 of each start's rows, with a small ridge on the diagonal where X'X is singular (as the compiled exchange
    does), so a singular opening can still move towards a design that estimates every term."""
    info = np.einsum("snp,snq->spq", x, x)
    sign, _ = np.linalg.slogdet(info)
    singular = (sign <= 0) | (np.linalg.cond(info) > SINGULAR_CONDITION)
    if singular.any():
        p = info.shape[1]
        ridge = RIDGE * np.maximum(1.0, np.trace(info[singular], axis1=1, axis2=2) / p)
        info[singular] += ridge[:, None, None] * np.eye(p)
    return np.linalg.inv(info)
