"""The learned leg classifier as plain arrays: its file format, loading and prediction.

A gradient-boosted ensemble of decision trees, trained with scikit-learn's
HistGradientBoostingClassifier (`robot_logs.leg_training`) and stored as the trees' arrays in an
.npz file with a format version and the training record, never as a pickle, so a detector file
is safe to open and easy to version. Prediction walks each segment down every tree in a compiled
loop (`robot_logs.tree_walk`).
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from robot_logs.errors import LogError

#: The detector file format this code reads and writes; bump it when the arrays or the features
#: change (4: `foreground` takes a beam without a return for open space and reads at most
#: `segment_features.STANDS_FREE`).
FORMAT_VERSION = 4

#: The detector shipped with the package, trained on tests/data/robot_logs (its record says how).
SHIPPED_DETECTOR = "leg_detector.npz"

_ARRAYS = ("feature", "split", "left", "right", "missing_left", "value", "roots")


@dataclass(frozen=True, eq=False)
class LegClassifier:
    """Trees as flat node arrays; a leaf points to itself on both sides and has feature 0.

    Attributes:
        feature, split: the feature index and the split value of each node (go left if <=).
        left, right: child node indices.
        missing_left: True where a node sends a NaN feature left.
        value: each leaf's contribution to the log-odds (learning rate included).
        roots: (T,) the root node of each tree.
        depth: the deepest tree's depth (levels to walk).
        bias: the log-odds before any tree.
        threshold: the probability at or above which a segment is a leg.
        confirm: the mean leg probability that confirms a tentative track (`robot_logs.pipeline`).
        protect: the mean leg probability of a track sure enough to keep out of the static grid.
        record: how it was trained (data, parameters, cross-validated figures, seed).
    """

    feature: np.ndarray
    split: np.ndarray
    left: np.ndarray
    right: np.ndarray
    missing_left: np.ndarray
    value: np.ndarray
    roots: np.ndarray
    depth: int
    bias: float
    threshold: float
    confirm: float
    protect: float
    record: dict[str, Any] = field(default_factory=dict)

    def probability(self, features: np.ndarray) -> np.ndarray:
        """(K,) leg probability of each row of (K, F) segment features."""
        from robot_logs.tree_walk import log_odds  # numba loads only once legs are classified

        features = np.ascontiguousarray(features, dtype=np.float64)
        total = log_odds(features, self.feature, self.split, self.left, self.right, self.missing_left, self.value,
                         self.roots, self.depth, self.bias)
        return 1.0 / (1.0 + np.exp(-total))

    def save(self, path: str | Path) -> None:
        """Write the .npz file (complete or not at all)."""
        path = Path(path)
        partial = path.with_name(f".{path.name}.partial")
        header = {"format": FORMAT_VERSION, "depth": self.depth, "bias": self.bias, "threshold": self.threshold,
                  "confirm": self.confirm, "protect": self.protect}
        with partial.open("wb") as stream:
            np.savez_compressed(
                stream,
                header=np.array(json.dumps(header)),
                record=np.array(json.dumps(self.record, sort_keys=True)),
                **{name: getattr(self, name) for name in _ARRAYS},
            )
        os.replace(partial, path)

    @classmethod
    def load(cls, path: str | Path) -> LegClassifier:
        """Read a detector file written by `save` (pickles are refused).

        Raises:
            LogError: not a detector file, or one of another format version.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as stored:
                header = json.loads(str(stored["header"]))
                if header.get("format") != FORMAT_VERSION:
                    raise LogError(
                        f"{path}: detector format {header.get('format')}, but this version reads format "
                        f"{FORMAT_VERSION}; retrain it with `trials log train-detector`"
                    )
                arrays = {name: stored[name] for name in _ARRAYS}
                record = json.loads(str(stored["record"]))
        except LogError:
            raise
        except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
            raise LogError(f"{path}: not a leg detector file ({type(exc).__name__}: {exc})") from None
        return cls(
            **arrays,
            depth=int(header["depth"]),
            bias=float(header["bias"]),
            threshold=float(header["threshold"]),
            confirm=float(header["confirm"]),
            protect=float(header["protect"]),
            record=record,
        )


def from_hist_gradient_boosting(model: Any, levels: tuple[float, float, float], record: dict[str, Any]) -> LegClassifier:
    """The arrays of a fitted binary `sklearn.ensemble.HistGradientBoostingClassifier` (numeric
    features only), with `levels` its (threshold, confirm, protect) probabilities.

    Its log-odds are the baseline's plus each tree's leaf value (the learning rate is already in
    the leaves). scikit-learn keeps the trees in `_predictors`; the tests compare the arrays'
    predictions with the model's, so a change there fails loudly.
    """
    trees = [predictors[0].nodes for predictors in model._predictors]
    offsets = np.cumsum([0] + [len(nodes) for nodes in trees])
    feature, split, left, right, missing_left, value = [], [], [], [], [], []
    for offset, nodes in zip(offsets, trees):
        leaf = nodes["is_leaf"].astype(bool)
        own = np.arange(len(nodes)) + offset
        feature.append(np.where(leaf, 0, nodes["feature_idx"]))
        split.append(np.where(leaf, 0.0, nodes["num_threshold"]))
        left.append(np.where(leaf, own, nodes["left"].astype(np.int64) + offset))
        right.append(np.where(leaf, own, nodes["right"].astype(np.int64) + offset))
        missing_left.append(nodes["missing_go_to_left"].astype(bool))
        value.append(np.where(leaf, nodes["value"], 0.0))
    return LegClassifier(
        feature=np.concatenate(feature).astype(np.int32),
        split=np.concatenate(split).astype(np.float64),
        left=np.concatenate(left).astype(np.int32),
        right=np.concatenate(right).astype(np.int32),
        missing_left=np.concatenate(missing_left),
        value=np.concatenate(value).astype(np.float64),
        roots=offsets[:-1].astype(np.int32),
        depth=int(max(int(nodes["depth"].max()) for nodes in trees)),
        bias=float(np.ravel(model._baseline_prediction)[0]),
        threshold=levels[0],
        confirm=levels[1],
        protect=levels[2],
        record=record,
    )


@cache
def shipped_detector() -> LegClassifier:
    """The detector that ships with the package (`robot_logs/data/leg_detector.npz`), read once."""
    with resources.as_file(resources.files("robot_logs") / "data" / SHIPPED_DETECTOR) as path:
        return LegClassifier.load(path)
