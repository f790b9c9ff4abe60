"""Playback episodes: one per pedestrian of a test scene who stays long enough to set a goal.

Two target rules (`navigan.playback.protocols`) choose the targets. Under PRESENT (the paper protocol's)
a pedestrian present for T_OBS + GOAL_STEPS consecutive frames is a target from its first such stretch:
observed for T_OBS steps, its goal its own recorded position GOAL_STEPS = 3 * T_PRED steps (14.4 s)
later. Under OBSERVED (the strict protocol's), T_OBS + T_PRED consecutive frames suffice, and a target
that leaves before GOAL_STEPS gets its last recorded position of that stretch as goal. Either way the
episode is cut CUTOFF_STEPS = 5 * T_PRED steps (24 s) after the last observed step, or at the end of the
recording if sooner. A pedestrian whose goal lies within the goal radius of where it starts
(someone standing) has nothing to navigate and makes no episode; the count is kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navigan.data import Recording, read_recording
from navigan.errors import NaviganError
from navigan.playback.protocols import OBSERVED, PRESENT, target_rule
from robot_logs.physical import STEP_S, T_OBS, T_PRED

GOAL_STEPS = 3 * T_PRED
CUTOFF_STEPS = 5 * T_PRED
#: An episode ends with success once the target is this close to its goal (m).
GOAL_RADIUS = 0.5
#: Consecutive frames a target must be present under each target rule.
NEEDED_FRAMES = {PRESENT: T_OBS + GOAL_STEPS, OBSERVED: T_OBS + T_PRED}


@dataclass(frozen=True)
class SceneGrid:
    """A recording as a frame-by-pedestrian grid.

    Attributes:
        name: the file's name.
        ids: (P,) pedestrian ids, one per column.
        positions: (F, P, 2) positions (m) at consecutive frames 0.4 s apart, NaN where absent.
    """

    name: str
    ids: np.ndarray
    positions: np.ndarray


def scene_grid(recording: Recording) -> SceneGrid:
    """Lay a recording out on its frame grid (frame step: the smallest gap between frames).

    Raises:
        NaviganError: a frame lies off the frame step.
    """
    frames = np.unique(recording.frames)
    step = int(np.diff(frames).min()) if len(frames) > 1 else 1
    offset = recording.frames - frames[0]
    if np.any(offset % step):
        bad = int(np.argmax(offset % step != 0))
        raise NaviganError(f"{recording.path.name}: frame {recording.frames[bad]} is off the frame step {step}")
    ids, column = np.unique(recording.pedestrians, return_inverse=True)
    positions = np.full((int(offset.max() // step) + 1, len(ids), 2), np.nan, dtype=np.float32)
    positions[offset // step, column] = recording.xy
    return SceneGrid(recording.path.name, ids, positions)


@dataclass(frozen=True)
class Episodes:
    """Playback episodes over some scenes, as parallel arrays (E episodes).

    Attributes:
        scenes: the scenes the episodes are cut from.
        scene: (E,) index into `scenes`.
        agent: (E,) the target's column in its scene.
        start: (E,) frame of the target's last observed position (time 0 of the episode).
        steps: (E,) steps before the cut-off.
        goal: (E, 2) the goal (m).
        goal_steps: (E,) steps from time 0 to when the recorded target was at its goal
            (GOAL_STEPS, or fewer under OBSERVED for a target that left sooner).
        standing: pedestrians left out because their goal was within GOAL_RADIUS of the start.
    """

    scenes: tuple[SceneGrid, ...]
    scene: np.ndarray
    agent: np.ndarray
    start: np.ndarray
    steps: np.ndarray
    goal: np.ndarray
    goal_steps: np.ndarray
    standing: int = 0

    def __len__(self) -> int:
        return len(self.scene)

    @property
    def ids(self) -> list[str]:
        """A stable name per episode: `file:pedestrian`."""
        return [f"{self.scenes[s].name}:{self.scenes[s].ids[a]:g}" for s, a in zip(self.scene, self.agent)]

    @property
    def pace(self) -> np.ndarray:
        """(E,) each target's straight-line speed (m/s) from its start to its goal in its goal_steps:
        the pace that arrives when the recorded person was there."""
        return np.linalg.norm(self.goal - self.history()[:, -1], axis=-1) / (self.goal_steps * STEP_S)

    def history(self) -> np.ndarray:
        """(E, T_OBS, 2) each target's observed positions, oldest first."""
        return np.stack([self.scenes[s].positions[t - T_OBS + 1 : t + 1, a]
                         for s, a, t in zip(self.scene, self.agent, self.start)])

    def recorded(self, e: int) -> np.ndarray:
        """(steps + 1, 2) the target's recorded positions from time 0 to the cut-off, NaN where absent."""
        t = self.start[e]
        return self.scenes[self.scene[e]].positions[t : t + self.steps[e] + 1, self.agent[e]]

    def others(self, e: int) -> np.ndarray:
        """(steps + 1, P - 1, 2) the other pedestrians' recorded positions over the episode."""
        t, positions = self.start[e], self.scenes[self.scene[e]].positions
        return np.delete(positions[t : t + self.steps[e] + 1], self.agent[e], axis=1)

    def subset(self, index: Sequence[int] | np.ndarray) -> Episodes:
        """The same scenes with only some episodes."""
        index = np.asarray(index, dtype=np.int64)
        return Episodes(self.scenes, self.scene[index], self.agent[index], self.start[index],
                        self.steps[index], self.goal[index], self.goal_steps[index], self.standing)


