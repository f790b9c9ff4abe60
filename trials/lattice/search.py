"""ARA*, anytime repairing A* (Likhachev, Gordon & Thrun 2003), over the lattice's flat state arrays.

A state is `cell * num_thetas + heading`, `cell` a flat index of the padded grid. Each iteration is
a weighted A* with priority g + int(eps * h) that expands every state at most once; states improved
after they were closed wait in INCONS and re-enter OPEN when eps drops by `eps_step`, so later
iterations reuse the earlier search. Each finished iteration's path costs at most eps times the
optimum. The compiled kernel runs a bounded number of expansions per call, so the Python driver
checks the clock between calls and no search outlives its budget. The edge rule is SBPL's
GetActionCost; the bookkeeping follows SBPL's ARAPlanner, so epsilon-1 costs equal SBPL's.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from trials.lattice.heap import heapify, new_heap, pop_min, push_or_update
from trials.lattice.heuristic import INFINITE_COST

#: Kernel outcomes (SBPL's ImprovePath codes).
NO_SOLUTION, SOLVED, UNFINISHED = 0, 1, 2
EPS_TOLERANCE = 1e-6
CHUNK_EXPANSIONS = 1024


@dataclass(frozen=True)
class Tables:
    """The action tables with cell offsets flattened for one padded-grid row width (see `actions`)."""

    end_offset: np.ndarray   # (N*A,) flat-index offset of the end cell
    end_heading: np.ndarray  # (N*A,)
    cost: np.ndarray         # (N*A,) base cost
    centre: np.ndarray       # flat offsets of cells under the centre, blocks by centre_ptr
    centre_ptr: np.ndarray
    swept: np.ndarray        # flat offsets of swept footprint cells, blocks by swept_ptr
    swept_ptr: np.ndarray
    reach2: np.ndarray       # (N*A,) squared reach in cells
    num_thetas: int
    per_heading: int
    use_footprint: bool


@dataclass(frozen=True)
class Thresholds:
    obsthresh: int
    inscribed: int
    circumscribed: int


@njit(cache=True)
def edge_cost(values, clear2, cell, action, end_offset, cost, centre, centre_ptr, swept, swept_ptr, reach2,
              obsthresh, inscribed, circumscribed, use_footprint):
    """The cost of `action` (flat heading*A+a) from a valid source `cell`, or -1 when it collides."""
    end_value = values[cell + end_offset[action]]
    if end_value >= obsthresh or end_value >= inscribed:
        return -1
    highest = 0
    for k in range(centre_ptr[action], centre_ptr[action + 1]):
        highest = max(highest, values[cell + centre[k]])
        if highest >= inscribed:
            return -1
    if use_footprint and highest >= circumscribed and clear2[cell] <= reach2[action]:
        for k in range(swept_ptr[action], swept_ptr[action + 1]):
            if values[cell + swept[k]] >= obsthresh:
                return -1
    highest = max(highest, values[cell], end_value)
    return cost[action] * (highest + 1)


@njit(cache=True, inline="always")
def _touch(state, call, g, v, pred, closed, seen):
    if seen[state] != call:
        seen[state] = call
        g[state] = INFINITE_COST
        v[state] = INFINITE_COST
        pred[state] = -1
        closed[state] = 0


@njit(cache=True)
def improve_path(values, clear2, num_thetas, per_heading, end_offset, end_heading, cost, centre, centre_ptr,
                 swept, swept_ptr, reach2, obsthresh, inscribed, circumscribed, use_footprint, hcell, eps,
                 iteration, call, goal, g, v, pred, closed, seen, keys, items, pos, size, incons, n_incons,
                 in_incons, max_expansions, best):
    """Expand states until the goal's cost is within `eps` (SOLVED), OPEN runs dry (NO_SOLUTION) or
    `max_expansions` are spent (UNFINISHED). `best` keeps [state, h, g] of the expanded state nearest
    the goal by heuristic, for partial paths. Returns (outcome, expansions)."""
    _touch(goal, call, g, v, pred, closed, seen)
    expansions = 0
    while size[0] > 0 and keys[1] < INFINITE_COST and g[goal] > keys[1]:
        if expansions >= max_expansions:
            return UNFINISHED, expansions
        state = pop_min(keys, items, pos, size)
        v[state] = g[state]
        closed[state] = iteration
        expansions += 1
        cell = state // num_thetas
        h = hcell[cell]
        if h < best[1] or (h == best[1] and g[state] < best[2]):
            best[0], best[1], best[2] = state, h, g[state]
        if state == goal or values[cell] >= obsthresh:  # the goal absorbs; an invalid cell has no moves
            continue
        first = (state - cell * num_thetas) * per_heading
        for action in range(first, first + per_heading):
            step = edge_cost(values, clear2, cell, action, end_offset, cost, centre, centre_ptr, swept, swept_ptr,
                             reach2, obsthresh, inscribed, circumscribed, use_footprint)
            if step < 0:
                continue
            nxt_cell = cell + end_offset[action]
            nxt = nxt_cell * num_thetas + end_heading[action]
            _touch(nxt, call, g, v, pred, closed, seen)
            new = v[state] + step
            if g[nxt] > new:
                g[nxt] = new
                pred[nxt] = state
                if closed[nxt] != iteration:
                    push_or_update(keys, items, pos, size, nxt, new + np.int64(eps * hcell[nxt_cell]))
                elif in_incons[nxt] == 0:
                    in_incons[nxt] = 1
                    incons[n_incons[0]] = nxt
                    n_incons[0] += 1
    if g[goal] == INFINITE_COST and size[0] == 0:
        return NO_SOLUTION, expansions
    if size[0] > 0 and g[goal] > keys[1]:
        return UNFINISHED, expansions
    if g[goal] == INFINITE_COST:
        return NO_SOLUTION, expansions
    return SOLVED, expansions


@njit(cache=True)
def new_iteration(num_thetas, hcell, eps, g, keys, items, pos, size, incons, n_incons, in_incons):
    """Move INCONS into OPEN and re-key OPEN for the new eps."""
    for i in range(n_incons[0]):
        state = incons[i]
        in_incons[state] = 0
        push_or_update(keys, items, pos, size, state, 0)
    n_incons[0] = 0
    for slot in range(1, size[0] + 1):
        state = items[slot]
        keys[slot] = g[state] + np.int64(eps * hcell[state // num_thetas])
    heapify(keys, items, pos, size)


@njit(cache=True)
def clear_open(items, pos, size, incons, n_incons, in_incons):
    for slot in range(1, size[0] + 1):
        pos[items[slot]] = 0
    size[0] = 0
    for i in range(n_incons[0]):
        in_incons[incons[i]] = 0
    n_incons[0] = 0


@dataclass(frozen=True)
class Iteration:
    """One finished ARA* iteration: its eps bound, the goal's cost, and the totals so far."""

    eps: float
    cost: int
    expansions: int
    seconds: float


