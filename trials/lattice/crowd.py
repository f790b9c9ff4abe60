"""Receding-horizon lattice planning among moving pedestrians, in arrays: pose, goal, tracks in, way-points out.

Every step it draws the tracked pedestrians into a cost grid around the robot and the goal, plans
from the robot's pose to the goal with ARA* within its budget (wall-clock seconds, or a number of
expansions where a run must reproduce on any machine), and returns way-points one step apart along
the path, timed at the robot's nominal speed (turns in place take no time: the way-points cannot
show them). A covered or unreachable goal is replaced by the nearest cell the robot can reach; a
search out of budget gives the best partial path. It never raises while planning and never stands
still for want of a plan; each step climbs this ladder until a rung moves the robot, and the
record's `rung` says which did:

1. `margin`: plan with the pedestrians grown by the comfort margin;
2. `no_margin`: the start lies inside the margin, or that search cannot move the robot: plan
   with the bare bodies;
3. `escape`: the robot touches a body's inscribed zone or still has no path: drive `ESCAPE_STEP_M`
   toward the direction that most increases its distance from the nearest pedestrian (behind:
   it backs off; to the side: its follower turns in place first), and plan afresh next step;
4. `hold`: no direction gains clearance (with someone within its turning circle, only straight
   ahead or behind count): stand still this step only, until people move.

Two more reasons to stand still: `wait`, the robot already stands on the reachable cell nearest a
goal that people cover, and at the goal or with an unusable observation.
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
#: The recovery ladder's rungs (module docstring), as the record names them.
MARGIN, NO_MARGIN, ESCAPE, HOLD, WAIT = "margin", "no_margin", "escape", "hold", "wait"
#: Reasons to stand still that no rung can help.
BAD_OBSERVATION, AT_GOAL = "bad_observation", "at_goal"
#: An escape move: how far (m), how fast (m/s, the Husky's reverse limit), among how many directions.
ESCAPE_STEP_M, ESCAPE_SPEED, ESCAPE_DIRECTIONS = 0.5, 0.5, 16
#: Directions within this angle of straight ahead or straight behind need no turn in place (rad).
STRAIGHT_RAD = math.pi / 4
#: An escape must gain at least this much clearance (m).
MIN_GAIN_M = 0.01
#: A point of the static world is lethal this far around (m): its points come 0.2 m apart
#: (`trials.controllers.obstacles.OBSTACLE_SPACING_M`), so a wall stays closed between them.
OBSTACLE_RADIUS_M = 0.15


def escape_point(pose: np.ndarray, centres: np.ndarray, turn_clearance: float) -> np.ndarray | None:
    """Where to escape to: of the points `ESCAPE_STEP_M` from the robot's `pose` (x, y, heading) in
    `ESCAPE_DIRECTIONS` directions, the one farthest from its nearest pedestrian centre (`centres`,
    (k, 2)), or None when none gains `MIN_GAIN_M`. With a centre nearer than `turn_clearance`, where
    turning in place would sweep into someone, only the directions within `STRAIGHT_RAD` of ahead or
    behind are candidates. Ties go to the first direction counterclockwise from ahead."""
    if not len(centres):
        return None
    bearings = 2 * math.pi * np.arange(ESCAPE_DIRECTIONS) / ESCAPE_DIRECTIONS
    angles = pose[2] + bearings
    points = pose[:2] + ESCAPE_STEP_M * np.column_stack([np.cos(angles), np.sin(angles)])

    def clearance(at: np.ndarray) -> np.ndarray:
        return np.hypot(*(at[:, None, :] - centres[None, :, :]).transpose(2, 0, 1)).min(axis=1)

    now = float(clearance(pose[None, :2])[0])
    gains = clearance(points) - now
    if now < turn_clearance:
        off_axis = np.abs(np.remainder(bearings + math.pi / 2, math.pi) - math.pi / 2)
        gains[off_axis > STRAIGHT_RAD + 1e-9] = -math.inf
    best = int(np.argmax(gains))
    return points[best] if gains[best] >= MIN_GAIN_M else None


def circumscribed_radius(polygon: Polygon) -> float:
    """The radius of the circle the polygon sweeps turning in place about the robot's origin."""
    return float(np.hypot(*np.asarray(polygon, dtype=np.float64).T).max()) if len(polygon) else 0.0


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
        budget_expansions: when set, each search stops after this many expansions instead, and
            `budget_s` is not used: the same answer on any machine, at any load.
        eps, eps_step: ARA*'s initial suboptimality bound and its decrement per iteration.
        window_margin: metres of grid around the robot and the goal.
        goal_tolerance: within this distance (m) of the goal the robot holds.
        primitives: the motion primitives (default: `husky_primitives(cell_size)`).
        turn_45_s: time to turn 45 degrees in place (s).
    """

    def __init__(self, *, footprint: Polygon, speed: float, step_s: float, horizon_steps: int,
                 cell_size: float = 0.1, pedestrian_radius: float = 0.3, comfort_margin: float = 0.2,
                 predict_s: float = 0.0, budget_s: float = 0.25, budget_expansions: int | None = None,
                 eps: float = 3.0, eps_step: float = 0.2,
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
        if budget_expansions is not None and not budget_expansions >= 1:
            raise LatticeError(f"lattice controller: budget_expansions must be at least 1, got {budget_expansions}")
        self.budget_expansions = budget_expansions
        self.cell_size, self.pedestrian_radius, self.comfort_margin = cell_size, pedestrian_radius, comfort_margin
        self.predict_s, self.budget_s, self.eps, self.eps_step = predict_s, budget_s, eps, eps_step
        self.horizon_steps, self.window_margin, self.goal_tolerance = int(horizon_steps), window_margin, goal_tolerance
        self.step_s = step_s
        prims = primitives if primitives is not None else husky_primitives(cell_size)
        self._template = Environment(np.zeros((1, 1), np.uint8), cell_size, prims.num_angles, OBSTHRESH,
                                     INSCRIBED_THRESH, CIRCUMSCRIBED_THRESH, speed, turn_45_s)
        self.actions = build_actions(prims, self._template, footprint)
        self.inscribed = inscribed_radius(self.actions.polygon)
        self.turn_clearance = circumscribed_radius(self.actions.polygon) + pedestrian_radius
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

    def situation(self, pose: np.ndarray, goal: np.ndarray, pedestrian_history: np.ndarray,
                  margin: float | None = None, obstacles: np.ndarray | None = None) -> Situation:
        """The grid, start and target for the robot's `pose` (x, y, heading), its `goal` (x, y), the
        pedestrians' tracks `pedestrian_history` ((N, T, 2), oldest first, NaN before a track was seen),
        with the pedestrians grown by `margin` (default: the comfort margin), and the static world's points
        `obstacles` ((M, 2), walls: lethal within `OBSTACLE_RADIUS_M`); or the reason there is no search to run."""
        pose = np.asarray(pose, dtype=np.float64)
        goal = np.asarray(goal, dtype=np.float64)[:2]
        margin = self.comfort_margin if margin is None else margin
        record: dict[str, Any] = {"status": "", "holding": False, "pedestrians": len(pedestrian_history),
                                  "margin": margin}
        if not (np.isfinite(pose).all() and np.isfinite(goal).all()):
            return Situation(np.nan_to_num(pose), record, BAD_OBSERVATION, "robot pose or goal is not finite")
        if np.hypot(*(goal - pose[:2])) <= self.goal_tolerance:
            return Situation(pose, record, AT_GOAL, "within the goal tolerance")
        planner, window = self._planner_for(pose[:2], goal)
        start = self._state(window, pose)
        centres = predicted_centres(pedestrian_history, self.predict_s, self.step_s)
        grid = pedestrian_costmap(window, centres, self.pedestrian_radius + margin, self.inscribed)
        if obstacles is not None and len(obstacles):
            np.maximum(grid, pedestrian_costmap(window, np.asarray(obstacles, dtype=np.float64).reshape(-1, 2), OBSTACLE_RADIUS_M,
                                                self.inscribed), out=grid)
        planner.set_grid(grid)
        collision = planner.collision(start)
        if collision is not None:
            return Situation(pose, record, "start_in_collision", collision)
        wanted = (*self._state(window, np.array([*goal, 0.0]))[:2], self._goal_heading)
        target = self._target(planner, start, wanted)
        record["goal_moved"] = target != wanted
        if target is None:
            return Situation(pose, record, "goal_blocked", "no free cell within reach")
        record["target"] = window.to_world(planner.env.to_pose(target)[:2]).tolist()
        return Situation(pose, record, planner=planner, window=window, start=start, target=target)

    def plan(self, pose: np.ndarray, goal: np.ndarray, pedestrian_history: np.ndarray, obstacles: np.ndarray | None = None) -> CrowdPlan:
        """Way-points for the next `horizon_steps` steps, climbing the recovery ladder (module docstring)
        until a rung moves the robot; the arguments as for `situation`."""
        t0 = time.perf_counter()
        record: dict[str, Any] = {}
        rungs = [(MARGIN, self.comfort_margin)] + [(NO_MARGIN, 0.0)] * (self.comfort_margin > 0)
        for rung, margin in rungs:
            situation = self.situation(pose, goal, pedestrian_history, margin, obstacles)
            if situation.hold in (BAD_OBSERVATION, AT_GOAL):  # no rung: nothing to recover from
                return self._hold(situation.pose, {**situation.record, "status": situation.hold,
                                                   "message": situation.message, "plan_seconds": time.perf_counter() - t0})
            record = {**situation.record, "rung": rung}
            if situation.hold is not None:
                record.update(status=situation.hold, message=situation.message)
                continue
            result = situation.planner.plan(situation.start, situation.target, self.eps, self.eps_step,
                                            **self._budget(t0))
            record.update(self._search_record(result))
            if len(result.states) >= 2:
                record["plan_seconds"] = time.perf_counter() - t0
                return CrowdPlan(situation.window.to_world(self._waypoints(result)), record)
        if record.get("status") == "solved":  # it stands on the reachable cell nearest a goal people cover
            return self._hold(np.asarray(pose, np.float64), {**record, "rung": WAIT,
                                                             "plan_seconds": time.perf_counter() - t0})
        return self._escape(np.asarray(pose, dtype=np.float64), pedestrian_history, record, t0)

    def _budget(self, t0: float) -> dict[str, float]:
        """The search's budget: the expansion budget when one is set, else what is left of `budget_s`."""
        if self.budget_expansions is not None:
            return {"budget": math.inf, "max_expansions": self.budget_expansions}
        return {"budget": max(t0 + self.budget_s - RESERVE_S - time.perf_counter(), 0.0)}

    def _waypoints(self, result: PlanResult) -> np.ndarray:
        """(horizon_steps, 2) window positions along the path one `step_s` apart, timed at nominal speed
        with turns in place taking no time: way-points show no heading, so the robot's follower turns
        toward them itself, and a path timed to start with a turn would show the robot standing still."""
        times, clock = [], 0.0
        for heading, action in result.actions:
            prim = self.actions.primitives[heading][action]
            samples = len(prim.poses) - 1
            seconds = 0.0 if prim.end[0] == prim.end[1] == 0 else float(self.actions.seconds[heading, action])
            times.extend(clock + seconds * np.arange(samples) / samples)
            clock += seconds
        times.append(clock)
        moments = np.asarray(times)
        last = np.append(np.diff(moments) > 0, True)  # of poses passed at the same moment, the last
        ahead = self.step_s * np.arange(1, self.horizon_steps + 1)
        return np.column_stack([np.interp(ahead, moments[last], result.poses[last, i]) for i in (0, 1)])

    def _escape(self, pose: np.ndarray, pedestrian_history: np.ndarray, record: dict[str, Any],
                t0: float) -> CrowdPlan:
        """The last rungs: a short move toward the most clearance from the pedestrians, or, when no
        direction gains any, holding still until they move."""
        centres = predicted_centres(pedestrian_history, 0.0, self.step_s)
        target = escape_point(pose, centres, self.turn_clearance)
        if target is None:
            return self._hold(pose, {**record, "rung": HOLD, "plan_seconds": time.perf_counter() - t0})
        direction = target - pose[:2]
        reach = np.minimum(ESCAPE_SPEED * self.step_s * np.arange(1, self.horizon_steps + 1), ESCAPE_STEP_M)
        waypoints = pose[:2] + reach[:, None] * direction / np.hypot(*direction)
        record = {**record, "rung": ESCAPE, "escape_to": target.tolist(), "plan_seconds": time.perf_counter() - t0}
        return CrowdPlan(waypoints, record)

    @staticmethod
    def _search_record(result: PlanResult) -> dict[str, Any]:
        return {"status": result.status, "message": result.message, "cost": result.cost,
                "eps": None if math.isinf(result.eps) else result.eps, "expansions": result.expansions,
                "iterations": len(result.iterations), "heuristic_seconds": result.heuristic_seconds,
                "search_seconds": result.seconds}
