"""CLEAR-MOT by Leigh et al.'s protocol: counts on a hand-made sequence with a known id switch,
checked against motmetrics, and `trials log score-tracks` on a bag with labelled people."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg

from robot_logs.clear_mot import Identities, ScoredScan, clear_mot
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.records import PointSet
from robot_logs.tracks import TrackRow, TrackTable
from tests.support.bag_writer import BagWriter
from trials.cli import main

#: leg_tracker's label messages as its msg/ folder defines them, registered with rosbags to write test bags.
LEG_TRACKER_MSGS = {
    "leg_tracker/msg/Person": "geometry_msgs/Pose pose\nuint32 id\n",
    "leg_tracker/msg/PersonArray": "std_msgs/Header header\nPerson[] people\n",
}


def scan(people: dict[int, tuple[float, float]], tracks: dict[int, tuple[float, float]]) -> ScoredScan:
    return ScoredScan(
        np.array(list(people), dtype=int), np.array(list(people.values()), dtype=float).reshape(-1, 2),
        np.array(list(tracks), dtype=int), np.array(list(tracks.values()), dtype=float).reshape(-1, 2),
    )


#: Person 1 walks along y = 0, person 2 stands at (3, 2). Track 10 follows person 1 until it is
#: lost at scan 3 and track 11 takes over (one switch); track 20 sits on person 2 but is 0.9 m
#: off at scan 2 (a miss and a false positive); track 30 is clutter at scan 4.
SEQUENCE = [
    scan({1: (1.0, 0.0), 2: (3.0, 2.0)}, {10: (1.1, 0.0), 20: (3.0, 2.1)}),
    scan({1: (1.5, 0.0), 2: (3.0, 2.0)}, {10: (1.5, 0.2), 20: (3.0, 2.0)}),
    scan({1: (2.0, 0.0), 2: (3.0, 2.0)}, {10: (2.0, 0.1), 20: (3.9, 2.0)}),
    scan({1: (2.5, 0.0), 2: (3.0, 2.0)}, {11: (2.5, 0.3), 20: (3.0, 2.0)}),
    scan({1: (3.0, 0.0), 2: (3.0, 2.0)}, {11: (3.0, 0.0), 20: (3.0, 2.0), 30: (5.0, -1.0)}),
]



def test_people_labelled_without_ids_keep_theirs_from_scan_to_scan() -> None:
    """Two walkers whose labels (legs paired by position) come in either order, each followed by
    its own track: numbered by position they seem to swap tracks; `Identities` numbers them by
    continuity, so only a real swap of tracks counts."""
    walkers = [np.array([[1.0 + 0.1 * k, 0.0], [1.0 + 0.1 * k, 2.0]]) for k in range(6)]
    listed = [people[::-1] if k % 2 else people for k, people in enumerate(walkers)]
    tracks = np.array([10, 20])

    def scored(ids_of, swap_at: int | None = None) -> list[ScoredScan]:
        scans = []
        for k, (people, truth) in enumerate(zip(listed, walkers)):
            ids = tracks[::-1] if swap_at is not None and k >= swap_at else tracks
            scans.append(ScoredScan(ids_of(people), people, ids, truth + [0.05, 0.0]))
        return scans

    assert clear_mot(scored(lambda people: np.arange(len(people)))).id_switches == 10  # both, at each of 5 reorderings
    continuity = clear_mot(scored(Identities()))
    assert (continuity.id_switches, continuity.matches, continuity.misses) == (0, 12, 0)
    assert clear_mot(scored(Identities(), swap_at=3)).id_switches == 2
    # One walker steps 0.6 m between scans, beyond the 0.5 m reach: a new person, and the other keeps its id.
    ids = Identities()
    assert ids(np.array([[0.0, 0.0], [0.0, 2.0]])).tolist() == [0, 1]
    assert ids(np.array([[0.0, 2.1], [0.6, 0.0]])).tolist() == [1, 2]

def test_counts_on_a_hand_made_sequence_with_a_known_switch() -> None:
    score = clear_mot(SEQUENCE)
    assert (score.objects, score.matches, score.misses, score.false_positives, score.id_switches) == (10, 9, 1, 2, 1)
    assert score.mota == pytest.approx(1.0 - 4 / 10)
    distances = [0.1, 0.1, 0.2, 0.0, 0.1, 0.3, 0.0, 0.0, 0.0]
    assert score.motp == pytest.approx(sum(distances) / 9)


def test_counts_agree_with_motmetrics() -> None:
    import motmetrics

    accumulator = motmetrics.MOTAccumulator(auto_id=True)
    for s in SEQUENCE:
        accumulator.update(s.person_ids.tolist(), s.track_ids.tolist(),
                           motmetrics.distances.norm2squared_matrix(s.people, s.tracks, max_d2=0.75**2) ** 0.5)
    row = motmetrics.metrics.create().compute(
        accumulator, metrics=["num_misses", "num_false_positives", "num_switches", "mota"], name="x").iloc[0]
    score = clear_mot(SEQUENCE)
    assert (score.misses, score.false_positives, score.id_switches) == (
        row["num_misses"], row["num_false_positives"], row["num_switches"])
    assert score.mota == pytest.approx(row["mota"])


def test_a_match_carried_over_holds_against_a_closer_newcomer() -> None:
    """Track 1 matched the person before; track 2 now sits closer, yet the match stays (no switch)."""
    score = clear_mot([scan({1: (2.0, 0.0)}, {1: (2.3, 0.0)}), scan({1: (2.0, 0.0)}, {1: (2.5, 0.0), 2: (2.05, 0.0)})])
    assert (score.id_switches, score.false_positives, score.matches) == (0, 1, 2)
    assert score.motp == pytest.approx(0.4)


@pytest.fixture(scope="module")
def labelled_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six scans of a stationary sensor; the people (PoseArray, scan frame) labelled at scans 1-4."""
    path = tmp_path_factory.mktemp("scored") / "labelled.bag"
    lidar = LidarSimulator(seed=0)
    with BagWriter(path, "ros1") as bag:
        for k in range(6):
            stamp = 1_000_000_000 + k * 100_000_000
            bag.scan(lidar.scan(stamp * 1e-9, Pose2D(), np.zeros((0, 2))))
            if 1 <= k <= 4:
                people = np.array([[2.0 + 0.1 * k, 0.0], [3.0, -2.0]])
                bag.points(PointSet(stamp, stamp + 1, "laser", people), "/people")
    return path


