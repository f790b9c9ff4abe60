"""The learned leg detector: segment features on hand-made shapes, the training protocol (label
matching, folds by log), the tree arrays against scikit-learn, the detector file (format version,
training record), and `train-detector`'s bad input."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robot_logs.detection import DetectorConfig, open_beams, segment
from robot_logs.errors import LogError
from robot_logs.frames import Pose2D
from robot_logs.leg_classifier import FORMAT_VERSION, LegClassifier, from_hist_gradient_boosting, shipped_detector
from robot_logs.leg_training import (
    LabelledSegments,
    StaticFlags,
    TrainingSettings,
    candidates,
    folds,
    match_labels,
    stage_threshold,
    threshold_for_recall,
)
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.records import Scan
from robot_logs.segment_features import CONTEXT_NAMES, FEATURE_NAMES, MAX_RADIUS, SHAPE_NAMES, STANDS_FREE, segment_features
from trials.cli import main

COLUMN = {name: k for k, name in enumerate(FEATURE_NAMES)}

#: The angle between beams of the hand-made scans (rad): 0.25 degrees.
BEAM = math.radians(0.25)


def arc(centre: tuple[float, float], radius: float, points: int) -> np.ndarray:
    """The near half of a circle as a sensor at the origin sees it (a leg at `centre`)."""
    facing = math.atan2(-centre[1], -centre[0])
    angles = np.linspace(facing - math.pi / 2 + 0.2, facing + math.pi / 2 - 0.2, points)
    return np.column_stack((centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)))


def test_features_of_a_circle_arc_and_a_line() -> None:
    circle = arc((2.0, 0.5), 0.07, 12)
    line = np.column_stack((np.full(10, 3.0), np.linspace(-1.0, -0.5, 10)))
    features = segment_features(np.vstack((circle, line)), np.array([0, 12]), BEAM)
    leg, wall = features[:, :].tolist()
    assert leg[COLUMN["radius"]] == pytest.approx(0.07, abs=1e-9)
    assert leg[COLUMN["circularity"]] == pytest.approx(0.0, abs=1e-9)
    assert leg[COLUMN["mean_curvature"]] == pytest.approx(1 / 0.07, rel=1e-6)  # three points on a circle: 1 / r
    assert leg[COLUMN["linearity"]] > 0.01
    assert wall[COLUMN["width"]] == pytest.approx(0.5)
    assert wall[COLUMN["boundary_length"]] == pytest.approx(0.5)
    assert wall[COLUMN["linearity"]] == pytest.approx(0.0, abs=1e-12)
    assert wall[COLUMN["radius"]] == MAX_RADIUS  # a straight line fits no finite circle
    assert wall[COLUMN["mean_curvature"]] == wall[COLUMN["sagitta"]] == 0.0
    assert wall[COLUMN["boundary_regularity"]] == pytest.approx(0.0, abs=1e-9)  # evenly spaced
    assert leg[COLUMN["neighbour_distance"]] == pytest.approx(np.hypot(*(circle.mean(0) - line.mean(0))))
    assert leg[COLUMN["distance"]] == pytest.approx(np.hypot(*circle.mean(0)))


def test_shape_features_are_computed_per_segment_regardless_of_their_neighbours() -> None:
    circle = arc((2.0, 0.5), 0.07, 12)
    alone = segment_features(circle, np.array([0]), BEAM)[0]
    together = segment_features(np.vstack((circle, circle + [0.0, 2.0])), np.array([0, 12]), BEAM)[0]
    shape = [COLUMN[n] for n in SHAPE_NAMES]
    assert together[shape] == pytest.approx(alone[shape])
    assert alone[[COLUMN[n] for n in ("neighbour_distance", "clearance")]].tolist() == [3.0, 3.0]  # nothing else: FAR
    assert alone[[COLUMN[n] for n in ("neighbour_width", "surface_near", "surface_around", "candidates_around")]].tolist() == [0] * 4
    assert alone[COLUMN["foreground"]] == 0.0  # nothing seen on either side: no step, not open space


def test_context_features_of_a_leg_between_two_walls() -> None:
    """A leg 2 m ahead seen between a far wall piece on its right and a nearer one on its left
    (beam order: right wall, leg, left wall), checked point by point against the definitions."""
    right = np.column_stack((np.full(10, 3.0), np.linspace(-1.0, -0.5, 10)))
    leg = arc((2.0, 0.0), 0.07, 12)[::-1]  # counter-clockwise, as the beams sweep
    left = np.column_stack((np.full(11, 2.5), np.linspace(0.3, 0.8, 11)))
    points = np.vstack((right, leg, left))
    rows = segment_features(points, np.array([0, 10, 22]), BEAM)
    context = {name: rows[:, COLUMN[name]] for name in CONTEXT_NAMES}
    centre = leg.mean(axis=0)
    others = np.vstack((right, left))
    to_others = np.hypot(*(others - centre).T)
    assert context["neighbour_distance"][1] == pytest.approx(min(np.hypot(*(right.mean(0) - centre)), np.hypot(*(left.mean(0) - centre))))
    assert context["neighbour_width"][1] == pytest.approx(0.5)  # the left wall piece is the nearer
    assert context["clearance"][1] == pytest.approx(to_others.min()) and 0.6 < to_others.min() < 0.7
    # Each point within 1 m stands for the surface its beam spans at its range.
    near_surface = (np.hypot(*others.T) * BEAM)[to_others < 1.0].sum()
    assert context["surface_near"][1] == 0 and context["surface_around"][1] == pytest.approx(near_surface) and near_surface > 0
    assert context["candidates_around"].tolist() == [0, 1, 1]  # the leg and the left wall piece are 0.78 m apart
    ranges = np.hypot(*points.T)
    before, after = ranges[9] - ranges[10], ranges[22] - ranges[21]  # both walls lie behind the leg
    assert context["foreground"][1] == pytest.approx(min(before, after)) and context["foreground"][1] > 0.4
    # The right wall's first point is the first of the scan: nothing is known beyond it (0), and
    # on its other side the leg stands in front of it (a negative step).
    assert context["foreground"][0] == pytest.approx(ranges[10] - ranges[9]) and context["foreground"][0] < -1.0



def test_labels_match_one_segment_each_and_ignore_their_surroundings() -> None:
    centroids = np.array([[2.0, 0.0], [2.05, 0.02], [2.3, 0.4], [4.0, -1.0], [1.0, 3.0]])
    labels = np.array([[2.04, 0.02], [0.98, 3.0]])
    leg, ignored = match_labels(centroids, labels, TrainingSettings(label_radius=0.1, ignore_radius=1.0))
    # One segment per label, the closer of the two at the first; its neighbour and the segment
    # 0.5 m away are ignored, the one 2.3 m away is a negative.
    assert leg.tolist() == [False, True, False, False, True]
    assert ignored.tolist() == [True, False, True, False, False]
    leg, ignored = match_labels(centroids, np.zeros((0, 2)), TrainingSettings())
    assert not leg.any() and not ignored.any()


def test_folds_by_log_hold_out_each_log_with_legs_and_deal_out_the_empty_ones() -> None:
    log = np.array([0, 0, 1, 1, 2, 2, 3, 3, 3, 3])  # two labelled logs, a standing one, one with nobody present
    block = np.array([0, 1, 2, 2, 3, 3, 4, 5, 6, 7])
    logs = [{"kind": "labelled"}, {"kind": "labelled"}, {"kind": "standing"}, {"kind": "nobody present"}]
    none = np.zeros(10, bool)
    data = LabelledSegments(features=np.zeros((10, 1)), is_leg=none, ignored=none, log=log, block=block, static=none,
                            logs=logs, augmented=none, centroids=np.zeros((10, 2)))
    assert (data.labelled_logs, data.logs_with_legs) == (2, 3)
    assert folds(data, "log").tolist() == [0, 0, 1, 1, 2, 2, 1, 2, 0, 1]
    by_time = folds(data, "time", TrainingSettings(folds=3))
    assert len(set(by_time.tolist())) == 3 and by_time[2] == by_time[3]  # a block is never split
    with pytest.raises(LogError, match="needs two labelled logs"):
        folds(replace(data, log=np.zeros(10, int), logs=logs[:1]), "log")


def test_static_flags_take_a_post_after_its_log_has_seen_it_and_never_a_walker() -> None:
    lidar = LidarSimulator(seed=4, posts=(np.array([[3.0, 1.0]]), np.array([0.06])))
    flags = StaticFlags(odometry=None)  # a standing laser: each scan in its own frame
    post_static, walker_static = [], []
    for k in range(40):  # 10 Hz: the post at (3, 1), a person walking along y = -1 at 1 m/s
        scan = lidar.scan(0.1 * k, Pose2D(), np.array([[1.5 + 0.1 * k, -1.0]]), np.array([[1.0, 0.0]]))
        segments, mask = candidates(scan, DetectorConfig())
        static = flags(scan, segments, mask)
        centroids = segments.centroids[mask]
        post = np.hypot(*(centroids - [3.0, 1.0]).T) < 0.2
        assert post.sum() == 1 and (centroids[~post, 1] < -0.5).all()  # the post and the walker's legs
        post_static.append(bool(static[post][0]))
        walker_static.extend(static[~post].tolist())
    # Static from scan 16 on, once the earlier scans 0-15 have hit its cells over 1.5 s; never before.
    assert post_static == [False] * 16 + [True] * 24
    assert walker_static and not any(walker_static)


def test_the_threshold_keeps_the_recall_through_the_static_world() -> None:
    probability = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1, 0.05, 0.95])
    is_leg = np.arange(11) < 10  # ten legs, and one other segment
    static = np.zeros(11, dtype=bool)
    assert stage_threshold(is_leg, probability, static, 0.8) == threshold_for_recall(is_leg, probability, 0.8) == 0.2
    static[1] = True  # the 0.8 leg is on the static world: the eighth leg kept is now the 0.1 one
    assert stage_threshold(is_leg, probability, static, 0.8) == 0.1
    static[[0, 2]] = True  # three of ten legs static: 0.8 cannot be kept, so every leg off it is
    assert stage_threshold(is_leg, probability, static, 0.8) == 0.05
    with pytest.raises(LogError, match="every labelled leg lies on its log's static world"):
        stage_threshold(is_leg, probability, is_leg, 0.8)


@pytest.fixture(scope="module")
def small_model():
    from sklearn.ensemble import HistGradientBoostingClassifier

    rng = np.random.default_rng(3)
    features = rng.normal(size=(400, len(FEATURE_NAMES)))
    labels = features[:, 0] + 0.5 * features[:, 3] ** 2 > 0.3
    model = HistGradientBoostingClassifier(max_iter=20, max_leaf_nodes=15, random_state=0).fit(features, labels)
    probe = rng.normal(size=(300, len(FEATURE_NAMES)))
    probe[::7, 0] = np.nan  # a missing value goes the way scikit-learn sends it
    return model, probe


def test_tree_arrays_predict_what_scikit_learn_predicts(small_model, tmp_path: Path) -> None:
    model, probe = small_model
    classifier = from_hist_gradient_boosting(model, (0.4, 0.5, 0.6), {"note": "test"})
    expected = model.predict_proba(probe)[:, 1]
    assert classifier.probability(probe) == pytest.approx(expected, abs=1e-9)
    classifier.save(tmp_path / "d.npz")
    loaded = LegClassifier.load(tmp_path / "d.npz")
    assert loaded.probability(probe) == pytest.approx(expected, abs=1e-9)
    assert (loaded.threshold, loaded.confirm, loaded.protect) == (0.4, 0.5, 0.6) and loaded.record == {"note": "test"}


def test_a_detector_of_another_format_is_one_error_line(small_model, tmp_path: Path, capsys, robot_logs_dir: Path) -> None:
    model, _ = small_model
    path = tmp_path / "old.npz"
    from_hist_gradient_boosting(model, (0.5, 0.6, 0.7), {}).save(path)
    with np.load(path) as stored:
        arrays = dict(stored)
    header = json.loads(str(arrays["header"]))
    arrays["header"] = np.array(json.dumps({**header, "format": FORMAT_VERSION + 1}))
    np.savez(path, **arrays)
    with pytest.raises(LogError) as refused:
        LegClassifier.load(path)
    assert str(refused.value) == (f"{path}: detector format {FORMAT_VERSION + 1}, but this version reads format "
                                  f"{FORMAT_VERSION}; retrain it with `trials log train-detector`")
    out = tmp_path / "tracks.csv"
    code = main(["log", "track", str(robot_logs_dir / "stationary_ros1.bag"), "--detector", str(path), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("error: ") and str(path) in err[0]
    assert not out.exists()
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(LogError, match="not a leg detector file"):
        LegClassifier.load(tmp_path / "junk.npz")


def test_the_shipped_detector_carries_its_training_record() -> None:
    detector = shipped_detector()
    record = detector.record
    assert record["format"] == FORMAT_VERSION and record["features"] == list(FEATURE_NAMES)
    files = {log["file"]: log for log in record["logs"]}
    assert set(files) == {"legs_labelled_ros1.bag", "negative_2.bag", "stationary_ros1.bag"} | {
        f"positive_{k}_extracted.bag" for k in (2, 3, 4, 6, 7)}
    assert sum(log["scans"] for log in record["logs"] if log["kind"] == "labelled") == 1204
    assert files["negative_2.bag"]["kind"] == "nobody present" and files["negative_2.bag"]["scans"] == 1304
    assert files["stationary_ros1.bag"]["kind"] == "standing" and files["stationary_ros1.bag"]["scans"] == 1265
    assert record["settings"]["seed"] == 0 and record["settings"]["augment"] and record["ignored"] > 0
    assert record["augmented_segments"] > record["segments"]  # three copies of the logs with legs
    assert set(record["protocol"]) == {"positives", "negatives", "ignored", "augmented", "threshold", "folds by log",
                                       "static world"}
    figures = record["cross_validation"]
    assert set(figures) == {f"{design}{scope}{stage}{rule}" for design in ("logs", "time blocks")
                            for scope in ("", ", labelled logs", ", standing logs") for stage in ("", ", static world")
                            for rule in ("", ", strict")}
    # The hand-labelled legs and those of the standing log make every leg; the recorded segments only are scored.
    labelled, standing = figures["logs, labelled logs"], figures["logs, standing logs"]
    assert labelled["legs"] == 1825 and labelled["legs"] + standing["legs"] == figures["logs"]["legs"] == record["legs"]
    assert figures["logs"]["segments"] == record["segments"] - record["ignored"] == figures["logs, strict"]["segments"] - record["ignored"]
    # The goal, leg precision 0.8 at recall 0.9 held out by bag over the labelled sample bags, for the detection
    # stage the tracker uses, under the protocol (measured 0.813). Strictly (0.750), which also counts the
    # segments near a label, it is missed (docs/leg_detector.md).
    goal = figures["logs, labelled logs, static world"]
    assert goal["precision"] >= 0.8 and goal["recall"] >= record["settings"]["recall"]
    assert figures["logs, labelled logs, static world, strict"]["precision"] > 0.74
    # Held out whole, the standing log is another laser in another place: what a new robot's log gets
    # (recall 0.671, measured); held out by time blocks, a laser and place trained on (0.986).
    assert figures["logs, standing logs, static world"]["recall"] > 0.6
    assert figures["time blocks, standing logs, static world"]["recall"] > 0.95
    for design in ("logs", "time blocks"):
        for stage in ("", ", static world"):  # the strict figure counts the ignored segments as negatives
            assert figures[f"{design}{stage}, strict"]["precision"] <= figures[f"{design}{stage}"]["precision"]
            assert figures[f"{design}{stage}, strict"]["recall"] == figures[f"{design}{stage}"]["recall"]
        # The static world only takes legs away: on these bags it drops some labelled legs too.
        assert figures[f"{design}, static world"]["recall"] < figures[design]["recall"]
        assert figures[f"{design}, static world"]["segments"] == figures[design]["segments"]
    assert 0.0 < detector.threshold < detector.confirm < detector.protect < 1.0
    assert (detector.threshold, detector.confirm, detector.protect) == (record["threshold"], record["confirm"], record["protect"])


def test_train_detector_refuses_a_log_without_labels(robot_logs_dir: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "detector.npz"
    code = main(["log", "train-detector", str(robot_logs_dir / "stationary_ros1.bag"), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith("error: ") and "stationary_ros1.bag has no PoseArray topic" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_train_detector_learns_legs_from_one_labelled_log(robot_logs_dir: Path, tmp_path: Path, capsys) -> None:
    from robot_logs.leg_training import TrainingSettings, collect, held_out_probability, scores

    data = collect([robot_logs_dir / "legs_labelled_ros1.bag"])
    assert int(data.is_leg[~data.augmented].sum()) == 317  # 317 of the 324 labelled legs lie on a segment centroid
    assert data.augmented.any() and (data.log == 0).all()
    settings = TrainingSettings(trees=30, folds=3)
    probability = held_out_probability(data, "time", settings)
    recorded = ~data.augmented  # the copies are trained on, never scored
    score = scores(data.is_leg[recorded], probability[recorded], 0.5)
    assert score.precision > 0.5 and score.recall > 0.3  # far better than the 0.06 share of legs by chance


def test_train_detector_help_states_the_model_defaults_of_the_training_settings(capsys) -> None:
    assert main(["log", "train-detector", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    settings = TrainingSettings()
    assert not settings.balanced and "(default: no class weights)" in text
    for option, value in (("--trees TREES", settings.trees), ("--leaves LEAVES", settings.leaves),
                          ("--min-leaf N", settings.min_leaf), ("--l2 L2", f"{settings.l2:g}")):
        assert f"{option} " in text and f"(default {value})" in text.rsplit(option, 1)[1].split("--", 1)[0]  # the option list, after the usage line


def test_the_tree_walk_follows_splits_and_missing_values_and_stops_at_the_depth() -> None:
    """Two hand-made stumps on features 0 and 1 (leaves are their own children), and a damaged
    tree whose nodes point at each other: the walk sums the right leaves and ends after `depth` steps."""
    from robot_logs.tree_walk import log_odds

    #            node: 0 (x0 <= 0.5?)  1 leaf  2 leaf  3 (x1 <= 0, missing right)  4 leaf  5 leaf  6 -> 7 -> 6 ...
    feature = np.array([0, 0, 0, 1, 0, 0, 0, 0], dtype=np.int32)
    split = np.array([0.5, 0, 0, 0.0, 0, 0, 0, 0])
    left = np.array([1, 1, 2, 4, 4, 5, 7, 6], dtype=np.int32)
    right = np.array([2, 1, 2, 5, 4, 5, 7, 6], dtype=np.int32)
    missing_left = np.array([True, False, False, False, False, False, False, False])
    value = np.array([0, -1.0, 1.0, 0, 10.0, 20.0, 100.0, 200.0])
    features = np.array([[0.2, -1.0], [0.9, 1.0], [np.nan, np.nan]])
    stumps = log_odds(features, feature, split, left, right, missing_left, value, np.array([0, 3], dtype=np.int32), 1, 0.5)
    np.testing.assert_array_equal(stumps, [0.5 - 1 + 10, 0.5 + 1 + 20, 0.5 - 1 + 20])
    looped = log_odds(features[:1], feature, split, left, right, missing_left, value, np.array([6], dtype=np.int32), 3, 0.0)
    assert looped.tolist() == [200.0]  # 6 -> 7 -> 6 -> 7, three steps, then stopped


def leg_scan(behind: float) -> Scan:
    """A 90-degree scan at 0.25 degrees of a leg (radius 0.07 m) 2 m ahead; every other beam reads
    `behind` (m): a wall's range, or what the laser writes for a beam without a return."""
    angles = np.arange(-math.pi / 4, math.pi / 4, BEAM)
    # Where each beam meets the circle about (2, 0): the nearer root of |t u - c|^2 = r^2.
    along = 2.0 * np.cos(angles)
    across = 4.0 - along**2
    hits = across <= 0.07**2
    ranges = np.where(hits, along - np.sqrt(np.clip(0.07**2 - across, 0.0, None)), behind)
    return Scan(0, "laser", float(angles[0]), BEAM, 0.03, 5.6, ranges)


