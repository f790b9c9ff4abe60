"""A constant-velocity check of a plan's first step: the nearest move that keeps its distance.

Everyone else is forecast to keep their last move for `horizon` steps (HORIZON by default). If the
planned first step, held for those steps, would bring the walker closer than `margin` to someone,
it is replaced by the move (a ring of headings and speeds) that costs least: its distance from the
planned step plus PENALTY times the shortfall of its closest forecast approach. A step that keeps
the margin costs nothing and is kept, so the check only bends the plan where the forecast says it
must.
"""

from __future__ import annotations

import numpy as np

from robot_logs.physical import STEP_S

#: Headings (rad) and speeds (m/s) of the alternative moves.
HEADINGS = np.deg2rad(np.arange(0, 360, 15))
SPEEDS = np.array([0.0, 0.3, 0.6, 0.9, 1.2, 1.5])
#: Cost per metre of shortfall, against one per metre of change to the planned step.
PENALTY = 10.0
#: Steps (0.4 s each) of the forecast: 1.6 s, the part of a plan the playback NaviGAN-R's
#: resistance loss scores and its pooling looks ahead.
HORIZON = 4

MOVES = (SPEEDS[:, None, None] * np.stack([np.cos(HEADINGS), np.sin(HEADINGS)], axis=-1)[None]).reshape(-1, 2)


def forecast(others: np.ndarray, horizon: int) -> np.ndarray:
    """(B, N, horizon, 2) the others' positions 1..horizon steps ahead if each keeps its last move.

    Args:
        others: (B, N, T, 2) the others' recent positions, oldest first, NaN where unknown; one
            seen only now is held still, one absent now stays NaN.
    """
    last, before = others[:, :, -1], others[:, :, -2]
    move = np.where(np.isnan(before), 0.0, last - before)
    return last[:, :, None] + move[:, :, None] * np.arange(1, horizon + 1)[:, None]


def clearance(positions: np.ndarray, steps: np.ndarray, ahead: np.ndarray) -> np.ndarray:
    """(B, M) the closest forecast approach of each of M candidate steps held for the horizon.

    Args:
        positions: (B, 2) where the walkers are.
        steps: (B, M, 2) candidate steps (m per STEP_S).
        ahead: (B, N, H, 2) the others' forecast positions (`forecast`).
    """
    horizon = ahead.shape[2]
    walked = positions[:, None, None] + steps[:, :, None] * np.arange(1, horizon + 1)[:, None]
    gap = np.linalg.norm(walked[:, :, None] - ahead[:, None], axis=-1)
    return np.where(np.isnan(gap), np.inf, gap).min(axis=(2, 3), initial=np.inf)


def shielded_steps(
    positions: np.ndarray, planned: np.ndarray, others: np.ndarray, margin: float, horizon: int = HORIZON
) -> np.ndarray:
    """(B, 2) each walker's step: the planned one if it keeps `margin` from everyone's forecast
    over `horizon` steps, else the cheapest move (see the module's docstring).

    Args:
        positions: (B, 2) where the walkers are.
        planned: (B, 2) the planned next positions.
        others: (B, N, T, 2) the others' recent positions (T >= 2), NaN where unknown.
    """
    step = planned - positions
    ahead = forecast(others, horizon)
    short = clearance(positions, step[:, None], ahead)[:, 0] < margin
    if short.any():  # only the walkers whose planned step falls short weigh the alternatives
        moves = np.broadcast_to(MOVES * STEP_S, (int(short.sum()),) + MOVES.shape)
        candidates = np.concatenate([step[short, None], moves], axis=1)
        gap = clearance(positions[short], candidates, ahead[short])
        cost = np.linalg.norm(candidates - step[short, None], axis=-1) + PENALTY * np.clip(margin - gap, 0.0, None)
        step[short] = candidates[np.arange(len(candidates)), cost.argmin(axis=1)]
    return positions + step
