"""Receding-horizon lattice planning among moving pedestrians, in arrays: pose, goal, tracks in, way-points out.

Every step it draws the tracked pedestrians into a cost grid around the robot and the goal, plans
from the robot's pose to the goal with ARA* within its time budget, and returns way-points one step
apart along the path, timed at the robot's nominal speed. It never raises while planning: when the
robot already stands too close to someone it first retries without the comfort margin, then holds
still; when the goal is covered or out of reach it aims at the nearest cell it can reach; when no
path is found in time it follows the best partial path. The record says which.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import ndimage

from trials.lattice.actions import build_actions
from trials.lattice.costmap import (
    CIRCUMSCRIBED_THRESH,
    FREE,
    INSCRIBED_THRESH,
    OBSTHRESH,
    Window,
    pedestrian_costmap,
    predicted_centres,
)
from trials.lattice.environment import Environment, cont_to_cell, cont_to_heading
from trials.lattice.errors import LatticeError
from trials.lattice.footprint import Polygon
from trials.lattice.husky import HUSKY_TURN_45_S, husky_primitives
from trials.lattice.planner import LatticePlanner, PlanResult, State
from trials.lattice.primitives import PrimitiveSet

#: Time kept back from the budget for the way-points and the record.
RESERVE_S = 0.02
#: Free cells tried, nearest first, when the goal is covered or out of reach.
GOAL_CANDIDATES = 400


def inscribed_radius(polygon: Polygon) -> float:
    """The radius of the largest circle about the robot's origin inside the polygon (0 for a point robot)."""
    if len(polygon) < 3:
        return 0.0
    pts = np.asarray(polygon, dtype=np.float64)
    radius = math.inf
    for a, b in zip(pts, np.roll(pts, -1, axis=0)):
        edge = b - a
        t = np.clip(-a @ edge / (edge @ edge), 0.0, 1.0)
        radius = min(radius, float(np.hypot(*(a + t * edge))))
    return radius


@dataclass
class Situation:
    """One step's planning problem (`planner`, `start`, `target` on `window`), or with `hold` set, the
    reason there is none; `record` collects what the step will log."""

    pose: np.ndarray
    record: dict[str, Any]
    hold: str | None = None
    message: str = ""
    planner: LatticePlanner | None = None
    window: Window | None = None
    start: State | None = None
    target: State | None = None


@dataclass(frozen=True)
class CrowdPlan:
    """One step's answer: `waypoints` (horizon_steps, 2) in the world frame, one every `step_s` ahead
    (all at the robot's position when it holds), and `record`, what the step did, ready for JSON."""

    waypoints: np.ndarray
    record: dict[str, Any]