def test_score_tracks_prints_mota_over_all_and_labelled_scans(labelled_bag: Path, tmp_path: Path, capsys) -> None:
    rows = [TrackRow(1_000_000_000 + k * 100_000_000, k, 1, 2.0 + 0.1 * k, 0.05, 0.0, 0.0, "laser") for k in range(6)]
    rows.append(TrackRow(1_500_000_000, 5, 2, 6.0, 1.0, 0.0, 0.0, "laser"))
    TrackTable(rows).write_csv(tmp_path / "tracks.csv")
    assert main(["log", "score-tracks", str(labelled_bag), str(tmp_path / "tracks.csv")]) == 0
    everything, labelled = capsys.readouterr().out.strip().splitlines()
    # 8 labelled person-scans: person 0 matched 4 times, person 1 missed 4 times; scans 0 and 5 hold
    # nobody, so tracks there are false positives (1 at scan 0, 2 at scan 5).
    assert everything.startswith("all scans (6 scans, 8 labelled person-scans): MOTA 0.125, MOTP 0.050 m")
    assert "misses 4, false positives 3, id switches 0" in everything
    assert labelled.startswith("labelled scans (4 scans, 8 labelled person-scans): MOTA 0.500")
    assert main(["log", "score-tracks", str(labelled_bag), str(tmp_path / "tracks.csv"), "--window", "-10", "10"]) == 0
    windowed = capsys.readouterr().out.splitlines()[1]
    assert "(4 scans, 4 labelled person-scans): MOTA 1.000" in windowed  # person 1 at -34 degrees is left out


