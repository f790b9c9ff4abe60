"""Planning with a trained generator in world coordinates: the API the trial controller calls.

    planner = Planner()                      # the shipped all-scenes NaviGAN-R
    out = planner.plan(history, others, goal, seed=3)
    out.waypoints                            # (12, 2), one every 0.4 s

`plan_batch` does the same for B targets at once (each with its own other agents), for
rolling out many episodes in one call per step.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from navigan import checkpoint as ckpt
from navigan.data import fill_tracks
from navigan.errors import NaviganError
from robot_logs.physical import STEP_S, T_OBS


@dataclass(frozen=True)
class PlanOutput:
    """A plan in world coordinates (leading batch axis B for `plan_batch`).

    Attributes:
        waypoints: (..., T_PRED, 2) y_hat, the positions to reach, one every `step` seconds.
        intention: (..., T_PRED, 2) y_tilde, the intention-only (dagger) path.
        forces: (..., T_PRED, 2) the social forces f, waypoints - intention (zero for
            Goal-Social-LSTM, which has no force decomposition).
        step: seconds between way-points.
    """

    waypoints: np.ndarray
    intention: np.ndarray
    forces: np.ndarray
    step: float = STEP_S


class Planner:
    """A NaviGAN-family generator loaded from a checkpoint, planning in world coordinates."""

    def __init__(self, checkpoint: str | Path | None = None, device: str = "cpu", seed: int = 0) -> None:
        """Load `checkpoint` (a path or shipped name; default: the shipped all-scenes NaviGAN-R).

        `seed` seeds the fluctuation noise drawn by calls that pass no seed of their own.

        Raises:
            NaviganError: the checkpoint cannot be read.
        """
        path = ckpt.shipped() if checkpoint is None else ckpt.resolve(checkpoint)
        self.checkpoint = ckpt.load(path)
        self.path = path
        self.device = torch.device(device)
        self.generator = self.checkpoint.build_generator().to(self.device)
        self.model = self.checkpoint.model.model
        self.noise = torch.Generator(device=self.device)
        self.reset(seed)

    def reset(self, seed: int) -> None:
        """Reseed the fluctuation noise (start of a run)."""
        self.noise.manual_seed(seed)

    def plan(self, history: np.ndarray, others: np.ndarray, goal: np.ndarray, seed: int | None = None) -> PlanOutput:
        """Plan one target.

        Args:
            history: (T_OBS=8, 2) the target's own last positions, oldest first, 0.4 s apart.
            others: (N, 8, 2) the other agents' last positions (N may be 0); NaN where an
                agent was not yet seen; a row whose newest position is NaN is ignored.
            goal: (2,) where the target should be at the end of the plan (T_PRED * 0.4 = 4.8 s
                ahead); every model is trained with goals that far, so pass a sub-goal on the way to
                a farther one.
            seed: seed of this call's fluctuation noise (default: the planner's running RNG).

        Returns:
            (12, 2) way-points, intention path and social forces in world coordinates.
        """
        others = np.asarray(others, dtype=np.float32).reshape(-1, T_OBS, 2)
        out = self.plan_batch(np.asarray(history)[None], others[None], np.asarray(goal)[None], seed=seed)
        return PlanOutput(out.waypoints[0], out.intention[0], out.forces[0])

    @torch.inference_mode()
    def plan_batch(
        self, histories: np.ndarray, others: np.ndarray, goals: np.ndarray, seed: int | None = None
    ) -> PlanOutput:
        """Plan B targets at once, each among its own other agents.

        Args:
            histories: (B, 8, 2) each target's last positions.
            others: (B, N, 8, 2) each target's other agents, padded with NaN rows.
            goals: (B, 2).
            seed: as for `plan`.

        Returns:
            (B, 12, 2) way-points, intention paths and social forces.

        Raises:
            NaviganError: wrong shapes, or a NaN in a target's history or goal.
        """
        histories = np.asarray(histories, dtype=np.float32)
        others = np.asarray(others, dtype=np.float32)
        goals = np.asarray(goals, dtype=np.float32)
        batch = histories.shape[0] if histories.ndim == 3 else -1
        if histories.shape != (batch, T_OBS, 2):
            raise NaviganError(f"histories: expected shape (B, {T_OBS}, 2), got {histories.shape}")
        if others.ndim != 4 or others.shape[0] != batch or others.shape[2:] != (T_OBS, 2):
            raise NaviganError(f"others: expected shape ({batch}, N, {T_OBS}, 2), got {others.shape}")
        if goals.shape != (batch, 2):
            raise NaviganError(f"goals: expected shape ({batch}, 2), got {goals.shape}")
        if np.isnan(histories).any() or np.isnan(goals).any():
            raise NaviganError("a target's history or goal holds NaN; the target's own track must be complete")
        filled, present = fill_tracks(others)
        scene = np.concatenate([histories[:, None], filled], axis=1)
        mask = np.concatenate([np.ones((batch, 1), dtype=bool), present], axis=1)
        targets = np.zeros_like(mask)
        targets[:, 0] = True
        noise = None
        if self.checkpoint.model.variant.fluctuation:
            rng = self.noise if seed is None else torch.Generator(device=self.device).manual_seed(seed)
            noise = torch.randn(batch, self.checkpoint.model.noise, generator=rng, device=self.device)
        prediction = self.generator(
            torch.from_numpy(scene).to(self.device),
            torch.from_numpy(mask).to(self.device),
            torch.from_numpy(goals).to(self.device),
            targets=torch.from_numpy(targets).to(self.device),
            noise=noise,
        )
        return PlanOutput(
            waypoints=prediction.waypoints.cpu().numpy(),
            intention=prediction.intention.cpu().numpy(),
            forces=prediction.forces.cpu().numpy(),
        )


