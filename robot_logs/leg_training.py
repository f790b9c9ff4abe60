"""Training the leg classifier from labelled logs, with cross-validated precision and recall.

Positives are the segments at the labelled legs (geometry_msgs/PoseArray, one pose per leg);
negatives are every other candidate segment of the labelled scans, and every candidate segment
of logs recorded with nobody present. Precision and recall are cross-validated with whole
groups held out (blocks of time, or whole logs), so neighbouring scans of one walk never sit
on both sides of a split.
"""

from __future__ import annotations

import datetime
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from robot_logs.convert import to_scan
from robot_logs.detection import DetectorConfig, Segments, segment
from robot_logs.errors import LogError
from robot_logs.labels import labelled_scans
from robot_logs.leg_classifier import FORMAT_VERSION, LegClassifier, from_gradient_boosting
from robot_logs.reader import LogReader
from robot_logs.records import Scan
from robot_logs.segment_features import FEATURE_NAMES, segment_features
from robot_logs.topics import SCAN_TYPES, TopicNames, pick_topic


@dataclass(frozen=True)
class TrainingSettings:
    """How segments are labelled and the classifier is fitted.

    Attributes:
        label_radius: a segment whose centroid lies this close to a labelled leg is that leg (m).
        block_s: length of the time blocks for cross-validation (s).
        folds: folds of the cross-validation by time blocks.
        trees, depth, learning_rate: the gradient boosting's size and step.
        recall, confirm_recall, protect_recall: the leg threshold, the confirming and the
            protecting mean probability are the highest probabilities that this share of the
            labelled legs reach in the cross-validation by time blocks.
        seed: seeds the boosting's subsampling and the fold assignment.
    """

    label_radius: float = 0.1
    block_s: float = 10.0
    folds: int = 5
    trees: int = 100
    depth: int = 3
    learning_rate: float = 0.1
    recall: float = 0.9
    confirm_recall: float = 0.75
    protect_recall: float = 0.5
    seed: int = 0


@dataclass(frozen=True)
class LabelledSegments:
    """Candidate segments of some logs: (N, F) features, (N,) leg or not, (N,) log index and
    (N,) time block (numbered across logs); `logs` names each log with its scan count."""

    features: np.ndarray
    is_leg: np.ndarray
    log: np.ndarray
    block: np.ndarray
    logs: list[dict[str, object]]


@dataclass(frozen=True)
class Scores:
    """Precision and recall of legs called at the threshold, over held-out predictions."""

    precision: float
    recall: float
    legs: int
    segments: int

    def as_dict(self) -> dict[str, float | int]:
        return {"precision": self.precision, "recall": self.recall, "legs": self.legs, "segments": self.segments}


def candidates(scan: Scan, config: DetectorConfig) -> tuple[Segments, np.ndarray]:
    """A scan's segments and the mask of those a classifier sees (as `detection.detect`)."""
    segments = segment(scan, config.jump_distance)
    return segments, (segments.counts >= config.min_points) & (segments.widths < config.candidate_width)


def _digest(path: Path) -> str:
    if path.is_dir():
        return ""
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def _labelled(scans: list[tuple[Scan, np.ndarray]], settings: TrainingSettings, config: DetectorConfig):
    features, is_leg, stamps = [], [], []
    for scan, labels in scans:
        segments, mask = candidates(scan, config)
        if not mask.any():
            continue
        centroids = segments.centroids[mask]
        positive = np.zeros(len(centroids), dtype=bool)
        if len(labels):
            cost = np.hypot(*(centroids[:, None, :] - labels[None, :, :]).transpose(2, 0, 1))
            rows, cols = linear_sum_assignment(cost)
            positive[rows[cost[rows, cols] <= settings.label_radius]] = True
        features.append(segment_features(segments.points, segments.starts, mask))
        is_leg.append(positive)
        stamps.append(np.full(len(centroids), scan.stamp))
    return features, is_leg, stamps


def _scans_of_empty_log(log: LogReader) -> list[tuple[Scan, np.ndarray]]:
    topics = {t.name for t in log.topics if t.msgtype in SCAN_TYPES}
    if not topics:
        pick_topic(log.topics, SCAN_TYPES, "LaserScan", None, log.path, "--scan-topic")
    return [
        (to_scan(m.data, m.record_ns, f"scan on {m.topic} of {log.path}"), np.zeros((0, 2)))
        for m in log.messages(topics)
    ]