class CrowdPlanner:
    """SBPL-like lattice planning among pedestrians, replanned every step from the robot's pose.

    Args:
        footprint: the robot's outline, robot frame (m; fewer than two points: a point robot).
        speed: the robot's nominal speed (m/s).
        step_s: seconds between way-points, and between a track's positions.
        horizon_steps: way-points returned, one every `step_s`.
        cell_size: grid resolution in metres (0.1 or 0.05).
        pedestrian_radius: a pedestrian's body radius (m).
        comfort_margin: clearance (m) the footprint keeps from a pedestrian's body.
        predict_s: also block each pedestrian's constant-velocity prediction this far ahead (s); 0: now only.
        budget_s: wall-clock budget of one `plan` call (s), everything included.
        eps, eps_step: ARA*'s initial suboptimality bound and its decrement per iteration.
        window_margin: metres of grid around the robot and the goal.
        goal_tolerance: within this distance (m) of the goal the robot holds.
        primitives: the motion primitives (default: `husky_primitives(cell_size)`).
        turn_45_s: time to turn 45 degrees in place (s).
    """

    def __init__(self, *, footprint: Polygon, speed: float, step_s: float, horizon_steps: int,
                 cell_size: float = 0.1, pedestrian_radius: float = 0.3, comfort_margin: float = 0.2,
                 predict_s: float = 0.0, budget_s: float = 0.25, eps: float = 3.0, eps_step: float = 0.2,
                 window_margin: float = 4.0, goal_tolerance: float = 0.3, primitives: PrimitiveSet | None = None,
                 turn_45_s: float = HUSKY_TURN_45_S) -> None:
        for option, value in (("cell_size", cell_size), ("budget_s", budget_s), ("speed", speed),
                              ("step_s", step_s), ("turn_45_s", turn_45_s), ("horizon_steps", horizon_steps),
                              ("eps_step", eps_step)):
            if not value > 0:
                raise LatticeError(f"lattice controller: {option} must be positive, got {value}")
        for option, value in (("pedestrian_radius", pedestrian_radius), ("comfort_margin", comfort_margin),
                              ("predict_s", predict_s), ("window_margin", window_margin),
                              ("goal_tolerance", goal_tolerance)):
            if not value >= 0:
                raise LatticeError(f"lattice controller: {option} must not be negative, got {value}")
        if not eps >= 1:
            raise LatticeError(f"lattice controller: eps must be at least 1, got {eps}")
        self.cell_size, self.pedestrian_radius, self.comfort_margin = cell_size, pedestrian_radius, comfort_margin
        self.predict_s, self.budget_s, self.eps, self.eps_step = predict_s, budget_s, eps, eps_step
        self.horizon_steps, self.window_margin, self.goal_tolerance = int(horizon_steps), window_margin, goal_tolerance
        self.step_s = step_s
        prims = primitives if primitives is not None else husky_primitives(cell_size)
        self._template = Environment(np.zeros((1, 1), np.uint8), cell_size, prims.num_angles, OBSTHRESH,
                                     INSCRIBED_THRESH, CIRCUMSCRIBED_THRESH, speed, turn_45_s)
        self.actions = build_actions(prims, self._template, footprint)
        self.inscribed = inscribed_radius(self.actions.polygon)
        self.reset()
        self._warm_up()

    def reset(self) -> None:
        """Start a new run: forget the grid window and the goal heading."""
        self._window: Window | None = None
        self._planner: LatticePlanner | None = None
        self._goal: np.ndarray | None = None
        self._goal_heading = 0

    def _warm_up(self) -> None:
        """Compile (or load) every compiled function once, so that no trial step pays for it: a small
        search with no time limit, run down to epsilon 1."""
        middle = self.actions.reach + 2
        planner = self._new_planner(Window((0.0, 0.0), self.cell_size, 2 * middle + 8, 2 * middle))
        planner.plan((middle, middle, 0), (middle + 8, middle, 0), budget=math.inf)

    def _new_planner(self, window: Window) -> LatticePlanner:
        grid = np.zeros((window.height, window.width), np.uint8)
        return LatticePlanner(replace(self._template, grid=grid), self.actions)

    def _planner_for(self, robot: np.ndarray, goal: np.ndarray) -> tuple[LatticePlanner, Window]:
        """The run's planner, rebuilt when the goal changes or the robot nears the window's edge."""
        if (self._window is None or self._planner is None or self._goal is None
                or not np.array_equal(goal, self._goal) or not self._window.contains(robot, border=1.0)):
            if self._goal is None or not np.array_equal(goal, self._goal):
                direction = goal - robot
                self._goal_heading = cont_to_heading(math.atan2(direction[1], direction[0]),
                                                     self.actions.num_thetas)
            self._goal = goal.copy()
            self._window = Window.around(np.array([robot, goal]), self.window_margin, self.cell_size)
            self._planner = self._new_planner(self._window)
        return self._planner, self._window

    def _state(self, window: Window, pose: np.ndarray) -> State:
        x, y = window.to_local(pose[:2])
        return (cont_to_cell(x, self.cell_size), cont_to_cell(y, self.cell_size),
                cont_to_heading(float(pose[2]), self.actions.num_thetas))

    def _target(self, planner: LatticePlanner, start: State, goal: State) -> State | None:
        """`goal`, or when the robot cannot stand there or reach it, the nearest cell (same heading) it can
        stand on within the area its centre can reach from `start`."""
        grid = planner.env.grid
        labels, _ = ndimage.label(grid < INSCRIBED_THRESH, structure=np.ones((3, 3), dtype=bool))
        reachable = labels == labels[start[1], start[0]]
        if planner.env.on_map(goal[0], goal[1]) and reachable[goal[1], goal[0]] and planner.collision(goal) is None:
            return goal
        ys, xs = np.nonzero(reachable & (grid == FREE))
        order = np.argsort((xs - goal[0]) ** 2 + (ys - goal[1]) ** 2, kind="stable")
        for i in order[:GOAL_CANDIDATES]:
            candidate = (int(xs[i]), int(ys[i]), goal[2])
            if planner.collision(candidate) is None:
                return candidate
        return None

    def _hold(self, robot: np.ndarray, record: dict[str, Any]) -> CrowdPlan:
        return CrowdPlan(np.repeat(np.asarray(robot[:2], np.float64)[None, :], self.horizon_steps, axis=0),
                         {**record, "holding": True})

    def situation(self, pose: np.ndarray, goal: np.ndarray, pedestrian_history: np.ndarray) -> Situation:
        """The grid, start and target for the robot's `pose` (x, y, heading), its `goal` (x, y) and the
        pedestrians' tracks `pedestrian_history` ((N, T, 2), oldest first, NaN before a track was seen),
        or the reason the robot must hold."""
        pose = np.asarray(pose, dtype=np.float64)
        goal = np.asarray(goal, dtype=np.float64)[:2]
        record: dict[str, Any] = {"status": "", "holding": False, "pedestrians": len(pedestrian_history)}
        if not (np.isfinite(pose).all() and np.isfinite(goal).all()):
            return Situation(np.nan_to_num(pose), record, "bad_observation", "robot pose or goal is not finite")
        if np.hypot(*(goal - pose[:2])) <= self.goal_tolerance:
            return Situation(pose, record, "at_goal", "within the goal tolerance")
        planner, window = self._planner_for(pose[:2], goal)
        start = self._state(window, pose)
        centres = predicted_centres(pedestrian_history, self.predict_s, self.step_s)
        for margin in dict.fromkeys((self.comfort_margin, 0.0)):
            planner.set_grid(pedestrian_costmap(window, centres, self.pedestrian_radius + margin, self.inscribed))
            collision = planner.collision(start)
            if collision is None:
                break
        record["margin"] = margin
        if collision is not None:
            return Situation(pose, record, "start_in_collision", collision)
        wanted = (*self._state(window, np.array([*goal, 0.0]))[:2], self._goal_heading)
        target = self._target(planner, start, wanted)
        record["goal_moved"] = target != wanted
        if target is None:
            return Situation(pose, record, "goal_blocked", "no free cell within reach")
        record["target"] = window.to_world(planner.env.to_pose(target)[:2]).tolist()
        return Situation(pose, record, planner=planner, window=window, start=start, target=target)

    def plan(self, pose: np.ndarray, goal: np.ndarray, pedestrian_history: np.ndarray) -> CrowdPlan:
        """Way-points for the next `horizon_steps` steps (held in place when no move is possible); the
        arguments as for `situation`."""
        t0 = time.perf_counter()
        situation = self.situation(pose, goal, pedestrian_history)
        record = situation.record
        if situation.hold is not None:
            return self._hold(situation.pose, {**record, "status": situation.hold, "message": situation.message,
                                               "plan_seconds": time.perf_counter() - t0})
        budget = max(t0 + self.budget_s - RESERVE_S - time.perf_counter(), 0.0)
        result = situation.planner.plan(situation.start, situation.target, self.eps, self.eps_step, budget=budget)
        record.update(self._search_record(result))
        if len(result.states) < 2:
            return self._hold(situation.pose, {**record, "plan_seconds": time.perf_counter() - t0})
        ahead = self.step_s * np.arange(1, self.horizon_steps + 1)
        local = np.column_stack([np.interp(ahead, result.times, result.poses[:, i]) for i in (0, 1)])
        record["plan_seconds"] = time.perf_counter() - t0
        return CrowdPlan(situation.window.to_world(local), record)

    @staticmethod
    def _search_record(result: PlanResult) -> dict[str, Any]:
        return {"status": result.status, "message": result.message, "cost": result.cost,
                "eps": None if math.isinf(result.eps) else result.eps, "expansions": result.expansions,
                "iterations": len(result.iterations), "heuristic_seconds": result.heuristic_seconds,
                "search_seconds": result.seconds}