@dataclass
class SearchResult:
    """The outcome of one search call.

    `status` is "solved" (a path to the goal, within `eps` of optimal), "partial" (the budget ran out
    before any path to the goal: `states` lead to the expanded state nearest the goal) or "no_path"
    (the reachable lattice holds no path: `states` as for partial).
    """

    status: str
    states: list[int]
    cost: int
    eps: float
    expansions: int
    seconds: float
    iterations: list[Iteration] = field(default_factory=list)


class AraStar:
    """ARA* over one padded grid size; its state arrays are reused from call to call."""

    def __init__(self, num_cells: int, tables: Tables, thresholds: Thresholds) -> None:
        self.tables, self.thresholds = tables, thresholds
        n = num_cells * tables.num_thetas
        self.g, self.v, self.pred = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int32)
        self.closed, self.seen = np.zeros(n, np.int32), np.zeros(n, np.int32)
        self.keys, self.items, self.pos, self.size = new_heap(n)
        self.incons, self.n_incons, self.in_incons = np.empty(n, np.int32), np.zeros(1, np.int64), np.zeros(n, np.int8)
        self.call = 0

    def search(self, values: np.ndarray, clear2: np.ndarray, hcell: np.ndarray, start: int, goal: int,
               eps: float = 3.0, eps_step: float = 0.2, final_eps: float = 1.0,
               deadline: float = math.inf) -> SearchResult:
        """ARA* from state `start` to state `goal` until eps reaches `final_eps` or `time.perf_counter()`
        passes `deadline`."""
        t, th = self.tables, self.thresholds
        t0 = time.perf_counter()
        self.call += 1
        clear_open(self.items, self.pos, self.size, self.incons, self.n_incons, self.in_incons)
        for state in (start, goal):
            if self.seen[state] != self.call:
                self.seen[state] = self.call
                self.g[state] = self.v[state] = INFINITE_COST
                self.pred[state], self.closed[state] = -1, 0
        self.g[start] = 0
        nth = t.num_thetas
        push_or_update(self.keys, self.items, self.pos, self.size, start, np.int64(eps * hcell[start // nth]))
        best = np.array([start, hcell[start // nth], 0], dtype=np.int64)
        iterations: list[Iteration] = []
        satisfied, iteration, expansions, outcome = math.inf, 0, 0, UNFINISHED
        while satisfied > final_eps and time.perf_counter() < deadline:
            if iteration > 0:
                if abs(satisfied - eps) < EPS_TOLERANCE:
                    eps = max(eps - eps_step, final_eps)
                new_iteration(nth, hcell, eps, self.g, self.keys, self.items, self.pos, self.size,
                              self.incons, self.n_incons, self.in_incons)
            iteration += 1
            outcome = UNFINISHED
            while outcome == UNFINISHED and time.perf_counter() < deadline:
                outcome, done = improve_path(
                    values, clear2, nth, t.per_heading, t.end_offset, t.end_heading, t.cost, t.centre,
                    t.centre_ptr, t.swept, t.swept_ptr, t.reach2, th.obsthresh, th.inscribed, th.circumscribed,
                    t.use_footprint, hcell, eps, iteration, self.call, goal, self.g, self.v, self.pred,
                    self.closed, self.seen, self.keys, self.items, self.pos, self.size, self.incons,
                    self.n_incons, self.in_incons, CHUNK_EXPANSIONS, best)
                expansions += done
            if outcome != SOLVED:
                break
            satisfied = eps
            iterations.append(Iteration(eps, int(self.g[goal]), expansions, time.perf_counter() - t0))
        elapsed = time.perf_counter() - t0
        if self.g[goal] < INFINITE_COST:
            return SearchResult("solved", self.path_to(goal), int(self.g[goal]), satisfied, expansions, elapsed,
                                iterations)
        status = "no_path" if outcome == NO_SOLUTION else "partial"
        end = int(best[0])
        return SearchResult(status, self.path_to(end), int(self.g[end]), math.inf, expansions, elapsed, iterations)

    def path_to(self, state: int) -> list[int]:
        """States from the start to `state` along the best predecessors."""
        path = [int(state)]
        while self.pred[path[-1]] >= 0:
            path.append(int(self.pred[path[-1]]))
        return path[::-1]