def test_a_leg_before_beams_without_return_stands_free_however_the_laser_writes_them() -> None:
    """A laser writes a beam that saw nothing as inf, NaN, 0 (below its range_min) or beyond its
    range_max; each is open space behind the leg, as is a wall farther than STANDS_FREE."""
    def leg_row(behind: float) -> np.ndarray:
        segments = segment(leg_scan(behind), DetectorConfig().jump_distance)
        leg = np.flatnonzero(np.abs(segments.centroids[:, 1]) < 0.1)
        return segments.features(np.isin(np.arange(len(segments.starts)), leg))[0]

    open_space = leg_row(np.inf)
    assert open_space[COLUMN["foreground"]] == STANDS_FREE
    for written in (np.nan, 0.0, 0.01, 7.0):
        np.testing.assert_array_equal(leg_row(written), open_space)
    assert leg_row(3.5)[COLUMN["foreground"]] == STANDS_FREE  # a wall 1.5 m behind
    # A wall 0.4 m behind the leg's front: its edge beams (about 2.0 m) stand about 0.34 m before it.
    near_wall = leg_row(2.33)
    assert 0.3 < near_wall[COLUMN["foreground"]] < 0.4
    assert near_wall[COLUMN["clearance"]] < 0.5 < open_space[COLUMN["clearance"]]


