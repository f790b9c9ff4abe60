"""Training the leg classifier from labelled logs, with cross-validated precision and recall.

The protocol (docs/leg_detector.md says why): positives are the segments at the labelled legs
(geometry_msgs/PoseArray, one pose per leg) and, in logs of a robot standing still, the
leg-sized segments standing in front of the room's background (`robot_logs.background_labels`);
negatives are every candidate segment of logs recorded with nobody present, the segments of
labelled scans farther than `ignore_radius` from every label and the standing logs' segments on
their background; unmatched segments nearer a label (the labelled person's other leg or a piece
of them split differently) and segments partly in front of the background are left out of
training and of the protocol's scores. Each labelled and standing log is also trained on as
copies (`AUGMENTATIONS`): as a laser of half its resolution sees it, the same with every segment
taken for twice as far, and with beams lost; copies are never scored. Precision and recall are
cross-validated with whole groups held out (each labelled or standing log with its copies, or
blocks of time), so neighbouring scans of one walk never sit on both sides of a split; the
stricter figure that counts every unlabelled segment as a negative is reported beside it.

Each figure is given over every log's segments, over the labelled logs' and over the standing
logs' alone, and for the
classifier alone and for the detection stage the tracker uses, the classifier followed by
static-world rejection (`robot_logs.static_world`): a segment on
a cell that the log's own occupancy grid, built from its earlier scans only, holds static is not a
leg.
"""

from __future__ import annotations

import datetime
import hashlib
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from robot_logs.background_labels import IN_FRONT_SHARE, MARGIN, Background, background_labels
from robot_logs.convert import to_scan
from robot_logs.detection import DetectorConfig, Segments, scan_points, segment
from robot_logs.errors import LogError
from robot_logs.frames import Pose2D
from robot_logs.labels import labelled_scans
from robot_logs.leg_classifier import FORMAT_VERSION, LegClassifier, from_hist_gradient_boosting
from robot_logs.reader import LogReader
from robot_logs.records import Scan
from robot_logs.scan_odometry import ScanOdometry, ScanOdometryConfig
from robot_logs.segment_features import FEATURE_NAMES
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
        augment: also train on each labelled and standing log as `AUGMENTATIONS` change it.
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
    augment: bool = True


@dataclass(frozen=True)
class LabelledSegments:
    """Candidate segments of some logs: (N, F) features, (N,) leg or not, (N,) ignored
    (unmatched but near a label), (N,) log index, (N,) time block (numbered across logs), (N,)
    on the static world (`StaticFlags`), (N,) from an augmented copy (`AUGMENTATIONS`; trained
    on, never scored) and (N, 2) centroids in their scan's frame (m); `logs` names each log with
    its kind, its scan count and how many of them scan matching could not place (`unplaced`):
    labelled logs first, then standing, then empty ones."""

    features: np.ndarray
    is_leg: np.ndarray
    ignored: np.ndarray
    log: np.ndarray
    block: np.ndarray
    static: np.ndarray
    logs: list[dict[str, object]]
    augmented: np.ndarray
    centroids: np.ndarray

    def count(self, kind: str) -> int:
        """How many logs of a `kind` ("labelled", "standing", "nobody present")."""
        return sum(log["kind"] == kind for log in self.logs)

    @property
    def labelled_logs(self) -> int:
        return self.count("labelled")

    @property
    def logs_with_legs(self) -> int:
        """How many labelled and standing logs (each a fold of its own by log; they come first)."""
        return self.labelled_logs + self.count("standing")


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
    "positives": "segments whose centroid is matched one to one to a labelled leg within label_radius; in "
                 f"logs of a robot standing still, leg-wide segments with {IN_FRONT_SHARE:.0%} of their points "
                 f"{MARGIN} m or more in front of their beams' background (robot_logs.background_labels)",
    "negatives": "every segment of logs recorded with nobody present, segments of labelled scans "
                 "farther than ignore_radius from every label, and standing logs' segments on the background",
    "ignored": "unmatched segments of labelled scans within ignore_radius of a label, and standing logs' other "
               "segments with a point in front of the background (not trained on, not scored by the protocol; "
               "the strict figures count them as negatives)",
    "augmented": "each labelled and standing log is also trained on as seen with every other beam, the same "
                 "with each segment taken for twice as far, and with runs of lost beams "
                 "(leg_training.AUGMENTATIONS); these copies are held out with their log, never scored",
    "threshold": "the highest held-out probability at which the classifier followed by the static world "
                 "keeps the settings' recall of the hand-labelled legs",
    "folds by log": "each labelled and each standing log held out whole; the time blocks of logs with nobody "
                    "present are dealt to those folds in turn",
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


