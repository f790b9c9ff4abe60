"""How comfortable and punctual a plain reactive walker is in the playback episodes (a yardstick for Table I).

Each step the walker predicts every other agent at constant velocity (its last recorded move) and
picks, among headings within 90 degrees of its goal's direction (10 degree steps) and speeds 0 to
1.5 m/s, the move that ends closest to the goal plus PENALTY times how far the predicted closest
approach over the next --horizon steps falls short of --margin. It is scored with the playback
metrics, so its C and A sit beside Table I's: what a non-learned avoider reaches among the same
recordings that never give way.

    python scripts/reactive_reference.py [--split univ] [--margin 0.5]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from navigan.data import SHIPPED_DATA, SPLITS, load_split
from navigan.playback.episodes import CUTOFF_STEPS, GOAL_RADIUS, Episodes, load_episodes
from navigan.playback.evaluate import score_rollout
from navigan.playback.metrics import Scoring
from navigan.playback.protocols import DEFAULT_PROTOCOL, PROTOCOLS
from navigan.playback.rollout import Rollout
from navigan.shield import clearance, forecast
from robot_logs.physical import STEP_S

HEADINGS = np.deg2rad(np.arange(-90, 91, 10))
SPEEDS = np.array([0.0, 0.4, 0.8, 1.2, 1.5])
PENALTY = 10.0


def walk(episodes: Episodes, e: int, position: np.ndarray, margin: float, horizon: int) -> np.ndarray:
    """(n + 1, 2) the reactive walker's path in episode `e` from `position`, to its goal or the cut-off."""
    start, goal = episodes.start[e], episodes.goal[e].astype(float)
    others = np.delete(episodes.scenes[episodes.scene[e]].positions, episodes.agent[e], axis=1).astype(float)
    position = position.astype(float)
    path = [position]
    for k in range(episodes.steps[e]):
        ahead = forecast(others[start + k - 1 : start + k + 1].transpose(1, 0, 2)[None], horizon)
        towards = np.arctan2(*(goal - position)[::-1]) + HEADINGS
        moves = SPEEDS[:, None, None] * np.stack([np.cos(towards), np.sin(towards)], axis=-1)[None]
        candidates = moves.reshape(-1, 2) * STEP_S
        closest = clearance(position[None], candidates[None], ahead)[0]
        after = position + candidates
        cost = np.linalg.norm(goal - after, axis=-1) + PENALTY * np.clip(margin - closest, 0, None)
        position = after[np.argmin(cost)]
        path.append(position)
        if np.linalg.norm(position - goal) <= GOAL_RADIUS:
            break
    return np.array(path)


def walk_all(episodes: Episodes, margin: float, horizon: int) -> Rollout:
    """Every episode walked by the reactive walker, as a playback roll-out."""
    history = episodes.history()
    paths = np.full((len(episodes), CUTOFF_STEPS + 1, 2), np.nan)
    steps = np.zeros(len(episodes), dtype=np.int64)
    for e in range(len(episodes)):
        path = walk(episodes, e, history[e, -1], margin, horizon)
        paths[e, : len(path)], steps[e] = path, len(path) - 1
    return Rollout(paths, steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=SHIPPED_DATA, help="the ETH/UCY folder (default: the shipped copy)")
    parser.add_argument("--split", default="all", help="a split or all five (default)")
    parser.add_argument("--margin", type=float, default=0.5, help="predicted distance kept from others (m)")
    parser.add_argument("--protocol", choices=PROTOCOLS, default=DEFAULT_PROTOCOL,
                        help=f"targets and where distances are measured, as trials playback --protocol (default {DEFAULT_PROTOCOL})")
    parser.add_argument("--horizon", type=int, default=3, help="steps of 0.4 s the prediction looks ahead")
    args = parser.parse_args()
    splits = [s for s in SPLITS if s != "all"] if args.split == "all" else [args.split]
    pooled: list[tuple[bool, bool, float]] = []
    for split in splits:
        episodes = load_episodes(load_split(args.data, split).test, args.protocol)
        scoring = Scoring(distances=PROTOCOLS[args.protocol].distances)
        records = score_rollout(episodes, walk_all(episodes, args.margin, args.horizon), scoring)
        scores = [(r["comfortable"], r["arrived"], r["social_score"]) for r in records]
        table = np.array(scores, dtype=float)
        print(f"{split}: {len(table)} episodes  S {table[:, 2].mean():.3f}  C {table[:, 0].mean():.3f}  "
              f"A {table[:, 1].mean():.3f}")
        pooled += scores
    table = np.array(pooled, dtype=float)
    print(f"pooled: {len(table)} episodes  S {table[:, 2].mean():.3f}  C {table[:, 0].mean():.3f}  "
          f"A {table[:, 1].mean():.3f}  (margin {args.margin} m, {args.horizon} steps ahead)")


if __name__ == "__main__":
    main()
