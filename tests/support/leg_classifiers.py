"""Hand-made leg classifiers for tests of the tracking around the detector."""

from __future__ import annotations

import math

import numpy as np

from robot_logs.leg_classifier import LegClassifier


def constant(probability: float) -> LegClassifier:
    """A classifier of one leaf that gives every segment the same leg probability (simulated legs'
    shapes are not what a detector trained on real ones knows, so tests of the tracking fix it)."""
    zero = np.zeros(1, dtype=np.int32)
    return LegClassifier(zero, np.zeros(1), zero, zero, np.zeros(1, dtype=bool), np.zeros(1), zero, depth=0,
                         bias=math.log(probability / (1 - probability)), threshold=0.5, confirm=0.5, protect=0.7)