def half_beams(scan: Scan, rng: np.random.Generator) -> Scan:
    """Every other beam, from the first or the second: a laser of half the angular resolution,
    or the same one seeing everything twice as far in beams per metre."""
    start = int(rng.integers(2))
    return replace(scan, angle_min=scan.angle_min + start * scan.angle_increment,
                   angle_increment=2.0 * scan.angle_increment, ranges=scan.ranges[start::2].copy())


def lost_beams(scan: Scan, rng: np.random.Generator) -> Scan:
    """One beam in 20 starts a run of 1 to 3 beams that return nothing: a darker or partly
    occluded surface, segments cut short or split."""
    ranges = scan.ranges.copy()
    for start in np.flatnonzero(rng.random(len(ranges)) < 0.05):
        ranges[start:start + int(rng.integers(1, 4))] = np.inf
    return replace(scan, ranges=ranges)


#: How a log's segments are labelled: given a scan, its segments and the mask of the K candidates,
#: the (K,) leg and ignored masks of those candidates.
Labeller = Callable[[Scan, Segments, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class _Gathered:
    """A log's candidate segments as they are gathered, scan by scan."""

    features: list[np.ndarray]
    is_leg: list[np.ndarray]
    ignored: list[np.ndarray]
    static: list[np.ndarray]
    stamps: list[np.ndarray]
    centroids: list[np.ndarray]

    def extend(self, other: _Gathered) -> None:
        """Append another gathering's segments (an augmented copy's)."""
        for name in ("features", "is_leg", "ignored", "static", "stamps", "centroids"):
            getattr(self, name).extend(getattr(other, name))


def _gather(scans: Iterable[Scan], label: Labeller, config: DetectorConfig, flags: StaticFlags | None) -> _Gathered:
    """The labelled candidate segments of `scans`, each flagged on the static world by `flags`
    (None: none is)."""
    gathered = _Gathered([], [], [], [], [], [])
    for scan in scans:
        segments, mask = candidates(scan, config)
        on_static = flags(scan, segments, mask) if flags is not None else np.zeros(int(mask.sum()), dtype=bool)
        if not mask.any():
            continue
        positive, near = label(scan, segments, mask)
        gathered.features.append(segments.features(mask))
        gathered.is_leg.append(positive)
        gathered.ignored.append(near)
        gathered.static.append(on_static)
        gathered.stamps.append(np.full(len(positive), scan.stamp))
        gathered.centroids.append(segments.centroids[mask])
    return gathered


@dataclass(frozen=True)
class Augmentation:
    """An augmented copy of a log: `change` makes each scan's copy, and the copy's segments are
    taken to stand `farther` times as far from the laser (their distance feature alone changes)."""

    change: Callable[[Scan, np.random.Generator], Scan]
    farther: float = 1.0

    def gather(self, scans: Iterable[Scan], label: Labeller, config: DetectorConfig, rng: np.random.Generator) -> _Gathered:
        """The copy's labelled candidate segments (none on the static world: copies only train)."""
        copy = _gather((self.change(scan, rng) for scan in scans), label, config, None)
        for features in copy.features:
            features[:, DISTANCE] *= self.farther
        return copy


#: The augmented copies of each labelled and standing log: how another laser sees the same legs. A
#: laser sees a leg with every other beam as it sees the leg twice as far with every beam (the
#: same points per leg, as far apart), so that copy also teaches legs beyond the labelled range.
AUGMENTATIONS = {
    "half beams": Augmentation(half_beams),
    "half beams, twice as far": Augmentation(half_beams, farther=2.0),
    "lost beams": Augmentation(lost_beams),
}

#: The column of the segment's distance from the laser.
DISTANCE = FEATURE_NAMES.index("distance")


def _scans(log: LogReader, topics: set[str]) -> list[Scan]:
    return [to_scan(m.data, m.record_ns, f"scan on {m.topic} of {log.path}") for m in log.messages(topics)]


def _all_scans(log: LogReader) -> list[Scan]:
    topics = {t.name for t in log.topics if t.msgtype in SCAN_TYPES}
    if not topics:
        pick_topic(log.topics, SCAN_TYPES, "LaserScan", None, log.path, "--scan-topic")
    return _scans(log, topics)


def _standing_scans(log: LogReader, topics: TopicNames) -> list[Scan]:
    return _scans(log, {pick_topic(log.topics, SCAN_TYPES, "LaserScan", topics.scan, log.path, "--scan-topic").name})


def _scans_and_labeller(path: Path, kind: str, topics: TopicNames, settings: TrainingSettings,
                        config: DetectorConfig) -> tuple[list[Scan], Labeller]:
    """A log's scans and how its segments are labelled, by its kind."""
    with LogReader(path) as log:
        if kind == "labelled":
            pairs = labelled_scans(log, topics)
            scans = [scan for scan, _ in pairs]
        else:
            scans = _standing_scans(log, topics) if kind == "standing" else _all_scans(log)
    if kind == "labelled":
        # An augmented copy keeps its scan's stamp and labels: the legs stay where they were.
        by_stamp = {scan.stamp_ns: label.points for scan, label in pairs}
        return scans, lambda scan, segments, mask: match_labels(segments.centroids[mask], by_stamp[scan.stamp_ns], settings)
    if kind == "standing":
        background = Background.of(scans, str(path))
        return scans, lambda scan, segments, mask: background_labels(background, segments, mask, config.leg_width)

    def nobody(scan: Scan, segments: Segments, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        none = np.zeros(int(mask.sum()), dtype=bool)
        return none, none.copy()

    return scans, nobody


def collect(
    labelled: Sequence[Path],
    empty: Sequence[Path] = (),
    topics: TopicNames = TopicNames(),
    settings: TrainingSettings = TrainingSettings(),
    config: DetectorConfig = DetectorConfig(),
    standing: Sequence[Path] = (),
) -> LabelledSegments:
    """Candidate segments of labelled logs, of logs of a robot standing still among passers-by
    (labelled by background subtraction) with their augmented copies (`settings.augment`), and
    of logs with nobody present (all negative).

    Raises:
        LogError: a labelled log has no PoseArray labels (or no scans), or no leg was found
            at any label; a standing log has no scans, scans of differing beams, too few beams on
            their background (the robot moved) or no leg in front of it; a log has no candidate
            segment.
    """
    every = _Gathered([], [], [], [], [], [])
    log_index, blocks, logs, augmented = [], [], [], []
    next_block = 0
    kinds = [("labelled", path) for path in labelled] + [("standing", path) for path in standing]
    kinds += [("nobody present", path) for path in empty]
    for index, (kind, path) in enumerate(kinds):
        scans, label = _scans_and_labeller(Path(path), kind, topics, settings, config)
        flags = StaticFlags(ScanOdometryConfig() if settings.scan_odometry else None)
        gathered = _gather(scans, label, config, flags)
        if not gathered.features:
            raise LogError(f"{path}: no segment in any scan to learn from")
        if kind == "standing" and not any(legs.any() for legs in gathered.is_leg):
            raise LogError(f"{path}: no leg-wide segment stands in front of the background; expected a robot "
                           "standing still while people pass")
        recorded = sum(len(stamps) for stamps in gathered.stamps)
        if settings.augment and kind != "nobody present":
            for number, augmentation in enumerate(AUGMENTATIONS.values()):
                rng = np.random.default_rng([settings.seed, index, number])
                gathered.extend(augmentation.gather(scans, label, config, rng))
        stamps_all = np.concatenate(gathered.stamps)
        # A copy's segments fall in the time block of the scan they were copied from.
        block = np.floor((stamps_all - stamps_all[:recorded].min()) / settings.block_s).astype(int)
        _, block = np.unique(block, return_inverse=True)
        every.extend(gathered)
        log_index.append(np.full(len(stamps_all), index))
        blocks.append(block + next_block)
        augmented.append(np.arange(len(stamps_all)) >= recorded)
        next_block += int(block.max()) + 1
        logs.append({"file": Path(path).name, "kind": kind, "scans": len(scans), "sha256": _digest(Path(path)),
                     "unplaced": flags.lost})
    data = LabelledSegments(
        np.concatenate(every.features), np.concatenate(every.is_leg), np.concatenate(every.ignored),
        np.concatenate(log_index), np.concatenate(blocks), np.concatenate(every.static), logs, np.concatenate(augmented),
        np.concatenate(every.centroids),
    )
    if not data.is_leg[(data.log < data.labelled_logs) & ~data.augmented].any():
        raise LogError(f"no segment lies within {settings.label_radius} m of a labelled leg in {', '.join(map(str, labelled))}")
    return data


def _model(settings: TrainingSettings):
    """The classifier to fit. The defaults were chosen among the settings tried by their figures
    held out by log and by tracking (docs/leg_detector.md): larger, penalised leaves and no class
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
    """(N,) the fold each segment is held out in: `by` "log" (each labelled and each standing
    log a fold of its own with its augmented copies, the time blocks of logs with nobody present
    dealt to those folds in turn; needs two labelled logs) or "time" (blocks of `block_s` seconds
    shuffled into `folds` groups)."""
    if by == "log":
        if data.labelled_logs < 2:
            raise LogError("cross-validation by log needs two labelled logs or more")
        with_legs = data.logs_with_legs
        return np.where(data.log < with_legs, data.log, data.block % with_legs)
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
    time blocks when only one log is labelled) of the hand-labelled legs, the threshold for the
    classifier followed by the static world (`stage_threshold`); the held-out scores at the
    threshold, by log and by time blocks, each under the protocol and strictly (every unlabelled
    segment a negative), for the classifier alone and followed by the static world
    (`StaticFlags`); and each log's false positives under the protocol, held out as the threshold
    was. Augmented copies are never scored.

    The scores' keys name the design ("logs", "time blocks"), then ", labelled logs" or ", standing
    logs" for the figures over those logs' segments alone, ", static world" and ", strict" where
    they apply."""
    designs = (["log"] if data.labelled_logs >= 2 else []) + ["time"]
    held_out = {by: held_out_probability(data, by, settings) for by in designs}
    chosen = held_out[designs[0]]
    recorded = ~data.augmented
    labelled = recorded & (data.log < data.labelled_logs)
    levels = (stage_threshold(data.is_leg[labelled], chosen[labelled], data.static[labelled], settings.recall),
              *(threshold_for_recall(data.is_leg[labelled], chosen[labelled], share)
                for share in (settings.confirm_recall, settings.protect_recall)))
    validation = {}
    scopes = [("", recorded), (", labelled logs", labelled)]
    if data.count("standing"):
        scopes.append((", standing logs", recorded & (data.log >= data.labelled_logs) & (data.log < data.logs_with_legs)))
    for by, probability in held_out.items():
        name = {"log": "logs", "time": "time blocks"}[by]
        for scope, within in scopes:
            scored = within & ~data.ignored
            for stage, kept in (("", probability), (", static world", np.where(data.static, -np.inf, probability))):
                validation[f"{name}{scope}{stage}"] = scores(data.is_leg[scored], kept[scored], levels[0])
                validation[f"{name}{scope}{stage}, strict"] = scores(data.is_leg[within], kept[within], levels[0])
    wrong = (chosen >= levels[0]) & ~data.is_leg & ~data.ignored & recorded
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
        "segments": int((~data.augmented).sum()),
        "legs": int(data.is_leg[~data.augmented].sum()),
        "ignored": int(data.ignored[~data.augmented].sum()),
        "augmented_segments": int(data.augmented.sum()),
        "cross_validation": {name: score.as_dict() for name, score in (validation or {}).items()},
        "trained": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
    }
    return from_hist_gradient_boosting(model, levels, record)