def test_open_beams_wrap_around_a_full_circle_but_not_past_a_field_of_view() -> None:
    ranges = np.array([np.inf, 2.0, 2.0, 0.0, 2.0])  # beams 0 and 3 return nothing
    circle = Scan(0, "laser", 0.0, 2.0 * math.pi / 5, 0.03, 5.6, ranges)
    assert open_beams(circle).tolist() == [[True, False], [False, True], [True, True]]  # beams 1, 2 and 4
    partial = replace(circle, angle_increment=BEAM)
    assert open_beams(partial).tolist() == [[True, False], [False, True], [True, False]]  # nothing after the last beam


def test_surface_around_a_segment_does_not_depend_on_the_beams() -> None:
    """A wall 0.6 m beside a leg, seen by a laser and by one of half its resolution: the same surface."""
    leg = arc((2.0, 0.0), 0.07, 12)
    wall_bearings = np.arange(0.3, 0.55, BEAM)
    wall = np.column_stack((np.full(len(wall_bearings), 2.2), 2.2 * np.tan(wall_bearings)))
    fine = segment_features(np.vstack((leg, wall)), np.array([0, 12]), BEAM)[0]
    coarse = segment_features(np.vstack((leg, wall[::2])), np.array([0, 12]), 2 * BEAM)[0]
    for name in ("surface_near", "surface_around"):
        assert coarse[COLUMN[name]] == pytest.approx(fine[COLUMN[name]], rel=0.1)
    assert fine[COLUMN["surface_around"]] > 0.2  # part of the wall's 0.67 m lies within 1 m of the leg


