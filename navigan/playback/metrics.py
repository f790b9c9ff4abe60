"""Scoring one playback episode: the CrowdNav reward, comfort, arrival and the path measures.

Distances are between pedestrians as points (the recordings give no body sizes). The step's
distance d_k is measured one of two ways (`Scoring.distances`). FRAMES (the paper protocol): the
distance to the nearest other agent at the recorded frame that ends step k. INTERPOLATED (the strict
protocol): over each 0.4 s step the target and every other agent are taken to move in a straight
line, and d_k is the closest approach during it (an agent seen at only one end of the step counts at
that instant); two people whose paths cross between frames count as meeting.

Reward of step k (the paper's eq. 1, CrowdNav's reward), the first case that holds:
    -0.25             if d_k < collision distance (a collision)
    +1                if the target ends the step within GOAL_RADIUS of its goal
    -0.1 + d_k / 2    if d_k < 0.2 m (discomfort)
    0                 otherwise
S (social score) is CrowdNav's discounted return: sum_k gamma^((k - 1) * dt * v_pref) * r_k over
the steps of the episode (k = 1, 2, ...; dt = 0.4 s), i.e. each reward is discounted by the time
elapsed before its step times the preferred speed, as CrowdNav's explorer does.

C (comfort) holds when the target never comes closer than 0.2 m to another agent. The paper's
prose defines the comfort rate the other way round (episodes that do come that close), but its
numbers, which are higher for the better models and high for humans, only fit this reading.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navigan.playback.episodes import GOAL_RADIUS
from navigan.playback.protocols import FRAMES, INTERPOLATED
from robot_logs.physical import STEP_S

#: Closer than this (m) is uncomfortable: C fails and the step's reward is -0.1 + d / 2.
DISCOMFORT_DISTANCE = 0.2


@dataclass(frozen=True)
class Scoring:
    """The reward's settings.

    Attributes:
        gamma: CrowdNav's discount factor, applied per second of travel at the preferred speed.
        v_pref: the preferred speed (m/s) in the discount's exponent.
        collision: two points closer than this (m) have collided.
        distances: where d_k is measured, FRAMES or INTERPOLATED.
    """

    gamma: float = 0.9
    v_pref: float = 1.0
    collision: float = 0.1
    distances: str = INTERPOLATED


@dataclass(frozen=True)
class EpisodeScore:
    """The measures of one episode.

    Attributes:
        steps: steps walked (to arrival, or to the cut-off).
        arrived: reached the goal within GOAL_RADIUS before the cut-off.
        comfortable: never closer than DISCOMFORT_DISTANCE to another agent.
        collided: came closer than the collision distance at some step.
        social_score: S, the discounted return.
        min_distance: the least d_k over the episode (m; inf if alone).
        time_to_goal: seconds to arrival (None if it did not arrive).
        path_length: metres walked.
        path_ratio: path length over the recorded path's length to the same goal (None if it
            did not arrive).
        irregularity: total absolute turning per metre walked (rad/m), starting from the
            direction of the last observed step; steps under 1 cm have no direction and are skipped.
        ade: mean distance to the recorded positions at the same times (m), over the steps the
            target was recorded.
    """

    steps: int
    arrived: bool
    comfortable: bool
    collided: bool
    social_score: float
    min_distance: float
    time_to_goal: float | None
    path_length: float
    path_ratio: float | None
    irregularity: float
    ade: float


def step_distances(path: np.ndarray, others: np.ndarray, distances: str = INTERPOLATED) -> np.ndarray:
    """(n,) each step's distance d_k to the nearest other agent: at the frame that ends the step
    (FRAMES), or the closest approach during the step (INTERPOLATED); inf where nobody is there.

    Args:
        path: (n + 1, 2) the target's positions at the start and after each step.
        others: (n + 1, M, 2) the other agents' positions at the same times, NaN where absent.
        distances: FRAMES or INTERPOLATED.
    """
    if distances == FRAMES:
        at_end = np.linalg.norm(others[1:] - path[1:, None], axis=-1)
        return np.where(np.isnan(at_end), np.inf, at_end).min(axis=1, initial=np.inf)
    a0, a1 = path[:-1, None], path[1:, None]
    b0, b1 = others[:-1], others[1:]
    r0 = b0 - a0
    dr = (b1 - b0) - (a1 - a0)
    speed = np.einsum("kmi,kmi->km", dr, dr)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(np.where(speed > 0, -np.einsum("kmi,kmi->km", r0, dr) / speed, 0.0), 0.0, 1.0)
    moving = np.linalg.norm(r0 + t[..., None] * dr, axis=-1)
    at_end = np.linalg.norm(b1 - a1, axis=-1)
    both = ~np.isnan(moving)
    distance = np.where(both, moving, at_end)
    distance = np.where(np.isnan(distance), np.inf, distance)
    return distance.min(axis=1, initial=np.inf)


def rewards(distances: np.ndarray, arrived_at: int | None, scoring: Scoring) -> np.ndarray:
    """(n,) the reward of each step; `arrived_at` is the 1-based step that reached the goal."""
    r = np.where(distances < DISCOMFORT_DISTANCE, -0.1 + distances / 2, 0.0)
    if arrived_at is not None:
        r[arrived_at - 1] = 1.0
    return np.where(distances < scoring.collision, -0.25, r)


def discounted_return(step_rewards: np.ndarray, scoring: Scoring) -> float:
    """sum_k gamma^((k - 1) * dt * v_pref) * r_k."""
    elapsed = np.arange(len(step_rewards)) * STEP_S
    return float(np.sum(scoring.gamma ** (elapsed * scoring.v_pref) * step_rewards))


def path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=-1).sum())


def irregularity(path: np.ndarray, before: np.ndarray) -> float:
    """Total absolute heading change per metre of `path`, starting from the move `before` (2,)."""
    moves = np.concatenate([before[None], np.diff(path, axis=0)])
    moves = moves[np.linalg.norm(moves, axis=-1) >= 0.01]
    length = path_length(path)
    if len(moves) < 2 or length == 0:
        return 0.0
    heading = np.arctan2(moves[:, 1], moves[:, 0])
    turns = np.angle(np.exp(1j * np.diff(heading)))
    return float(np.abs(turns).sum() / length)


def arrival_step(path: np.ndarray, goal: np.ndarray) -> int | None:
    """The first step (1-based) that ends within GOAL_RADIUS of the goal, or None."""
    near = np.flatnonzero(np.linalg.norm(path[1:] - goal, axis=-1) <= GOAL_RADIUS)
    return int(near[0]) + 1 if len(near) else None


def score_episode(
    path: np.ndarray,
    others: np.ndarray,
    goal: np.ndarray,
    recorded: np.ndarray,
    before: np.ndarray,
    scoring: Scoring,
) -> EpisodeScore:
    """Score a walked path; it ends at the first step that reaches the goal.

    Args:
        path: (n + 1, 2) positions from time 0 (the last observed) to the cut-off or beyond
            the arrival (what follows the arrival is left out).
        others: (n + 1, M, 2) the other agents as recorded, NaN where absent.
        goal: (2,) the goal.
        recorded: (m + 1, 2) the target's own recorded positions from time 0 (m >= the step the
            recording reaches the goal), NaN where absent.
        before: (2,) the target's last observed move (its heading at time 0).
        scoring: the reward's settings.
    """
    path = np.asarray(path, dtype=np.float64)
    others = np.asarray(others, dtype=np.float64)
    recorded = np.asarray(recorded, dtype=np.float64)
    arrived_at = arrival_step(path, goal)
    if arrived_at is not None:
        path, others = path[: arrived_at + 1], others[: arrived_at + 1]
    n = len(path) - 1
    distances = step_distances(path, others, scoring.distances)
    walked = path_length(path)
    ratio = None
    if arrived_at is not None:
        human_at = arrival_step(recorded, goal)
        reference = path_length(recorded[: human_at + 1]) if human_at is not None else np.nan
        ratio = walked / reference if reference > 0 else None
    overlap = min(n, len(recorded) - 1)
    errors = np.linalg.norm(path[1 : overlap + 1] - recorded[1 : overlap + 1], axis=-1)
    errors = errors[~np.isnan(errors)]
    closest = float(distances.min(initial=np.inf))
    return EpisodeScore(
        steps=n,
        arrived=arrived_at is not None,
        comfortable=closest >= DISCOMFORT_DISTANCE,
        collided=closest < scoring.collision,
        social_score=discounted_return(rewards(distances, arrived_at, scoring), scoring),
        min_distance=closest,
        time_to_goal=None if arrived_at is None else arrived_at * STEP_S,
        path_length=walked,
        path_ratio=ratio,
        irregularity=irregularity(path, np.asarray(before, dtype=np.float64)),
        ade=float(errors.mean()) if len(errors) else float("nan"),
    )