def test_score_tracks_refuses_tracks_in_another_frame(labelled_bag: Path, tmp_path: Path, capsys) -> None:
    TrackTable([TrackRow(1_000_000_000, 0, 1, 2.0, 0.0, 0.0, 0.0, "odom")]).write_csv(tmp_path / "odom.csv")
    assert main(["log", "score-tracks", str(labelled_bag), str(tmp_path / "odom.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the tracks are in frame odom but the labels" in err[0] and "in laser" in err[0]


def test_unstamped_labels_go_with_the_scan_recorded_nearest(tmp_path: Path, capsys) -> None:
    """Labels with zero stamps, recorded a year after the scans' header stamps (as the sample bag)."""
    year = 365 * 86400 * 1_000_000_000
    lidar = LidarSimulator(seed=0)
    path = tmp_path / "unstamped.bag"
    with BagWriter(path, "ros1") as bag:
        for k in range(3):
            stamp = 1_000_000_000 + k * 100_000_000
            bag.scan(lidar.scan(stamp * 1e-9, Pose2D(), np.zeros((0, 2))), record_ns=stamp + year)
            bag.points(PointSet(0, stamp + year + 1000, "laser", np.array([[2.0, 0.0]])), "/people")
    rows = [TrackRow(1_000_000_000 + k * 100_000_000, k, 7, 2.1, 0.0, 0.0, 0.0, "laser") for k in range(3)]
    TrackTable(rows).write_csv(tmp_path / "tracks.csv")
    assert main(["log", "score-tracks", str(path), str(tmp_path / "tracks.csv")]) == 0
    assert capsys.readouterr().out.startswith("all scans (3 scans, 3 labelled person-scans): MOTA 1.000, MOTP 0.100 m")


def test_a_track_on_a_hidden_person_is_no_false_positive() -> None:
    visible = np.array([[1.0, 0.0]])
    tracks = np.array([[1.1, 0.0], [4.0, 1.2], [6.0, 0.0]])
    hidden = np.array([[4.0, 1.0]])  # behind someone: no label, but there
    excused = clear_mot([ScoredScan(np.array([1]), visible, np.array([10, 11, 12]), tracks, hidden)], radius=0.5)
    assert (excused.objects, excused.matches, excused.misses, excused.false_positives) == (1, 1, 0, 1)
    counted = clear_mot([ScoredScan(np.array([1]), visible, np.array([10, 11, 12]), tracks)], radius=0.5)
    assert counted.false_positives == 2
    far = clear_mot([ScoredScan(np.array([1]), visible, np.array([10, 11, 12]), tracks, hidden + [0.0, 0.8])], radius=0.5)
    assert far.false_positives == 2  # a hidden person excuses only a track within the match radius


def _person_bag(path: Path, person_type: str = "leg_tracker/msg/Person") -> None:
    """Five scans at 10 Hz; after each, one leg_tracker Person message per labelled person
    (unstamped, as in Leigh et al.'s benchmark): person 4 walks at (2 + 0.1 k, 0) in scans 0-4,
    person 9 stands at (3, -1) in scans 2-3. Registered from the msg text with rosbags."""
    lidar = LidarSimulator(seed=0)
    with BagWriter(path, "ros1") as bag:
        bag.store.register({name: parsed for name, text in LEG_TRACKER_MSGS.items()
                            for parsed in get_types_from_msg(text, name).values()})
        person, pose, point = (bag.store.types[name] for name in
                               ("leg_tracker/msg/Person", "geometry_msgs/msg/Pose", "geometry_msgs/msg/Point"))
        quaternion = bag.store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
        for k in range(5):
            stamp = 1_000_000_000 + k * 100_000_000
            bag.scan(lidar.scan(stamp * 1e-9, Pose2D(), np.zeros((0, 2))))
            people = {4: (2.0 + 0.1 * k, 0.0)} | ({9: (3.0, -1.0)} if k in (2, 3) else {})
            for offset, (ident, (x, y)) in enumerate(people.items()):
                message = person(pose=pose(position=point(x=x, y=y, z=0.0), orientation=quaternion), id=ident)
                bag.write("/ground_truth_people_tracks", person_type, message, stamp + 2_000_000 + offset)


def test_score_tracks_reads_one_leg_tracker_person_message_per_person(tmp_path: Path, capsys) -> None:
    path = tmp_path / "benchmark_format.bag"
    _person_bag(path)
    rows = [TrackRow(1_000_000_000 + k * 100_000_000, k, 1, 2.0 + 0.1 * k, 0.1, 0.0, 0.0, "laser") for k in range(5)]
    rows.append(TrackRow(1_300_000_000, 3, 2, 3.0, -0.8, 0.0, 0.0, "laser"))
    TrackTable(rows).write_csv(tmp_path / "tracks.csv")
    command = ["log", "score-tracks", str(path), str(tmp_path / "tracks.csv"), "--gt-topic", "/ground_truth_people_tracks"]
    assert main(command) == 0
    everything = capsys.readouterr().out.splitlines()[0]
    # 7 person-scans (person 4 in five scans, person 9 in two); person 9 is matched at scan 3 only;
    # matches 0.1 m off five times and 0.2 m once: MOTP 0.7 / 6.
    assert everything.startswith("all scans (5 scans, 7 labelled person-scans): MOTA 0.857, MOTP 0.117 m")
    assert "misses 1, false positives 0, id switches 0" in everything


def test_score_tracks_refuses_a_label_type_it_cannot_read_in_one_line(tmp_path: Path, capsys) -> None:
    path = tmp_path / "odd_labels.bag"
    lidar = LidarSimulator(seed=0)
    with BagWriter(path, "ros1") as bag:
        bag.scan(lidar.scan(1.0, Pose2D(), np.zeros((0, 2))))
        bag.write("/ground_truth_people_tracks", "geometry_msgs/msg/Point", bag.store.types["geometry_msgs/msg/Point"](
            x=1.0, y=0.0, z=0.0), 1_000_000_001)
    TrackTable([TrackRow(1_000_000_000, 0, 1, 2.0, 0.0, 0.0, 0.0, "laser")]).write_csv(tmp_path / "tracks.csv")
    command = ["log", "score-tracks", str(path), str(tmp_path / "tracks.csv"), "--gt-topic", "/ground_truth_people_tracks"]
    assert main(command) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds geometry_msgs/msg/Point; score-tracks reads leg_tracker/Person" in err[0]
    assert main(command[:4]) == 2  # without --gt-topic: no label topic at all
    assert "has no label topics" in capsys.readouterr().err
