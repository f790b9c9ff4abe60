"""Training the leg classifier from labelled logs, with cross-validated precision and recall.

The protocol (docs/leg_detector.md says why): positives are the segments at the labelled legs
(geometry_msgs/PoseArray, one pose per leg); negatives are every candidate segment of logs
recorded with nobody present and the segments of labelled scans farther than `ignore_radius`
from every label; unmatched segments nearer a label (the labelled person's other leg or a piece
of them split differently) are left out of training and of the protocol's scores. Precision and
recall are cross-validated with whole groups held out (each labelled log, or blocks of time),
so neighbouring scans of one walk never sit on both sides of a split; the stricter figure that
counts every unlabelled segment as a negative is reported beside it.

Each figure is given over every log's segments and over the labelled logs' alone, and for the
classifier alone and for the detection stage the tracker uses, the classifier followed by
static-world rejection (`robot_logs.static_world`): a segment on
a cell that the log's own occupancy grid, built from its earlier scans only, holds static is not a
leg.
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
from robot_logs.detection import DetectorConfig, Segments, scan_points, segment
from robot_logs.errors import LogError
from robot_logs.frames import Pose2D
from robot_logs.labels import labelled_scans
from robot_logs.leg_classifier import FORMAT_VERSION, LegClassifier, from_hist_gradient_boosting
from robot_logs.reader import LogReader
from robot_logs.records import Scan
from robot_logs.scan_odometry import ScanOdometry, ScanOdometryConfig
from robot_logs.segment_features import FEATURE_NAMES, segment_features
from robot_logs.static_world import StaticWorld, StaticWorldConfig
from robot_logs.topics import SCAN_TYPES, TopicNames, pick_topic


@dataclass(frozen=True)
class TrainingSettings:
    """How segments are labelled and the classifier is fitted.

    Attributes:
        label_radius: a segment whose centroid lies this close to a labelled leg is that leg (m).
        ignore_radius: an unmatched segment this close to a label is neither leg nor negative (m).
        block_s: length of the time blocks for cross-validation (s).
        folds: folds of the cross-validation by time blocks.
        trees, leaves, learning_rate: the histogram gradient boosting's iterations, leaves per
            tree and step.
        min_leaf, l2: the fewest segments a leaf may hold and the L2 penalty on leaf values;
            together they keep a tree from growing leaves for a few segments of one room.
        balanced: weight legs and other segments equally (legs are about 3 % of the segments).
        recall: the leg threshold is the highest probability at which the detection stage the
            tracker uses (the classifier, then the static world) keeps this share of the labelled
            legs held out (by log when there are two labelled logs or more, else by time blocks).
        confirm_recall, protect_recall: the confirming and the protecting mean probability are
            the highest probabilities that this share of the labelled legs reach, held out alike.
        seed: seeds the boosting and the fold assignment.
        scan_odometry: place each scan by scan matching (`robot_logs.scan_odometry`) for the
            static world, so it holds in the room while the robot moves; off, each sensor's grid
            stays in the sensor's own frame.
    """

    label_radius: float = 0.1
    ignore_radius: float = 1.0
    block_s: float = 10.0
    folds: int = 5
    trees: int = 200
    leaves: int = 31
    learning_rate: float = 0.1
    min_leaf: int = 50
    l2: float = 1.0
    balanced: bool = False
    recall: float = 0.9
    confirm_recall: float = 0.75
    protect_recall: float = 0.5
    seed: int = 0
    scan_odometry: bool = True


@dataclass(frozen=True)
class LabelledSegments:
    """Candidate segments of some logs: (N, F) features, (N,) leg or not, (N,) ignored (unmatched
    but near a label), (N,) log index, (N,) time block (numbered across logs) and (N,) on the
    static world (`StaticFlags`); `logs` names each log with its kind, its scan count and how many
    of them scan matching could not place (`unplaced`), labelled logs first."""

    features: np.ndarray
    is_leg: np.ndarray
    ignored: np.ndarray
    log: np.ndarray
    block: np.ndarray
    static: np.ndarray
    logs: list[dict[str, object]]

    @property
    def labelled_logs(self) -> int:
        return sum(log["kind"] == "labelled" for log in self.logs)


@dataclass(frozen=True)
class Scores:
    """Precision and recall of legs called at the threshold, over held-out predictions of the
    `segments` scored."""

    precision: float
    recall: float
    legs: int
    segments: int

    def as_dict(self) -> dict[str, float | int]:
        return {"precision": self.precision, "recall": self.recall, "legs": self.legs, "segments": self.segments}


@dataclass(frozen=True)
class FalsePositives:
    """The segments of one log wrongly called legs at the threshold under the protocol, held out,
    and how many of them lie on the static world (which the tracker's stage rejects)."""

    file: str
    called: int
    on_static: int


#: The protocol, as the training record states it.
PROTOCOL = {
    "positives": "segments whose centroid is matched one to one to a labelled leg within label_radius",
    "negatives": "every segment of logs recorded with nobody present, and segments of labelled scans "
                 "farther than ignore_radius from every label",
    "ignored": "unmatched segments of labelled scans within ignore_radius of a label (not trained on, "
               "not scored by the protocol; the strict figures count them as negatives)",
    "threshold": "the highest held-out probability at which the classifier followed by the static world "
                 "keeps the settings' recall of the labelled legs",
    "folds by log": "each labelled log held out whole; the time blocks of logs with nobody present "
                    "are dealt to those folds in turn",
    "static world": "the figures with the static world call no segment a leg whose middle point lies on a "
                    "cell that the log's own occupancy grid (robot_logs.static_world, default settings, "
                    "one grid per sensor, no track protected) holds static after the log's earlier scans; "
                    "with scan_odometry each sensor's scans are placed in the frame of its first scan by "
                    "scan matching (robot_logs.scan_odometry), else the grid stays in the sensor's frame",
}


def candidates(scan: Scan, config: DetectorConfig) -> tuple[Segments, np.ndarray]:
    """A scan's segments and the mask of those a classifier sees (as `detection.detect`)."""
    segments = segment(scan, config.jump_distance)
    return segments, (segments.counts >= config.min_points) & (segments.widths < config.candidate_width)


def _digest(path: Path) -> str:
    if path.is_dir():
        return ""
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def match_labels(centroids: np.ndarray, labels: np.ndarray, settings: TrainingSettings) -> tuple[np.ndarray, np.ndarray]:
    """(K,) leg and (K,) ignored masks of K segment centroids against L labelled legs: each
    label takes at most one segment (the closest assignment, within `label_radius`); an
    unmatched segment within `ignore_radius` of a label is ignored."""
    positive = np.zeros(len(centroids), dtype=bool)
    if not len(labels):
        return positive, positive.copy()
    cost = np.hypot(*(centroids[:, None, :] - labels[None, :, :]).transpose(2, 0, 1))
    rows, cols = linear_sum_assignment(cost)
    positive[rows[cost[rows, cols] <= settings.label_radius]] = True
    return positive, ~positive & (cost.min(axis=1) <= settings.ignore_radius)


class StaticFlags:
    """Which candidate segments lie on the static world, scan by scan, as the tracker's grid would
    hold it: one `StaticWorld` per sensor frame, asked before each scan is added, so only earlier
    scans count. The logs carry no odometry here, so with `odometry` settings each sensor's scans
    are placed by scan matching (`ScanOdometry`) in the frame of its first scan, and the room stays
    put while the robot moves; a scan the matching cannot place has nothing static and is not
    added. Without (None), each grid stays in its sensor's frame, where a moving robot keeps little
    static.

    No track keeps its surroundings out of this grid, unlike `PersonTracker`'s, so it needs no
    classifier and is built once for every fold; on the sample bags the tracker's own grid, run
    with each fold's classifier, rejected 11 fewer of the 1,825 labelled legs and moved the
    figures by under 0.01."""

    def __init__(self, odometry: ScanOdometryConfig | None = ScanOdometryConfig()) -> None:
        self.odometry = odometry
        self._worlds: dict[str, StaticWorld] = {}
        self._odometers: dict[str, ScanOdometry] = {}

    def _pose(self, scan: Scan) -> Pose2D | None:
        if self.odometry is None:
            return Pose2D()
        return self._odometers.setdefault(scan.frame_id, ScanOdometry(self.odometry)).update(scan)

    @property
    def lost(self) -> int:
        """Scans the matching could not place, over every sensor."""
        return sum(odometer.lost for odometer in self._odometers.values())

    def __call__(self, scan: Scan, segments: Segments, mask: np.ndarray) -> np.ndarray:
        """(K,) the masked segments on static cells; then adds `scan` to its sensor's grid."""
        world = self._worlds.setdefault(scan.frame_id, StaticWorld(StaticWorldConfig()))
        pose = self._pose(scan)
        if pose is None:
            return np.zeros(int(mask.sum()), dtype=bool)
        static = world.is_static(pose.apply(segments.middles()[mask]))
        world.update(scan, pose.apply(scan_points(scan)), pose, np.zeros((0, 2)))
        return static


def _labelled(scans: list[tuple[Scan, np.ndarray]], settings: TrainingSettings, config: DetectorConfig):
    features, is_leg, ignored, static, stamps = [], [], [], [], []
    flags = StaticFlags(ScanOdometryConfig() if settings.scan_odometry else None)
    for scan, labels in scans:
        segments, mask = candidates(scan, config)
        on_static = flags(scan, segments, mask)
        if not mask.any():
            continue
        positive, near = match_labels(segments.centroids[mask], labels, settings)
        features.append(segment_features(segments.points, segments.starts, mask))
        is_leg.append(positive)
        ignored.append(near)
        static.append(on_static)
        stamps.append(np.full(len(positive), scan.stamp))
    return features, is_leg, ignored, static, stamps, flags.lost


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
    features, is_leg, ignored, static, log_index, blocks, logs = [], [], [], [], [], [], []
    next_block = 0
    for index, path in enumerate([*labelled, *empty]):
        with LogReader(path) as log:
            if index < len(labelled):
                scans = [(scan, label.points) for scan, label in labelled_scans(log, topics)]
            else:
                scans = _scans_of_empty_log(log)
        f, legs, near, on_static, stamps, unplaced = _labelled(scans, settings, config)
        if not f:
            raise LogError(f"{path}: no segment in any scan to learn from")
        stamps_all = np.concatenate(stamps)
        block = np.floor((stamps_all - stamps_all.min()) / settings.block_s).astype(int)
        _, block = np.unique(block, return_inverse=True)
        features.extend(f)
        is_leg.extend(legs)
        ignored.extend(near)
        static.extend(on_static)
        log_index.append(np.full(len(stamps_all), index))
        blocks.append(block + next_block)
        next_block += int(block.max()) + 1
        kind = "labelled" if index < len(labelled) else "nobody present"
        logs.append({"file": Path(path).name, "kind": kind, "scans": len(scans), "sha256": _digest(Path(path)),
                     "unplaced": unplaced})
    data = LabelledSegments(
        np.concatenate(features), np.concatenate(is_leg), np.concatenate(ignored), np.concatenate(log_index),
        np.concatenate(blocks), np.concatenate(static), logs,
    )
    if not data.is_leg.any():
        raise LogError(f"no segment lies within {settings.label_radius} m of a labelled leg in {', '.join(map(str, labelled))}")
    return data


def _model(settings: TrainingSettings):
    """The classifier to fit. The defaults are the settings that scored best held out by log
    among those tried (docs/leg_detector.md): larger, penalised leaves and no class
    weights; the threshold, not the weights, sets how many legs are kept."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    return HistGradientBoostingClassifier(
        max_iter=settings.trees,
        max_leaf_nodes=settings.leaves,
        learning_rate=settings.learning_rate,
        min_samples_leaf=settings.min_leaf,
        l2_regularization=settings.l2,
        class_weight="balanced" if settings.balanced else None,
        early_stopping=False,
        random_state=settings.seed,
    )


def scores(is_leg: np.ndarray, probability: np.ndarray, threshold: float) -> Scores:
    """Precision and recall of calling legs the segments at or above `threshold`."""
    called = probability >= threshold
    hits = int((called & is_leg).sum())
    return Scores(hits / max(int(called.sum()), 1), hits / max(int(is_leg.sum()), 1), int(is_leg.sum()), len(is_leg))


def folds(data: LabelledSegments, by: str, settings: TrainingSettings = TrainingSettings()) -> np.ndarray:
    """(N,) the fold each segment is held out in: `by` "log" (each labelled log a fold of its
    own, the time blocks of logs with nobody present dealt to those folds in turn; needs two
    labelled logs) or "time" (blocks of `block_s` seconds shuffled into `folds` groups)."""
    if by == "log":
        labelled = data.labelled_logs
        if labelled < 2:
            raise LogError("cross-validation by log needs two labelled logs or more")
        return np.where(data.log < labelled, data.log, data.block % labelled)
    from sklearn.model_selection import GroupKFold

    splitter = GroupKFold(n_splits=min(settings.folds, len(np.unique(data.block))), shuffle=True,
                          random_state=settings.seed)
    fold = np.empty(len(data.block), dtype=int)
    for index, (_, test) in enumerate(splitter.split(data.features, groups=data.block)):
        fold[test] = index
    return fold


def held_out_probability(data: LabelledSegments, by: str, settings: TrainingSettings = TrainingSettings()) -> np.ndarray:
    """(N,) each segment's leg probability from a model fitted, under the protocol, on the other
    folds (`folds`), so it never saw the segment's log or time block."""
    fold = folds(data, by, settings)
    probability = np.zeros(len(fold))
    trainable = ~data.ignored
    for held_out in np.unique(fold):
        test = fold == held_out
        fit = trainable & ~test
        model = _model(settings).fit(data.features[fit], data.is_leg[fit])
        probability[test] = model.predict_proba(data.features[test])[:, 1]
    return probability


def threshold_for_recall(is_leg: np.ndarray, probability: np.ndarray, recall: float) -> float:
    """The highest probability threshold that still calls a share `recall` of the labelled legs."""
    leg_probability = np.sort(probability[is_leg])[::-1]
    keep = max(int(np.ceil(recall * len(leg_probability))), 1)
    return float(leg_probability[keep - 1])


def stage_threshold(is_leg: np.ndarray, probability: np.ndarray, static: np.ndarray, recall: float) -> float:
    """The highest probability threshold at which the classifier followed by the static world
    (which drops the `static` segments) still calls a share `recall` of the labelled legs; where
    the static world holds more legs than that leaves out, the threshold that keeps every leg off it.

    Raises:
        LogError: every labelled leg lies on the static world.
    """
    kept = is_leg & ~static
    if not kept.any():
        raise LogError("every labelled leg lies on its log's static world: no threshold keeps any")
    return max(threshold_for_recall(is_leg, np.where(static, -np.inf, probability), recall), float(probability[kept].min()))


def validate(
    data: LabelledSegments, settings: TrainingSettings = TrainingSettings()
) -> tuple[tuple[float, float, float], dict[str, Scores], list[FalsePositives]]:
    """The (threshold, confirm, protect) probabilities, from the held-out predictions by log (by
    time blocks when only one log is labelled), the threshold for the classifier followed by the
    static world (`stage_threshold`); the held-out scores at the threshold, by log
    and by time blocks, each under the protocol and strictly (every unlabelled segment a
    negative), for the classifier alone and followed by the static world (`StaticFlags`); and
    each log's false positives under the protocol, held out as the threshold was.

    The scores' keys name the design ("logs", "time blocks"), then ", labelled logs" for the figures
    over the labelled logs' segments alone (the logs with nobody present left out), ", static world"
    and ", strict" where they apply."""
    designs = (["log"] if data.labelled_logs >= 2 else []) + ["time"]
    held_out = {by: held_out_probability(data, by, settings) for by in designs}
    chosen = held_out[designs[0]]
    levels = (stage_threshold(data.is_leg, chosen, data.static, settings.recall),
              *(threshold_for_recall(data.is_leg, chosen, share) for share in (settings.confirm_recall, settings.protect_recall)))
    validation = {}
    scopes = (("", np.ones(len(data.is_leg), dtype=bool)), (", labelled logs", data.log < data.labelled_logs))
    for by, probability in held_out.items():
        name = {"log": "logs", "time": "time blocks"}[by]
        for scope, within in scopes:
            scored = within & ~data.ignored
            for stage, kept in (("", probability), (", static world", np.where(data.static, -np.inf, probability))):
                validation[f"{name}{scope}{stage}"] = scores(data.is_leg[scored], kept[scored], levels[0])
                validation[f"{name}{scope}{stage}, strict"] = scores(data.is_leg[within], kept[within], levels[0])
    wrong = (chosen >= levels[0]) & ~data.is_leg & ~data.ignored
    false_positives = [
        FalsePositives(str(log["file"]), int((wrong & (data.log == index)).sum()),
                       int((wrong & data.static & (data.log == index)).sum()))
        for index, log in enumerate(data.logs)
    ]
    return levels, validation, false_positives


def train(
    data: LabelledSegments, levels: tuple[float, float, float], settings: TrainingSettings = TrainingSettings(),
    validation: dict[str, Scores] | None = None,
) -> LegClassifier:
    """Fit on all the data under the protocol; the record keeps the data, the protocol, the
    settings and `validation`'s figures."""
    import sklearn

    trainable = ~data.ignored
    model = _model(settings).fit(data.features[trainable], data.is_leg[trainable])
    record = {
        "format": FORMAT_VERSION,
        "features": list(FEATURE_NAMES),
        "model": f"sklearn.ensemble.HistGradientBoostingClassifier (scikit-learn {sklearn.__version__})",
        "protocol": PROTOCOL,
        "settings": settings.__dict__,
        "threshold": levels[0],
        "confirm": levels[1],
        "protect": levels[2],
        "logs": data.logs,
        "segments": len(data.is_leg),
        "legs": int(data.is_leg.sum()),
        "ignored": int(data.ignored.sum()),
        "cross_validation": {name: score.as_dict() for name, score in (validation or {}).items()},
        "trained": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
    }
    return from_hist_gradient_boosting(model, levels, record)
