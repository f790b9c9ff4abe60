"""GapKeeper: heads for the goal along the sampled heading that keeps the most room from people and walls.

Every 0.4 s it is given a `trials.controllers.base.Observation` and answers a `Plan` of 12 way-points 0.4 s apart.
"""

from __future__ import annotations

import math

import numpy as np

from trials.controllers.base import Observation, Plan

STEP_S, STEPS = 0.4, 12
#: Headings tried, relative to the goal's direction (rad).
HEADINGS = np.radians(np.arange(-80, 81, 10))
#: Wanted room (m, centre to centre) from a person and from a wall point; less costs, quadratically.
PERSON_ROOM_M, WALL_ROOM_M = 1.5, 0.8
#: Speeds (m/s): cruising, and the least when someone is within PERSON_ROOM_M.
CRUISE, CREEP = 0.9, 0.3


class GapKeeper:
    """A heading sampler (the navtrials controller interface: `plan`, and optionally `reset`, `end`, `details`)."""

    name = "GapKeeper"

    def __init__(self, person_room_m: float = PERSON_ROOM_M) -> None:
        self.person_room_m = person_room_m
        self.plans = 0

    def details(self) -> dict[str, str]:
        """What a run's metadata records about this controller (strings)."""
        return {"person_room_m": f"{self.person_room_m:g}"}

    def reset(self, seed: int) -> None:
        """A run starts; GapKeeper draws nothing at random, so the seed is not needed."""
        self.plans = 0

    def end(self, status: str) -> None:
        """The run ended: "goal", "collision", "timeout", "aborted" or "failed"."""

    def plan(self, observation: Observation) -> Plan:
        self.plans += 1
        here = np.asarray(observation.robot_pose[:2], dtype=float)
        goal = np.asarray(observation.goal[:2], dtype=float)
        history = np.asarray(observation.pedestrian_history, dtype=float)
        seen = history[np.isfinite(history[:, -1]).all(axis=1)] if len(history) else np.zeros((0, 2, 2))
        people = seen[:, -1]
        walking = np.nan_to_num((seen[:, -1] - seen[:, -2]) / STEP_S) if len(seen) else np.zeros((0, 2))
        walls = np.asarray(observation.obstacles, dtype=float).reshape(-1, 2)
        nearest = float(np.hypot(*(people - here).T).min()) if len(people) else math.inf
        speed = CREEP if nearest < self.person_room_m else CRUISE
        toward = math.atan2(*(goal - here)[::-1])
        times = STEP_S * np.arange(1, STEPS + 1)
        best, best_cost = None, math.inf
        for heading in toward + HEADINGS:
            path = here + speed * times[:, None] * np.array([math.cos(heading), math.sin(heading)])
            progress = np.hypot(*(goal - here)) - np.hypot(*(goal - path[-1]))
            cost = -progress
            if len(people):
                ahead = people[None] + times[:, None, None] * walking[None]
                gaps = np.hypot(*(path[:, None] - ahead).transpose(2, 0, 1))
                cost += np.square(np.maximum(self.person_room_m - gaps, 0.0)).sum()
            if len(walls):
                gaps = np.hypot(*(path[:, None] - walls[None]).transpose(2, 0, 1))
                cost += 4.0 * np.square(np.maximum(WALL_ROOM_M - gaps, 0.0)).sum()
            if cost < best_cost:
                best, best_cost = path, cost
        return Plan(best, STEP_S, {"speed": speed, "cost": best_cost, "nearest_person_m": nearest if len(people) else None})
