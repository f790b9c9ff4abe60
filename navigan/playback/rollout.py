"""Batched playback roll-outs: every episode of a scene steps at once, one network call per step.

At each 0.4 s step the policy sees each target's own last T_OBS positions (the walked ones once
the observation is used up), the other pedestrians' recorded last T_OBS positions and a goal,
plans T_PRED way-points and walks to the first. The networks were trained with goals T_PRED steps
(4.8 s) ahead, so by default they are handed a sub-goal that far ahead toward the episode's goal
at the recorded person's pace (as the trial controller hands the robot's at its speed); given the
goal itself, 36 steps ahead, they hurry to reach it in 12. A policy with evasion networks walks
the first step they choose (`navigan.evasion`); one with a shield has its first step checked
against everyone's constant-velocity forecast (`navigan.shield`) before it is walked.
An episode stops when it reaches its goal or its cut-off, and leaves the batch. The fluctuation
noise of each episode and step is drawn from the seed and the episode's name alone, so a batch
walks exactly as its episodes one at a time.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from navigan import checkpoint as ckpt
from navigan.data import fill_tracks
from navigan.errors import NaviganError
from navigan.evasion import Evasion
from navigan.generators import GoalSocialGenerator, NaviganGenerator
from navigan.goals import toward
from navigan.playback.episodes import CUTOFF_STEPS, GOAL_RADIUS, Episodes
from navigan.playback.protocols import RECORDED
from navigan.shield import shielded_steps
from robot_logs.physical import STEP_S, T_OBS, T_PRED


def subgoal_speeds(episodes: Episodes, speed: float | str | None) -> np.ndarray | None:
    """(E,) the pace (m/s) of each episode's sub-goals: the recorded person's (RECORDED) or
    `speed` for all; None to hand the goals themselves."""
    if speed is None:
        return None
    if speed == RECORDED:
        return episodes.pace
    return np.full(len(episodes), float(speed))


@dataclass(frozen=True)
class Policy:
    """A generator that walks its way-points (full) or its intention-only path (dagger).

    Attributes:
        generator: the network, in eval mode.
        dagger: walk the intention y_tilde instead of the way-points y_hat.
        noise_size: size of the fluctuation noise z; 0 for models that run without it.
        seed: seeds each episode's noise (with the episode's name).
        checkpoint: where the weights came from.
        shield: the margin (m) its first step must keep from everyone's constant-velocity
            forecast (`navigan.shield.shielded_steps`); None walks the plan as it is.
        evasion: the checkpoint's evasion networks, which choose the walked first step
            (`navigan.evasion`); None walks the plan as it is.
    """

    generator: NaviganGenerator | GoalSocialGenerator
    dagger: bool
    noise_size: int
    seed: int
    checkpoint: Path
    shield: float | None = None
    evasion: Evasion | None = None

    @classmethod
    def load(cls, path: str | Path, dagger: bool = False, seed: int = 0, shield: float | None = None,
             evasion: bool = False) -> Policy:
        """The policy of a checkpoint file.

        Raises:
            NaviganError: the checkpoint cannot be read, or has no evasion networks when asked for them.
        """
        return cls.of(ckpt.load(path), Path(path), dagger, seed, shield, evasion)

    @classmethod
    def of(cls, record: ckpt.Checkpoint, path: Path, dagger: bool = False, seed: int = 0,
           shield: float | None = None, evasion: bool = False) -> Policy:
        """The policy of a loaded checkpoint (read from `path`), walking its evasion networks if `evasion`.

        Raises:
            NaviganError: `evasion` and the checkpoint has none.
        """
        noise = record.model.noise if record.model.variant.fluctuation else 0
        networks = record.build_evasion() if evasion else None
        if evasion and networks is None:
            raise NaviganError(f"{path} has no evasion networks: add them with trials train --evasion")
        return cls(record.build_generator(), dagger, noise, seed, path, shield, networks)

    def noise(self, names: list[str]) -> np.ndarray | None:
        """(E, CUTOFF_STEPS, noise) each episode's noise for each step, or None without noise."""
        if not self.noise_size:
            return None
        return np.stack([
            np.random.default_rng([self.seed, zlib.crc32(name.encode())])
            .standard_normal((CUTOFF_STEPS, self.noise_size), dtype=np.float32)
            for name in names
        ])

    @torch.inference_mode()
    def plan(self, histories: np.ndarray, others: np.ndarray, goals: np.ndarray, noise: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B, T_PRED, 2) way-points, intention and forces for B targets among their (B, N, T_OBS, 2) others."""
        filled, present = fill_tracks(others)
        scene = np.concatenate([histories[:, None], filled], axis=1).astype(np.float32)
        mask = np.concatenate([np.ones((len(histories), 1), dtype=bool), present], axis=1)
        targets = np.zeros_like(mask)
        targets[:, 0] = True
        out = self.generator(
            torch.from_numpy(scene), torch.from_numpy(mask), torch.from_numpy(goals.astype(np.float32)),
            targets=torch.from_numpy(targets), noise=None if noise is None else torch.from_numpy(noise),
        )
        return out.waypoints.numpy(), out.intention.numpy(), out.forces.numpy()


@dataclass(frozen=True)
class Rollout:
    """The walked paths of some episodes.

    Attributes:
        paths: (E, CUTOFF_STEPS + 1, 2) positions from time 0 (the last observed), NaN after the end.
        steps: (E,) steps walked.
        plans: (E, CUTOFF_STEPS, 3, T_PRED, 2) each step's way-points, intention and forces, when recorded.
    """

    paths: np.ndarray
    steps: np.ndarray
    plans: np.ndarray | None = None

    def path(self, e: int) -> np.ndarray:
        """(steps + 1, 2) episode `e`'s walked path."""
        return self.paths[e, : self.steps[e] + 1]