def episodes_of(scenes: Sequence[SceneGrid], protocol: str) -> Episodes:
    """Every episode of some scenes under a protocol (`protocols.PROTOCOLS`) or a target rule, in scene
    then pedestrian order."""
    need = NEEDED_FRAMES[target_rule(protocol)]
    rows: list[tuple[int, int, int, int, int]] = []
    goals: list[np.ndarray] = []
    standing = 0
    for s, grid in enumerate(scenes):
        present = ~np.isnan(grid.positions[..., 0])
        if present.shape[0] < need:
            continue
        long_enough = np.lib.stride_tricks.sliding_window_view(present, need, axis=0).all(axis=-1)
        for agent in np.flatnonzero(long_enough.any(axis=0)):
            start = int(np.argmax(long_enough[:, agent])) + T_OBS - 1
            ahead = present[start : start + GOAL_STEPS + 1, agent]
            # GOAL_STEPS ahead, or (OBSERVED only) the last frame before the target leaves or the recording ends
            goal_steps = len(ahead) - 1 if ahead.all() else int(np.argmin(ahead)) - 1
            goal = grid.positions[start + goal_steps, agent]
            if np.linalg.norm(goal - grid.positions[start, agent]) <= GOAL_RADIUS:
                standing += 1
                continue
            steps = min(CUTOFF_STEPS, grid.positions.shape[0] - 1 - start)
            rows.append((s, int(agent), start, steps, goal_steps))
            goals.append(goal)
    table = np.asarray(rows, dtype=np.int64).reshape(-1, 5)
    return Episodes(
        scenes=tuple(scenes), scene=table[:, 0], agent=table[:, 1], start=table[:, 2], steps=table[:, 3],
        goal=np.asarray(goals, dtype=np.float32).reshape(-1, 2), goal_steps=table[:, 4], standing=standing,
    )


def load_episodes(files: Sequence[str | Path], protocol: str) -> Episodes:
    """The episodes of a split's test recordings under a protocol (`protocols.PROTOCOLS`) or a target rule.

    Raises:
        NaviganError: a file cannot be read, or no pedestrian stays long enough.
    """
    episodes = episodes_of([scene_grid(read_recording(f)) for f in files], protocol)
    if not len(episodes):
        names = ", ".join(Path(f).name for f in files)
        raise NaviganError(f"no playback episodes in {names}: no pedestrian is present for "
                           f"{NEEDED_FRAMES[target_rule(protocol)]} consecutive frames")
    return episodes