def collect(
    labelled: Sequence[Path],
    empty: Sequence[Path] = (),
    topics: TopicNames = TopicNames(),
    settings: TrainingSettings = TrainingSettings(),
    config: DetectorConfig = DetectorConfig(),
) -> LabelledSegments:
    """Candidate segments of labelled logs and of logs with nobody present (all negative).

    Raises:
        LogError: a labelled log has no PoseArray labels (or no scans), or no leg was found
            at any label.
    """
    features, is_leg, log_index, blocks, logs = [], [], [], [], []
    next_block = 0
    for index, path in enumerate([*labelled, *empty]):
        with LogReader(path) as log:
            if index < len(labelled):
                scans = [(scan, label.points) for scan, label in labelled_scans(log, topics)]
            else:
                scans = _scans_of_empty_log(log)
        f, legs, stamps = _labelled(scans, settings, config)
        if not f:
            raise LogError(f"{path}: no segment in any scan to learn from")
        stamps_all = np.concatenate(stamps)
        block = np.floor((stamps_all - stamps_all.min()) / settings.block_s).astype(int)
        _, block = np.unique(block, return_inverse=True)
        features.extend(f)
        is_leg.extend(legs)
        log_index.append(np.full(len(stamps_all), index))
        blocks.append(block + next_block)
        next_block += int(block.max()) + 1
        kind = "labelled" if index < len(labelled) else "nobody present"
        logs.append({"file": Path(path).name, "kind": kind, "scans": len(scans), "sha256": _digest(Path(path))})
    data = LabelledSegments(
        np.concatenate(features), np.concatenate(is_leg), np.concatenate(log_index), np.concatenate(blocks), logs
    )
    if not data.is_leg.any():
        raise LogError(f"no segment lies within {settings.label_radius} m of a labelled leg in {', '.join(map(str, labelled))}")
    return data


def _model(settings: TrainingSettings):
    from sklearn.ensemble import GradientBoostingClassifier

    return GradientBoostingClassifier(
        n_estimators=settings.trees,
        max_depth=settings.depth,
        learning_rate=settings.learning_rate,
        subsample=0.5,
        random_state=settings.seed,
    )


def scores(is_leg: np.ndarray, probability: np.ndarray, threshold: float) -> Scores:
    """Precision and recall of calling legs the segments at or above `threshold`."""
    called = probability >= threshold
    hits = int((called & is_leg).sum())
    return Scores(hits / max(int(called.sum()), 1), hits / max(int(is_leg.sum()), 1), int(is_leg.sum()), len(is_leg))


def held_out_probability(data: LabelledSegments, by: str, settings: TrainingSettings = TrainingSettings()) -> np.ndarray:
    """(N,) each segment's leg probability from a model that never saw its group: `by` "time"
    (blocks of `block_s` seconds in `folds` groups) or "log" (each log held out in turn)."""
    from sklearn.model_selection import GroupKFold, LeaveOneGroupOut, cross_val_predict

    if by == "log":
        groups, splitter = data.log, LeaveOneGroupOut()
    else:
        groups = data.block
        splitter = GroupKFold(n_splits=min(settings.folds, len(np.unique(groups))), shuffle=True, random_state=settings.seed)
    return cross_val_predict(
        _model(settings), data.features, data.is_leg, groups=groups, cv=splitter, method="predict_proba"
    )[:, 1]


def threshold_for_recall(is_leg: np.ndarray, probability: np.ndarray, recall: float) -> float:
    """The highest probability threshold that still calls a share `recall` of the labelled legs."""
    leg_probability = np.sort(probability[is_leg])[::-1]
    keep = max(int(np.ceil(recall * len(leg_probability))), 1)
    return float(leg_probability[keep - 1])


def validate(
    data: LabelledSegments, settings: TrainingSettings = TrainingSettings()
) -> tuple[tuple[float, float, float], dict[str, Scores]]:
    """The (threshold, confirm, protect) probabilities from the time-block cross-validation, and
    the held-out scores at the threshold, by time blocks and by whole logs."""
    by_time = held_out_probability(data, "time", settings)
    shares = (settings.recall, settings.confirm_recall, settings.protect_recall)
    threshold, confirm, protect = (threshold_for_recall(data.is_leg, by_time, share) for share in shares)
    by_log = held_out_probability(data, "log", settings)
    validation = {"time blocks": scores(data.is_leg, by_time, threshold), "logs": scores(data.is_leg, by_log, threshold)}
    return (threshold, confirm, protect), validation


def train(
    data: LabelledSegments, levels: tuple[float, float, float], settings: TrainingSettings = TrainingSettings(),
    validation: dict[str, Scores] | None = None,
) -> LegClassifier:
    """Fit on all the data; the record keeps the data, the settings and `validation`'s figures."""
    import sklearn

    model = _model(settings).fit(data.features, data.is_leg)
    record = {
        "format": FORMAT_VERSION,
        "features": list(FEATURE_NAMES),
        "model": f"sklearn.ensemble.GradientBoostingClassifier (scikit-learn {sklearn.__version__})",
        "settings": settings.__dict__,
        "threshold": levels[0],
        "confirm": levels[1],
        "protect": levels[2],
        "logs": data.logs,
        "segments": len(data.is_leg),
        "legs": int(data.is_leg.sum()),
        "cross_validation": {name: score.as_dict() for name, score in (validation or {}).items()},
        "trained": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
    }
    return from_gradient_boosting(model, levels, record)
