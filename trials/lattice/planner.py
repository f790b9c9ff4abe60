"""The lattice planner: environment, successor tables, heuristic and ARA* put together.

Everything that depends only on the primitives, the footprint and the map size is built once;
`set_grid` swaps in new cell values of the same size (the crowd planner's replanning), and `plan`
runs one anytime search within a time budget.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from trials.lattice.actions import ActionTable, build_actions
from trials.lattice.environment import Environment, cell_to_cont, heading_to_cont
from trials.lattice.footprint import Polygon, footprint_cells
from trials.lattice.grid import PaddedGrid, pad_grid
from trials.lattice.heuristic import grid_heuristic
from trials.lattice.primitives import PrimitiveSet
from trials.lattice.search import AraStar, Iteration, Tables, Thresholds, edge_cost

State = tuple[int, int, int]


@dataclass
class PlanResult:
    """A planning outcome.

    Attributes:
        status: "solved", "partial" (budget spent before reaching the goal; the path leads to the
            expanded state nearest the goal), "no_path" (none exists; path as for partial), or, with
            nothing searched and an empty path, "start_outside_map", "goal_outside_map",
            "start_in_collision" or "goal_in_collision".
        message: one line saying what happened.
        poses: (K, 3) world x, y, theta along the path (cell centres plus primitive poses).
        times: (K,) seconds at which the robot passes each pose at nominal speed.
        states: lattice states (x, y, heading) along the path.
        cost: the path's cost (SBPL units: milliseconds at nominal speed times cell factors).
        eps: the proven suboptimality bound of the path (inf when none).
        iterations: every finished ARA* iteration.
        heuristic_seconds: time spent on the 2-D heuristic.
        seconds: total planning time.
        actions: per path edge, the (heading, action) used.
    """

    status: str
    message: str
    poses: np.ndarray
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    states: list[State] = field(default_factory=list)
    cost: int = 0
    eps: float = math.inf
    expansions: int = 0
    iterations: list[Iteration] = field(default_factory=list)
    heuristic_seconds: float = 0.0
    seconds: float = 0.0
    actions: list[tuple[int, int]] = field(default_factory=list)

    @property
    def reached_goal(self) -> bool:
        return self.status == "solved"


def make_planner(env: Environment, prims: PrimitiveSet, polygon: Polygon) -> LatticePlanner:
    """A planner for `env` with the primitives `prims` and a footprint polygon (robot frame, metres;
    fewer than two points for a point robot)."""
    return LatticePlanner(env, build_actions(prims, env, polygon))


class LatticePlanner:
    """Plans on an `Environment`'s grid with successor tables built for it (`build_actions`)."""

    def __init__(self, env: Environment, actions: ActionTable) -> None:
        self.env, self.actions = env, actions
        self.grid: PaddedGrid = pad_grid(env.grid, self.actions.reach + 1, env.obsthresh)
        a = self.actions
        flat = a.end.reshape(-1, 3)
        self.tables = Tables(
            end_offset=self.grid.offsets(flat[:, :2]), end_heading=flat[:, 2].copy(), cost=a.cost.ravel(),
            centre=self.grid.offsets(a.centre), centre_ptr=a.centre_ptr, swept=self.grid.offsets(a.swept),
            swept_ptr=a.swept_ptr, reach2=a.reach2.ravel(), num_thetas=a.num_thetas, per_heading=a.per_heading,
            use_footprint=a.use_footprint)
        self.thresholds = Thresholds(env.obsthresh, env.cost_inscribed_thresh, env.cost_possibly_circumscribed_thresh)
        self.search = AraStar(self.grid.values.size, self.tables, self.thresholds)
        self._footprints = [footprint_cells(actions.polygon, (0.0, 0.0, heading_to_cont(t, env.num_thetas)),
                                            env.cell_size) for t in range(env.num_thetas)]

    def set_grid(self, grid: np.ndarray) -> None:
        """New cell values for the same map size (and thresholds)."""
        if grid.shape != self.env.grid.shape:
            raise ValueError(f"grid shape {grid.shape} differs from the planner's {self.env.grid.shape}")
        self.env = replace(self.env, grid=grid)
        self.grid = pad_grid(grid, self.grid.pad, self.env.obsthresh)

    def collision(self, state: State) -> str | None:
        """Why the robot cannot stand at `state` (centre cell or footprint), or None."""
        x, y, t = state
        value = self.env.grid[y, x]
        if value >= self.env.cost_inscribed_thresh or value >= self.env.obsthresh:
            return f"its cell ({x}, {y}) has cost {value}"
        for cx, cy in self._footprints[t]:
            if not self.env.on_map(x + cx, y + cy):
                return "the footprint leaves the map"
            if self.env.grid[y + cy, x + cx] >= self.env.obsthresh:
                return f"the footprint covers obstacle cell ({x + cx}, {y + cy})"
        return None

    def _refusal(self, start: State, goal: State) -> tuple[str, str] | None:
        for name, state in (("start", start), ("goal", goal)):
            if not self.env.on_map(state[0], state[1]):
                return (f"{name}_outside_map", f"the {name} cell {state[:2]} is outside the "
                        f"{self.env.width} x {self.env.height} map")
        for name, state in (("start", start), ("goal", goal)):
            why = self.collision(state)
            if why is not None:
                return f"{name}_in_collision", f"the {name} {state} is in collision: {why}"
        return None

    def plan(self, start: State | None = None, goal: State | None = None, eps: float = 3.0, eps_step: float = 0.2,
             budget: float = 10.0, final_eps: float = 1.0, max_expansions: float = math.inf) -> PlanResult:
        """Search from `start` to `goal` (lattice states; default: the environment's) with ARA*.

        The search starts at `eps` and lowers it by `eps_step` down to `final_eps`, returning the best
        path found when eps reaches `final_eps`, when `budget` seconds (heuristic included) are spent or
        when `max_expansions` states are expanded (a budget that gives the same answer on any machine).
        """
        t0 = time.perf_counter()
        start = start if start is not None else self.env.to_state(self.env.start)
        goal = goal if goal is not None else self.env.to_state(self.env.goal)
        refused = self._refusal(start, goal)
        if refused is not None:
            return PlanResult(refused[0], refused[1], np.zeros((0, 3)), seconds=time.perf_counter() - t0)
        env, n = self.env, self.tables.num_thetas
        hcell = grid_heuristic(self.grid, goal[:2], start[:2], env.cell_size, env.cost_inscribed_thresh,
                               env.nominal_vel)
        t_heuristic = time.perf_counter() - t0
        found = self.search.search(self.grid, hcell, self._state_id(start), self._state_id(goal), eps, eps_step,
                                   final_eps, deadline=t0 + budget, max_expansions=max_expansions)
        states = [(*self.grid.xy(s // n), s % n) for s in found.states]
        actions, poses, times = self._trace(states)
        bound = "no bound yet" if math.isinf(found.eps) else f"within eps {found.eps:g} of optimal"
        spent = " or ".join([f"{budget:g} s"] * (not math.isinf(budget))
                            + [f"{max_expansions:g} expansions"] * (not math.isinf(max_expansions)))
        message = {"solved": f"path of cost {found.cost} {bound}",
                   "partial": f"no path to the goal within {spent}; the path leads to the state nearest it",
                   "no_path": "no path to the goal exists; the path leads to the reachable state nearest it",
                   }[found.status]
        return PlanResult(found.status, message, poses, times, states, found.cost, found.eps, found.expansions,
                          found.iterations, t_heuristic, time.perf_counter() - t0, actions)

    def _state_id(self, state: State) -> int:
        return self.grid.index(state[0], state[1]) * self.tables.num_thetas + state[2]

    def edge(self, source: State, target: State) -> tuple[int, int]:
        """The cheapest valid action from `source` to `target` and its cost ((-1, -1) when none)."""
        t, th = self.tables, self.thresholds
        cell = self.grid.index(source[0], source[1])
        best = (-1, -1)
        if self.grid.values[cell] >= th.obsthresh:
            return best
        for action in range(source[2] * t.per_heading, (source[2] + 1) * t.per_heading):
            dx, dy, heading = self.actions.end.reshape(-1, 3)[action]
            if (source[0] + dx, source[1] + dy, heading) != tuple(target):
                continue
            cost = edge_cost(self.grid, cell, action, t, th)
            if cost >= 0 and (best[1] < 0 or cost < best[1]):
                best = (action % t.per_heading, int(cost))
        return best

    def _trace(self, states: list[State]) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
        """The actions along a state path, its world poses and the time at each pose."""
        cs = self.env.cell_size
        actions, poses, times, clock = [], [], [], 0.0
        for source, target in zip(states, states[1:]):
            action, _ = self.edge(source, target)
            actions.append((source[2], action))
            prim = self.actions.primitives[source[2]][action]
            offset = np.array([cell_to_cont(source[0], cs), cell_to_cont(source[1], cs), 0.0])
            poses.extend(prim.poses[:-1] + offset)
            duration = self.actions.seconds[source[2], action]
            times.extend(clock + duration * np.arange(len(prim.poses) - 1) / (len(prim.poses) - 1))
            clock += duration
        if states:
            x, y, _ = states[-1]
            last = self.actions.primitives[actions[-1][0]][actions[-1][1]].poses[-1, 2] if actions else \
                self.env.to_pose(states[-1])[2]
            poses.append(np.array([cell_to_cont(x, cs), cell_to_cont(y, cs), last]))
            times.append(clock)
        return actions, np.array(poses, dtype=np.float64).reshape(-1, 3), np.array(times, dtype=np.float64)