@dataclass(frozen=True)
class Visit:
    """What the policy saw at one step of a roll-out, for the B episodes still walking.

    Attributes:
        histories: (B, T_OBS, 2) each target's last positions, the walked ones once the
            observation is used up.
        around: (B, N, T_OBS, 2) the others present (`neighbours`).
        goals: (B, 2) the (sub-)goals handed to the policy.
        noise: (B, noise) the fluctuation noise, or None.
        planned: (B, 2) the first way-point the policy planned, before any check changes it.
    """

    histories: np.ndarray
    around: np.ndarray
    goals: np.ndarray
    noise: np.ndarray | None
    planned: np.ndarray


def neighbours(episodes: Episodes, active: np.ndarray, step: int) -> np.ndarray:
    """(B, N, T_OBS, 2) the recorded last T_OBS positions of the agents present around each active
    episode's target at `step`, in column order, padded with NaN rows."""
    scene = episodes.scene[active]
    parts: list[tuple[np.ndarray, np.ndarray]] = []
    for s in np.unique(scene):
        rows = np.flatnonzero(scene == s)
        chosen = active[rows]
        positions = episodes.scenes[s].positions
        frames = episodes.start[chosen, None] + step + np.arange(1 - T_OBS, 1)
        present = ~np.isnan(positions[frames[:, -1], :, 0])
        present[np.arange(len(chosen)), episodes.agent[chosen]] = False
        order = np.argsort(~present, axis=1, kind="stable")[:, : present.sum(axis=1).max()]
        window = positions[frames[:, :, None], order[:, None, :]].transpose(0, 2, 1, 3)
        window[~np.take_along_axis(present, order, axis=1)] = np.nan
        parts.append((rows, window))
    width = max(p.shape[1] for _, p in parts)
    out = np.full((len(active), width, T_OBS, 2), np.nan, dtype=np.float32)
    for rows, part in parts:
        out[rows, : part.shape[1]] = part
    return out


def roll_out(
    policy: Policy,
    episodes: Episodes,
    record: bool = False,
    progress: Callable[[int], object] | None = None,
    subgoal_speed: float | str | None = RECORDED,
    visit: Callable[[Visit], object] | None = None,
) -> Rollout:
    """Walk every episode with `policy`, all active episodes in one batch per step.

    Args:
        record: keep each step's plan (for figures; memory grows with the episodes).
        progress: called with 1 after each step.
        subgoal_speed: the pace of the sub-goals handed to the policy (`navigan.goals.toward`):
            RECORDED (each target's own, see `Episodes.pace`) or a speed in m/s; None hands it
            the episode's goal itself, as the paper describes.
        visit: called at each step with what the policy saw, before the step is
            walked (closed-loop training records the states a policy visits: `navigan.closed_loop`).
    """
    speeds = subgoal_speeds(episodes, subgoal_speed)
    count = len(episodes)
    track = np.full((count, T_OBS + CUTOFF_STEPS, 2), np.nan, dtype=np.float32)
    track[:, :T_OBS] = episodes.history()
    noise = policy.noise(episodes.ids)
    plans = np.full((count, CUTOFF_STEPS, 3, T_PRED, 2), np.nan, dtype=np.float32) if record else None
    steps = np.zeros(count, dtype=np.int64)
    active = np.arange(count)
    for step in range(CUTOFF_STEPS):
        if not len(active):
            break
        goals = episodes.goal[active]
        if speeds is not None:
            goals = toward(track[active, step + T_OBS - 1], goals, speeds[active, None] * T_PRED * STEP_S)
        around = neighbours(episodes, active, step)
        histories, drawn = track[active, step : step + T_OBS], None if noise is None else noise[active, step]
        waypoints, intention, forces = policy.plan(histories, around, goals, drawn)
        walked = (intention if policy.dagger else waypoints)[:, 0]
        if visit is not None:
            visit(Visit(histories, around, goals, drawn, walked))
        if policy.evasion is not None:
            walked = policy.evasion.steps(histories, around, walked)
        if policy.shield is not None:
            walked = shielded_steps(track[active, step + T_OBS - 1], walked, around, policy.shield)
        track[active, step + T_OBS] = walked
        if plans is not None:
            plans[active, step] = np.stack([waypoints, intention, forces], axis=1)
        reached = np.linalg.norm(track[active, step + T_OBS] - episodes.goal[active], axis=-1) <= GOAL_RADIUS
        ended = reached | (step + 1 >= episodes.steps[active])
        steps[active[ended]] = step + 1
        active = active[~ended]
        if progress is not None:
            progress(1)
    paths = np.full((count, CUTOFF_STEPS + 1, 2), np.nan, dtype=np.float32)
    for e in range(count):
        paths[e, : steps[e] + 1] = track[e, T_OBS - 1 : T_OBS + steps[e]]
    return Rollout(paths, steps, plans)


def recorded_rollout(episodes: Episodes) -> Rollout:
    """The human row: each target's own recorded path, to its arrival or the cut-off."""
    count = len(episodes)
    paths = np.full((count, CUTOFF_STEPS + 1, 2), np.nan, dtype=np.float32)
    steps = np.zeros(count, dtype=np.int64)
    for e in range(count):
        recorded = episodes.recorded(e)
        near = np.flatnonzero(np.linalg.norm(recorded[1:] - episodes.goal[e], axis=-1) <= GOAL_RADIUS)
        steps[e] = near[0] + 1 if len(near) else episodes.steps[e]
        paths[e, : steps[e] + 1] = recorded[: steps[e] + 1]
    return Rollout(paths, steps)