def test_augmented_scans_are_another_laser_seeing_the_same_room() -> None:
    from robot_logs.leg_training import half_beams, lost_beams

    scan = LidarSimulator(seed=2, walls=np.array([[[3.0, -5.0], [3.0, 5.0]]])).scan(0.0, Pose2D(), np.zeros((0, 2)))
    rng = np.random.default_rng(0)
    half = half_beams(scan, rng)
    assert half.angle_increment == 2 * scan.angle_increment and len(half.ranges) in (len(scan.ranges) // 2, len(scan.ranges) // 2 + 1)
    start = round((half.angle_min - scan.angle_min) / scan.angle_increment)
    assert half.ranges.tolist() == scan.ranges[start::2].tolist()  # the same beams, every other one
    lost = lost_beams(scan, rng)
    changed = lost.ranges != scan.ranges
    assert np.isinf(lost.ranges[changed]).all() and 0.02 < changed.mean() < 0.2


def test_the_copy_taken_for_twice_as_far_differs_from_the_half_beams_copy_in_distance_alone() -> None:
    """The same scans and draws: every feature of every segment equal, the distance doubled."""
    from robot_logs.leg_training import AUGMENTATIONS, DISTANCE

    lidar = LidarSimulator(seed=3, walls=np.array([[[4.0, -3.0], [4.0, 3.0]]]), posts=(np.array([[2.5, 1.0]]), np.array([0.05])))
    scans = [lidar.scan(0.1 * k, Pose2D(), np.array([[2.0, -0.5 + 0.1 * k]]), np.array([[0.0, 1.0]])) for k in range(5)]

    def nobody(scan, segments, mask):
        return np.zeros(int(mask.sum()), dtype=bool), np.zeros(int(mask.sum()), dtype=bool)

    half, far = (np.vstack(AUGMENTATIONS[name].gather(scans, nobody, DetectorConfig(), np.random.default_rng(7)).features)
                 for name in ("half beams", "half beams, twice as far"))
    assert len(half) >= 10 and half.shape == far.shape
    np.testing.assert_array_equal(far[:, DISTANCE], 2.0 * half[:, DISTANCE])
    others = np.arange(half.shape[1]) != DISTANCE
    np.testing.assert_array_equal(far[:, others], half[:, others])


def test_background_labels_take_the_passer_by_for_legs_and_the_room_for_the_room() -> None:
    """A standing laser before a wall 4 m away and three leg-sized posts while one person walks across
    2 m ahead for 2 s of 20."""
    from robot_logs.background_labels import Background, background_labels
    from robot_logs.lidar_sim import BodyModel, LidarSpec

    posts = (np.array([[3.0, 2.0], [3.0, -2.5], [2.5, 3.0]]), np.full(3, 0.06))  # leg-sized, part of the room
    lidar = LidarSimulator(LidarSpec.fitted(), BodyModel.fitted(), seed=3, walls=np.array([[[4.0, -6.0], [4.0, 6.0]]]),
                           posts=posts)
    scans = [lidar.scan(0.1 * k, Pose2D(), np.array([[2.0, -1.0 + 0.1 * (k - 180)]]), np.array([[0.0, 1.0]]))
             if k >= 180 else lidar.scan(0.1 * k, Pose2D(), np.zeros((0, 2))) for k in range(200)]
    background = Background.of(scans, "test")
    empty = scans[0].valid()
    assert background.ranges[empty] == pytest.approx(scans[0].ranges[empty], abs=0.02)  # the wall, not the walker
    assert np.isinf(background.ranges[~empty]).all()
    legs, person, room = 0, 0, 0
    for k, scan in enumerate(scans):
        segments, mask = candidates(scan, DetectorConfig())
        leg, ignored = background_labels(background, segments, mask, DetectorConfig().leg_width)
        centroids = segments.centroids[mask]
        at_person = np.hypot(*(centroids - [2.0, -1.0 + 0.1 * (k - 180)]).T) < 0.5 if k >= 180 else np.zeros(len(leg), bool)
        assert not (leg & ~at_person).any() and not (ignored & ~at_person).any()  # the room is never a leg
        legs, person, room = legs + int(leg.sum()), person + int(at_person.sum()), room + int((~at_person).sum())
    assert legs >= 0.9 * person and person >= 30 and room >= 3 * 200


@pytest.mark.slow
def test_a_standing_log_is_a_fold_of_its_own_with_legs_from_its_background(robot_logs_dir: Path) -> None:
    from robot_logs.leg_training import collect

    settings = TrainingSettings(scan_odometry=False, augment=False)
    data = collect([robot_logs_dir / "legs_labelled_ros1.bag"], settings=settings,
                   standing=[robot_logs_dir / "stationary_ros1.bag"])
    assert [log["kind"] for log in data.logs] == ["labelled", "standing"] and data.logs_with_legs == 2
    standing = data.log == 1
    # People walked loops before the standing laser: thousands of leg segments in front of the background
    # (3,946 measured), and the room's own segments as negatives.
    assert 3000 < int(data.is_leg[standing].sum()) < 5000
    assert int((standing & ~data.is_leg & ~data.ignored).sum()) > 1000
    assert not data.augmented.any()


def test_the_background_of_a_full_circle_wraps_and_bearings_past_a_partial_scan_take_its_nearer_end() -> None:
    from robot_logs.background_labels import Background

    step = 2 * math.pi / 360
    ranges = np.full(360, 5.0)
    ranges[270] = 1.0  # a post at 270 degrees (bearing -90 degrees) of a laser sweeping 0 to 360 degrees
    circle = Background(0.0, step, ranges)
    bearings = np.radians([-90.0, -90.0, 10.0, 359.8])
    distances = np.array([1.0, 0.5, 4.0, 4.8])
    points = np.column_stack((distances * np.cos(bearings), distances * np.sin(bearings)))
    assert circle.in_front(points).tolist() == [False, True, True, False]  # 359.8 degrees is beam 0: 4.8 m is on it
    half = Background(-math.pi / 2, step, np.r_[1.0, np.full(180, 5.0)])  # -90 to +90 degrees, beam 0 at 1 m
    beyond = np.radians([-90.2, -90.2, 90.2])
    reach = np.array([0.9, 0.6, 0.9])
    points = np.column_stack((reach * np.cos(beyond), reach * np.sin(beyond)))
    assert half.in_front(points).tolist() == [False, True, True]  # -90.2 is beam 0's, +90.2 the last beam's


def test_a_standing_log_that_moves_or_changes_laser_is_refused_in_one_line() -> None:
    from robot_logs.background_labels import Background

    rng = np.random.default_rng(5)
    scan = LidarSimulator(seed=5).scan(0.0, Pose2D(), np.zeros((0, 2)))
    driving = [replace(scan, ranges=rng.uniform(1.0, 8.0, len(scan.ranges))) for _ in range(50)]
    with pytest.raises(LogError, match=r"drive.bag: in the median scan only \d+% of the beams see their background"):
        Background.of(driving, "drive.bag")
    other = replace(scan, ranges=scan.ranges[:-1])
    with pytest.raises(LogError, match="scan 1 has 1080 beams .* the first 1081"):
        Background.of([scan, other], "two.bag")
    with pytest.raises(LogError, match="none.bag: no scan"):
        Background.of([], "none.bag")


@pytest.mark.slow
def test_train_detector_refuses_a_standing_log_that_moved_or_saw_nobody_in_one_line(
        robot_logs_dir: Path, tmp_path: Path, capsys) -> None:
    from robot_logs.clutter import furnished_room
    from tests.support.bag_writer import BagWriter

    room = furnished_room(6)
    lidar = LidarSimulator(seed=6, walls=room.walls, posts=(room.centres, room.radii))
    logs = {"driving.bag": lambda k: Pose2D(1.0 + 0.1 * k, 0.5 * math.sin(0.2 * k), 0.15 * k), "standing.bag": lambda k: Pose2D(1.0, 0.0, 0.0)}
    for name, pose in logs.items():  # 3 s of an empty furnished room, the laser driving and turning, or standing
        with BagWriter(tmp_path / name) as bag:
            for k in range(30):
                bag.scan(replace(lidar.scan(0.1 * k, pose(k), np.zeros((0, 2))), stamp_ns=1_000_000_000 + 100_000_000 * k))
    out = tmp_path / "detector.npz"
    fast = ["--no-scan-odometry", "--no-augment", "--out", str(out)]
    labelled = str(robot_logs_dir / "legs_labelled_ros1.bag")
    for name, message in (("driving.bag", "of the beams see their background (a laser standing still sees at least 50%)"),
                          ("standing.bag", "no leg-wide segment stands in front of the background")):
        code = main(["log", "train-detector", labelled, "--standing", str(tmp_path / name), *fast])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith(f"error: {tmp_path / name}: ") and message in err[0], err
        assert not out.exists()
