"""ARA*, anytime repairing A* (Likhachev, Gordon & Thrun 2003), over the lattice's flat state arrays.

A state is `cell * num_thetas + heading`, `cell` a flat index of the padded grid. Each iteration is
a weighted A* with priority g + int(eps * h) that expands every state at most once; states improved
after they were closed wait in INCONS and re-enter OPEN when eps drops by `eps_step`, so later
iterations reuse the earlier search. Each finished iteration's path costs at most eps times the
optimum. The compiled kernel runs a bounded number of expansions per call, so the Python driver
checks the clock (and the expansion count, a budget that does not depend on machine load) between
calls and no search outlives its budget; it takes its arrays grouped in
named tuples (the grid, the action tables, the thresholds, the per-state labels and the heap). The
edge rule is SBPL's GetActionCost; the bookkeeping follows SBPL's ARAPlanner, so epsilon-1 costs
equal SBPL's.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from trials.lattice.compiled import inlined_kernel, kernel
from trials.lattice.grid import PaddedGrid
from trials.lattice.heap import Heap, heapify, new_heap, pop_min, push_or_update
from trials.lattice.heuristic import INFINITE_COST

#: Kernel outcomes (SBPL's ImprovePath codes).
NO_SOLUTION, SOLVED, UNFINISHED = 0, 1, 2
EPS_TOLERANCE = 1e-6
CHUNK_EXPANSIONS = 1024


class Tables(NamedTuple):
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


class Thresholds(NamedTuple):
    """Cell values from which a cell is an obstacle, the robot's centre cannot stand on it, and the
    footprint must be checked (SBPL's obsthresh, inscribed and possibly-circumscribed thresholds)."""

    obsthresh: int
    inscribed: int
    circumscribed: int


class Labels(NamedTuple):
    """ARA*'s per-state arrays, kept from search to search; a state's entries are valid once `seen`
    holds the current call's number. INCONS lists the states improved after they were closed."""

    g: np.ndarray          # int64 cost from the start
    v: np.ndarray          # int64 cost when last expanded
    pred: np.ndarray       # int32 predecessor on the best path, -1 for none
    closed: np.ndarray     # int32 the iteration that last expanded it
    seen: np.ndarray       # int32 the call that last reset it
    incons: np.ndarray     # int32 INCONS, n_incons[0] states
    n_incons: np.ndarray   # int64 [count]
    in_incons: np.ndarray  # int8 per state: 1 while in INCONS


@kernel
def edge_cost(grid, cell, action, tables, thresholds):
    """The cost of `action` (flat heading*A+a) from a valid source `cell`, or -1 when it collides."""
    values = grid.values
    obsthresh, inscribed = thresholds.obsthresh, thresholds.inscribed
    end_value = values[cell + tables.end_offset[action]]
    if end_value >= obsthresh or end_value >= inscribed:
        return -1
    highest = 0
    centre, centre_ptr = tables.centre, tables.centre_ptr
    for k in range(centre_ptr[action], centre_ptr[action + 1]):
        highest = max(highest, values[cell + centre[k]])
        if highest >= inscribed:
            return -1
    if tables.use_footprint and highest >= thresholds.circumscribed and grid.clear2[cell] <= tables.reach2[action]:
        swept, swept_ptr = tables.swept, tables.swept_ptr
        for k in range(swept_ptr[action], swept_ptr[action + 1]):
            if values[cell + swept[k]] >= obsthresh:
                return -1
    highest = max(highest, values[cell], end_value)
    return tables.cost[action] * (highest + 1)


@inlined_kernel
def _touch(labels, state, call):
    if labels.seen[state] != call:
        labels.seen[state] = call
        labels.g[state] = INFINITE_COST
        labels.v[state] = INFINITE_COST
        labels.pred[state] = -1
        labels.closed[state] = 0


@kernel
def improve_path(grid, tables, thresholds, hcell, labels, heap, eps, iteration, call, goal, max_expansions, best):
    """Expand states until the goal's cost is within `eps` (SOLVED), OPEN (`heap`) runs dry
    (NO_SOLUTION) or `max_expansions` are spent (UNFINISHED). `best` keeps [state, h, g] of the
    expanded state nearest the goal by heuristic, for partial paths. Returns (outcome, expansions)."""
    values, num_thetas, per_heading = grid.values, tables.num_thetas, tables.per_heading
    g, v, keys, size = labels.g, labels.v, heap.keys, heap.size
    _touch(labels, goal, call)
    expansions = 0
    while size[0] > 0 and keys[1] < INFINITE_COST and g[goal] > keys[1]:
        if expansions >= max_expansions:
            return UNFINISHED, expansions
        state = pop_min(heap)
        v[state] = g[state]
        labels.closed[state] = iteration
        expansions += 1
        cell = state // num_thetas
        h = hcell[cell]
        if h < best[1] or (h == best[1] and g[state] < best[2]):
            best[0], best[1], best[2] = state, h, g[state]
        if state == goal or values[cell] >= thresholds.obsthresh:  # the goal absorbs; an invalid cell has no moves
            continue
        first = (state - cell * num_thetas) * per_heading
        for action in range(first, first + per_heading):
            step = edge_cost(grid, cell, action, tables, thresholds)
            if step < 0:
                continue
            nxt_cell = cell + tables.end_offset[action]
            nxt = nxt_cell * num_thetas + tables.end_heading[action]
            _touch(labels, nxt, call)
            new = v[state] + step
            if g[nxt] > new:
                g[nxt] = new
                labels.pred[nxt] = state
                if labels.closed[nxt] != iteration:
                    push_or_update(heap, nxt, new + np.int64(eps * hcell[nxt_cell]))
                elif labels.in_incons[nxt] == 0:
                    labels.in_incons[nxt] = 1
                    labels.incons[labels.n_incons[0]] = nxt
                    labels.n_incons[0] += 1
    if g[goal] == INFINITE_COST and size[0] == 0:
        return NO_SOLUTION, expansions
    if size[0] > 0 and g[goal] > keys[1]:
        return UNFINISHED, expansions
    if g[goal] == INFINITE_COST:
        return NO_SOLUTION, expansions
    return SOLVED, expansions


@kernel
def new_iteration(labels, heap, hcell, num_thetas, eps):
    """Move INCONS into OPEN and re-key OPEN for the new eps."""
    for i in range(labels.n_incons[0]):
        state = labels.incons[i]
        labels.in_incons[state] = 0
        push_or_update(heap, state, 0)
    labels.n_incons[0] = 0
    for slot in range(1, heap.size[0] + 1):
        state = heap.items[slot]
        heap.keys[slot] = labels.g[state] + np.int64(eps * hcell[state // num_thetas])
    heapify(heap)


@kernel
def clear_open(labels, heap):
    """Empty OPEN and INCONS."""
    for slot in range(1, heap.size[0] + 1):
        heap.pos[heap.items[slot]] = 0
    heap.size[0] = 0
    for i in range(labels.n_incons[0]):
        labels.in_incons[labels.incons[i]] = 0
    labels.n_incons[0] = 0


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
        self.labels = Labels(g=np.empty(n, np.int64), v=np.empty(n, np.int64), pred=np.empty(n, np.int32),
                             closed=np.zeros(n, np.int32), seen=np.zeros(n, np.int32), incons=np.empty(n, np.int32),
                             n_incons=np.zeros(1, np.int64), in_incons=np.zeros(n, np.int8))
        self.heap: Heap = new_heap(n)
        self.call = 0

    def search(self, grid: PaddedGrid, hcell: np.ndarray, start: int, goal: int, eps: float = 3.0,
               eps_step: float = 0.2, final_eps: float = 1.0, deadline: float = math.inf,
               max_expansions: float = math.inf) -> SearchResult:
        """ARA* from state `start` to state `goal` on `grid` until eps reaches `final_eps`,
        `time.perf_counter()` passes `deadline` or `max_expansions` states are expanded."""
        labels, heap, nth = self.labels, self.heap, self.tables.num_thetas
        t0 = time.perf_counter()
        self.call += 1
        clear_open(labels, heap)
        for state in (start, goal):
            if labels.seen[state] != self.call:
                labels.seen[state] = self.call
                labels.g[state] = labels.v[state] = INFINITE_COST
                labels.pred[state], labels.closed[state] = -1, 0
        labels.g[start] = 0
        push_or_update(heap, start, np.int64(eps * hcell[start // nth]))
        best = np.array([start, hcell[start // nth], 0], dtype=np.int64)
        iterations: list[Iteration] = []
        satisfied, iteration, expansions, outcome = math.inf, 0, 0, UNFINISHED
        def within_budget() -> bool:
            return expansions < max_expansions and time.perf_counter() < deadline

        while satisfied > final_eps and within_budget():
            if iteration > 0:
                if abs(satisfied - eps) < EPS_TOLERANCE:
                    eps = max(eps - eps_step, final_eps)
                new_iteration(labels, heap, hcell, nth, eps)
            iteration += 1
            outcome = UNFINISHED
            while outcome == UNFINISHED and within_budget():
                chunk = int(min(CHUNK_EXPANSIONS, max_expansions - expansions))
                outcome, done = improve_path(grid, self.tables, self.thresholds, hcell, labels, heap, eps, iteration,
                                             self.call, goal, chunk, best)
                expansions += done
            if outcome != SOLVED:
                break
            satisfied = eps
            iterations.append(Iteration(eps, int(labels.g[goal]), expansions, time.perf_counter() - t0))
        elapsed = time.perf_counter() - t0
        if labels.g[goal] < INFINITE_COST:
            return SearchResult("solved", self.path_to(goal), int(labels.g[goal]), satisfied, expansions, elapsed,
                                iterations)
        status = "no_path" if outcome == NO_SOLUTION else "partial"
        end = int(best[0])
        return SearchResult(status, self.path_to(end), int(labels.g[end]), math.inf, expansions, elapsed, iterations)

    def path_to(self, state: int) -> list[int]:
        """States from the start to `state` along the best predecessors."""
        pred = self.labels.pred
        path = [int(state)]
        while pred[path[-1]] >= 0:
            path.append(int(pred[path[-1]]))
        return path[::-1]
