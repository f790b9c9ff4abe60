"""The learned leg classifier as plain arrays: its file format, loading and prediction.

A gradient-boosted ensemble of shallow decision trees, trained with scikit-learn
(`robot_logs.leg_training`) and stored as the trees' arrays in an .npz file with a format
version and the training record, never as a pickle, so a detector file is safe to open and
easy to version. Prediction walks all trees at once with numpy, one level per step.
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

#: The detector file format this code reads and writes; bump it when the arrays change.
FORMAT_VERSION = 1

#: The detector shipped with the package, trained on tests/data/robot_logs (its record says how).
SHIPPED_DETECTOR = "leg_detector.npz"

_ARRAYS = ("feature", "split", "left", "right", "value", "roots")


@dataclass(frozen=True, eq=False)
class LegClassifier:
    """Trees as flat node arrays; a leaf points to itself on both sides and has feature 0.

    Attributes:
        feature, split: the feature index and the split value of each node (go left if <=).
        left, right: child node indices.
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
        # scikit-learn compares float32 features with its thresholds; do the same.
        features = np.asarray(features, dtype=np.float32)
        rows = np.arange(len(features))[None, :]
        nodes = np.repeat(self.roots[:, None], len(features), axis=1)
        for _ in range(self.depth):
            go_left = features[rows, self.feature[nodes]] <= self.split[nodes]
            nodes = np.where(go_left, self.left[nodes], self.right[nodes])
        log_odds = self.bias + self.value[nodes].sum(axis=0)
        return 1.0 / (1.0 + np.exp(-log_odds))

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


def from_gradient_boosting(model: Any, levels: tuple[float, float, float], record: dict[str, Any]) -> LegClassifier:
    """The arrays of a fitted binary `sklearn.ensemble.GradientBoostingClassifier`, with
    `levels` its (threshold, confirm, protect) probabilities.

    Its log-odds are the prior's plus the learning rate times each tree's leaf value; the
    prior is read back as the model's decision at a point minus the trees' sum there.
    """
    trees = [estimator.tree_ for estimator in model.estimators_[:, 0]]
    offsets = np.cumsum([0] + [tree.node_count for tree in trees])
    feature, split, left, right, value = [], [], [], [], []
    for offset, tree in zip(offsets, trees):
        leaf = tree.children_left < 0
        own = np.arange(tree.node_count) + offset
        feature.append(np.where(leaf, 0, tree.feature))
        split.append(np.where(leaf, 0.0, tree.threshold))
        left.append(np.where(leaf, own, tree.children_left + offset))
        right.append(np.where(leaf, own, tree.children_right + offset))
        value.append(np.where(leaf, model.learning_rate * tree.value[:, 0, 0], 0.0))
    classifier = LegClassifier(
        feature=np.concatenate(feature).astype(np.int32),
        split=np.concatenate(split).astype(np.float64),
        left=np.concatenate(left).astype(np.int32),
        right=np.concatenate(right).astype(np.int32),
        value=np.concatenate(value),
        roots=offsets[:-1].astype(np.int32),
        depth=max(tree.max_depth for tree in trees),
        bias=0.0,
        threshold=levels[0],
        confirm=levels[1],
        protect=levels[2],
        record=record,
    )
    probe = np.zeros((1, model.n_features_in_))
    trees_only = np.log(classifier.probability(probe) / (1.0 - classifier.probability(probe)))
    bias = float(model.decision_function(probe)[0] - trees_only[0])
    return LegClassifier(**{**classifier.__dict__, "bias": bias})


@cache
def shipped_detector() -> LegClassifier:
    """The detector that ships with the package (`robot_logs/data/leg_detector.npz`), read once."""
    with resources.as_file(resources.files("robot_logs") / "data" / SHIPPED_DETECTOR) as path:
        return LegClassifier.load(path)
