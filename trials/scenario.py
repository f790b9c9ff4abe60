"""From a plan row to the scene of one simulated trial: the robot's task and where people walk.

The layout is modelled on the paper's field trials (world frame `map`, metres, x along the robot's
nominal path): the robot starts at the origin facing +x and must reach a goal 10 m ahead, just to
the right of a cone. Pedestrians walk in one of three patterns:

- Parallel: everyone comes toward the robot on parallel lanes 1 m apart, centred on its path, in
  two staggered rows starting 11 and 12.2 m ahead, and walks on to 5 m behind the start.
- Crossing: everyone crosses the robot's path, the first half (rounded up) from the left, the
  others from the right, at crossing points 1 m apart starting max(5, d + 3.5) m ahead (d the
  crossing distance), so that the two sides never meet on the path. People wait 2-2.3 m to the
  side and set off when the robot's approach means they will cross d metres in front of its front
  bumper, then walk on to 2 m past the path and stand.
- ParallelCrossing: the floor(n/2) people on the outer edges walk oncoming on lanes 3.2 m, 4.0 m,
  ... to either side of the path (left first), outside the crossers' waiting spots; the others
  cross as above.

Each run varies seeded details: start offsets, walking speeds (about 1.2 m/s), start delays of
the oncoming walkers and the timing error of the crossers; `Scenario.variation()` records them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from designs.spec import BLOCK_COLUMN
from trials.errors import StudyError

PARALLEL, PARALLEL_CROSSING, CROSSING = "Parallel", "ParallelCrossing", "Crossing"
DIRECTIONS = (PARALLEL, PARALLEL_CROSSING, CROSSING)

#: The factors the simulator understands, and their values in a study that does not vary them.
PEDESTRIANS, DIRECTION, CROSSING_DISTANCE, CONTROLLER = "Pedestrians", "Direction", "CrossingDistance", "Controller"
DEFAULTS: dict[str, float | str] = {PEDESTRIANS: 4, DIRECTION: CROSSING, CROSSING_DISTANCE: 2.0}
MAX_PEDESTRIANS = 20
MAX_CROSSING_DISTANCE = 10.0

ROBOT_START = (0.0, 0.0, 0.0)
GOAL = (10.0, 0.0)
CONE = (10.0, 0.75)

LANE_SPACING = 1.0
ROW_STARTS = (11.0, 12.2)
ONCOMING_END_X = -5.0
OUTER_LANE_FIRST, OUTER_LANE_SPACING = 3.2, 0.8
CROSS_FIRST, CROSS_BEYOND_D, CROSS_SPACING = 5.0, 3.5, 1.0
CROSS_WAIT_Y, CROSS_END_Y = 2.0, 2.0

SPEED_MEAN, SPEED_STD, SPEED_RANGE = 1.2, 0.1, (0.9, 1.5)


@dataclass(frozen=True)
class Walker:
    """One pedestrian's part: where it starts and goes, how fast, and when it sets off.

    Attributes:
        id: stable id (0-based).
        role: "oncoming" (parallel to the robot's path, toward it) or "crossing".
        start, goal: positions (m).
        speed: preferred walking speed (m/s).
        delay_s: oncoming walkers set off this long after the start.
        cross_x: crossers: where on the robot's path they cross (m along x).
        timing_s: crossers: their error in judging when to set off (s; positive is late).
    """

    id: int
    role: str
    start: tuple[float, float]
    goal: tuple[float, float]
    speed: float
    delay_s: float = 0.0
    cross_x: float | None = None
    timing_s: float = 0.0


@dataclass(frozen=True)
class Settings:
    """The simulated factors of one plan row."""

    pedestrians: int
    direction: str
    crossing_distance: float


@dataclass(frozen=True)
class Scenario:
    """One trial's scene: the robot's start pose and goal, the cone, and the walkers."""

    settings: Settings
    seed: int
    robot_start: tuple[float, float, float]
    goal: tuple[float, float]
    cone: tuple[float, float]
    walkers: tuple[Walker, ...]

    def variation(self) -> list[dict[str, Any]]:
        """The seeded details of every walker, rounded for the record."""
        return [{k: _rounded(v) for k, v in asdict(w).items()} for w in self.walkers]


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 4)
    if isinstance(value, tuple):
        return [_rounded(v) for v in value]
    return value


def settings_from_row(row: dict[str, str], where: str) -> Settings:
    """The simulated factors of a plan row (`Controller` and `order`/`run_code` are left to the runner,
    `Block` to the analysis).

    Raises:
        StudyError: an unknown factor, or a value the simulator cannot run; `where` names the row.
    """
    unknown = [name for name in row if name not in (*DEFAULTS, CONTROLLER, "order", "run_code", BLOCK_COLUMN)]
    if unknown:
        known = ", ".join((*DEFAULTS, CONTROLLER))
        raise StudyError(f"{where}: factor {unknown[0]!r} cannot be simulated (the simulator knows {known})")
    values = {**DEFAULTS, **{k: v for k, v in row.items() if k in DEFAULTS}}
    count = _number(values[PEDESTRIANS], PEDESTRIANS, where)
    if count != int(count) or not 0 <= count <= MAX_PEDESTRIANS:
        raise StudyError(f"{where}: {PEDESTRIANS} {values[PEDESTRIANS]!r} must be a whole number from 0 to {MAX_PEDESTRIANS}")
    direction = str(values[DIRECTION])
    if direction not in DIRECTIONS:
        raise StudyError(f"{where}: {DIRECTION} {direction!r} is not one of {', '.join(DIRECTIONS)}")
    distance = _number(values[CROSSING_DISTANCE], CROSSING_DISTANCE, where)
    if not 0 < distance <= MAX_CROSSING_DISTANCE:
        raise StudyError(f"{where}: {CROSSING_DISTANCE} {values[CROSSING_DISTANCE]!r} must be above 0 "
                         f"and at most {MAX_CROSSING_DISTANCE:g} m")
    return Settings(int(count), direction, distance)


def _number(value: float | str, name: str, where: str) -> float:
    try:
        number = float(value)
    except ValueError:
        raise StudyError(f"{where}: {name} {value!r} is not a number") from None
    if not math.isfinite(number):
        raise StudyError(f"{where}: {name} {value!r} is not a finite number")
    return number


def build_scenario(settings: Settings, seed: int) -> Scenario:
    """Lay out the walkers of `settings`, varying their details with `seed`."""
    rng = np.random.default_rng(seed)
    n = settings.pedestrians
    if settings.direction == PARALLEL:
        oncoming, crossers = [_centre_lane(k, n) for k in range(n)], 0
    elif settings.direction == CROSSING:
        oncoming, crossers = [], n
    else:
        oncoming, crossers = [_outer_lane(k) for k in range(n // 2)], n - n // 2
    walkers = [_oncoming(i, lane, i % 2, rng) for i, lane in enumerate(oncoming)]
    first = max(CROSS_FIRST, settings.crossing_distance + CROSS_BEYOND_D)
    for j in range(crossers):
        side = 1.0 if j < (crossers + 1) // 2 else -1.0
        walkers.append(_crosser(len(walkers), first + CROSS_SPACING * j, side, rng))
    return Scenario(settings, seed, ROBOT_START, GOAL, CONE, tuple(walkers))


def _centre_lane(k: int, n: int) -> float:
    return (k - (n - 1) / 2.0) * LANE_SPACING


def _outer_lane(k: int) -> float:
    side = 1.0 if k % 2 == 0 else -1.0
    return side * (OUTER_LANE_FIRST + OUTER_LANE_SPACING * (k // 2))


def _speed(rng: np.random.Generator) -> float:
    return float(np.clip(rng.normal(SPEED_MEAN, SPEED_STD), *SPEED_RANGE))


def _oncoming(walker_id: int, lane: float, row: int, rng: np.random.Generator) -> Walker:
    x = ROW_STARTS[row] + rng.uniform(-0.3, 0.3)
    y = lane + rng.uniform(-0.15, 0.15)
    return Walker(walker_id, "oncoming", (x, y), (ONCOMING_END_X, y), _speed(rng), delay_s=rng.uniform(0.0, 0.5))


def _crosser(walker_id: int, cross_x: float, side: float, rng: np.random.Generator) -> Walker:
    x = cross_x + rng.uniform(-0.1, 0.1)
    start = (x, side * (CROSS_WAIT_Y + rng.uniform(0.0, 0.3)))
    return Walker(walker_id, "crossing", start, (x, -side * CROSS_END_Y), _speed(rng), cross_x=x,
                  timing_s=rng.uniform(-0.15, 0.15))
