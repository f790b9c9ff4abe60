"""Sub-goals: how a goal farther than the networks' horizon is passed to them."""

from __future__ import annotations

import numpy as np


def toward(position: np.ndarray, goal: np.ndarray, reach: float | np.ndarray) -> np.ndarray:
    """(..., 2) the points `reach` metres ((..., 1) or one for all) from `position` toward `goal`,
    beyond it when it is nearer.

    The networks were trained with goals one horizon (T_PRED steps, 4.8 s) ahead, so a farther goal
    is passed as such a sub-goal, at a walking pace (`reach` = speed * 4.8 s). Kept at that
    distance even past the goal, it leads the walker through its goal rather than slowing it to
    creep toward a point it plans to reach 4.8 s later.
    """
    offset = goal - position
    distance = np.linalg.norm(offset, axis=-1, keepdims=True)
    return position + offset * (reach / np.maximum(distance, 1e-9))
