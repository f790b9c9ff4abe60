"""Visited states: rows from where the planner's own walk through the training scenes took it.

Training windows are recorded, so the planner learns open loop, always standing where a person
stood. In playback and on the robot it walks its own plans and meets the crowd from places no one
recorded, often nearer to someone than any recorded person came. Each epoch the generator being
trained walks the training scenes' playback episodes (as `trials playback` walks the test
scenes) and its states become rows: every state from which its walk came within d_safe of a
recorded person over the next steps, and as many of the other states. The rows carry the
recorded people's futures (they do not react, as in playback) and the episode's goal, and are
scored as encounter rows are (`losses.force_losses`), so they train the social force to make the
room its own walk lacked, and to stay small where none was needed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from navigan.data import T_OBS, T_PRED, SceneBatch, fill_tracks, turn_windows
from navigan.generators import GoalSocialGenerator, NaviganGenerator
from navigan.playback.episodes import Episodes, load_episodes
from navigan.playback.rollout import Policy, neighbours, roll_out

#: Frames between the starts of one pedestrian's training episodes.
START_EVERY = 12


def visit_episodes(files: Sequence[str | Path]) -> Episodes:
    """Playback episodes of training recordings, one every START_EVERY frames a pedestrian stays long enough.

    Raises:
        NaviganError: a file cannot be read, or no pedestrian stays long enough.
    """
    return load_episodes(files, every=START_EVERY)


def walked_tracks(generator: NaviganGenerator | GoalSocialGenerator, episodes: Episodes, seed: int) -> np.ndarray:
    """(E, T_OBS - 1 + CUTOFF_STEPS + 1, 2) each episode's observed history then its walk with
    `generator` (NaN after the walk ends), noise drawn as the playback draws it from `seed`."""
    noise = generator.config.noise if generator.config.recipe.fluctuation else 0
    was_training = generator.training
    generator.eval()
    try:
        rollout = roll_out(Policy(generator, False, noise, seed, Path("(training)")), episodes)
    finally:
        generator.train(was_training)
    return np.concatenate([episodes.history()[:, :-1], rollout.paths], axis=1)


def risky(track: np.ndarray, around: np.ndarray, d_safe: float, steps: int) -> np.ndarray:
    """(B,) whether each walk came within `d_safe` of another agent in its next `steps` steps.

    Args:
        track: (B, steps, 2) the walked positions after the state.
        around: (B, N, steps, 2) the others' recorded positions at the same steps (NaN unknown).
    """
    gap = np.linalg.norm(around - track[:, None], axis=-1)
    return np.where(np.isnan(gap), np.inf, gap).min(axis=(1, 2), initial=np.inf) < d_safe


def visited_rows(
    generator: NaviganGenerator | GoalSocialGenerator,
    episodes: Episodes,
    seed: int,
    d_safe: float,
    steps: int,
    rng: np.random.Generator,
    augment: bool = False,
) -> SceneBatch | None:
    """The risky states of `generator`'s walks through `episodes` and as many others drawn by
    `rng`, one row each (the walker is row 0, its goal the episode's); None if no walk was risky.

    `steps` way-points after a state decide whether it was risky (see `risky`); with `augment`
    each row is turned by a random angle and mirrored at random, as training windows are.
    """
    tracks = walked_tracks(generator, episodes, seed)
    walked = (~np.isnan(tracks[:, T_OBS:, 0])).sum(axis=1)
    chosen: list[np.ndarray] = []
    calm: list[np.ndarray] = []
    for step in range(int(walked.max(initial=0))):
        active = np.flatnonzero(walked > step)
        ahead = tracks[active, step + T_OBS : step + T_OBS + steps]
        around = neighbours(episodes, active, step, ahead=steps)[:, :, T_OBS:]
        flags = risky(ahead, around[:, :, : ahead.shape[1]], d_safe, steps)
        chosen.append(np.stack([active[flags], np.full(flags.sum(), step)], axis=1))
        calm.append(np.stack([active[~flags], np.full((~flags).sum(), step)], axis=1))
    states, quiet = np.concatenate(chosen), np.concatenate(calm)
    if not len(states):
        return None
    states = np.concatenate([states, quiet[rng.choice(len(quiet), size=min(len(states), len(quiet)), replace=False)]])
    return _rows(tracks, episodes, states, rng if augment else None)


def _rows(tracks: np.ndarray, episodes: Episodes, states: np.ndarray, rng: np.random.Generator | None) -> SceneBatch:
    """A SceneBatch of (episode, step) states: the walker's last T_OBS positions in row 0, the
    agents present around it then with their next T_PRED recorded positions, the episode's goal."""
    parts = []
    for step in np.unique(states[:, 1]):
        index = states[states[:, 1] == step, 0]
        around = neighbours(episodes, index, int(step), ahead=T_PRED)
        own = np.full((len(index), 1, T_OBS + T_PRED, 2), np.nan, dtype=np.float32)
        own[:, 0, :T_OBS] = tracks[index, step : step + T_OBS]
        goals = np.broadcast_to(episodes.goal[index, None, None], (len(index), 1, 1, 2))
        parts.append((own, around, goals))
    width = 1 + max(around.shape[1] for _, around, _ in parts)
    positions = np.full((len(states), width, T_OBS + T_PRED + 1, 2), np.nan, dtype=np.float32)
    row = 0
    for own, around, goals in parts:
        rows = slice(row, row + len(own))
        positions[rows, :1, : T_OBS + T_PRED] = own
        positions[rows, 1 : 1 + around.shape[1], : T_OBS + T_PRED] = around
        positions[rows, :, -1] = goals[:, 0]
        row += len(own)
    if rng is not None:
        positions = turn_windows(positions, rng)
    obs, present = fill_tracks(positions[:, :, :T_OBS])
    future = positions[:, :, T_OBS : T_OBS + T_PRED]
    seen = ~np.isnan(future[..., 0]) & present[:, :, None]
    targets = np.zeros_like(present)
    targets[:, 0] = True
    return SceneBatch(
        obs=torch.from_numpy(obs),
        future=torch.from_numpy(np.where(seen[..., None], future, 0.0).astype(np.float32)),
        seen=torch.from_numpy(seen),
        mask=torch.from_numpy(present),
        targets=torch.from_numpy(targets),
        goals=torch.from_numpy(np.ascontiguousarray(positions[:, 0, -1])),
    )


def pick(rows: SceneBatch, index: np.ndarray) -> SceneBatch:
    """Some rows of a one-target-per-row batch, trimmed to the widest of them."""
    mask = rows.mask[index]
    width = int(mask.sum(dim=1).max())
    return SceneBatch(
        obs=rows.obs[index, :width], future=rows.future[index, :width], seen=rows.seen[index, :width],
        mask=mask[:, :width], targets=rows.targets[index, :width], goals=rows.goals[index],
    )
