"""ROS map_server maps as the static world: reading map.yaml and its image as map_server does, a post on
an occupied cell rejected from the first scan beside a walker who is tracked (in `trials log track` and
in logged trials), the map placed through the log's map -> odom transform, and one-line errors for maps
that cannot be used."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from robot_logs.errors import LogError
from robot_logs.frames import Pose2D
from robot_logs.lidar_sim import LidarSimulator
from robot_logs.log_tracking import track_log
from robot_logs.occupancy_map import read_map
from robot_logs.pipeline import PersonTracker
from robot_logs.records import Odometry, Transform
from robot_logs.static_world import StaticWorldConfig
from robot_logs.tracking import TrackerConfig
from robot_logs.tracks import TrackTable
from tests.support.bag_writer import BagWriter
from tests.support.leg_classifiers import constant
from trials.cli import main
from trials.log_trial import ReplayOptions, prepare

#: The post in the odometry frame, and the localiser's map -> odom transform the bag records.
POST = (3.0, 1.0)
MAP_TO_ODOM = Pose2D(5.0, -2.0, math.pi / 2)
#: The map: 0.05 m cells, 80 x 80 pixels from (2, -1) in the map frame; the post lies at map (4, 1).
RESOLUTION, SIDE, ORIGIN = 0.05, 80, (2.0, -1.0)


def write_pgm(path: Path, pixels: np.ndarray) -> None:
    """A binary PGM (P5) of 8-bit grey values, top row first, as map_server's map_saver writes."""
    rows, columns = pixels.shape
    path.write_bytes(f"P5\n{columns} {rows}\n255\n".encode() + pixels.astype(np.uint8).tobytes())


def write_map(folder: Path, pixels: np.ndarray, **fields: object) -> Path:
    """map.yaml beside map.pgm; `fields` override or add to the usual ones."""
    write_pgm(folder / "map.pgm", pixels)
    values = {"image": "map.pgm", "resolution": RESOLUTION, "origin": [*ORIGIN, 0.0], "negate": 0,
              "occupied_thresh": 0.65, "free_thresh": 0.196} | fields
    path = folder / "map.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in values.items()))
    return path


def post_map(folder: Path) -> Path:
    """A white map, grey unknown at its left edge, with the post's 0.25 m square black."""
    pixels = np.full((SIDE, SIDE), 254)
    pixels[:, :10] = 205
    column, row = int((4.0 - ORIGIN[0]) / RESOLUTION), int((1.0 - ORIGIN[1]) / RESOLUTION)  # cells from the bottom left
    pixels[SIDE - 1 - (row + 2): SIDE - 1 - (row - 3), column - 2: column + 3] = 0
    return write_map(folder, pixels)


def lane_map(folder: Path) -> Path:
    """A map whose only black cells cover the walker's lane (odom y = -1, map x = 6 under MAP_TO_ODOM) for
    8 m: whatever the detector makes of the walker, the map says nobody can stand there."""
    pixels = np.full((160, 40), 254)
    pixels[:, 14:26] = 0  # map x 5.7 to 6.3
    return write_map(folder, pixels, origin="[5.0, -1.0, 0.0]")


def test_cells_are_read_as_map_server_reads_them(tmp_path: Path) -> None:
    pixels = np.array([[0, 100, 120], [254, 205, 80]])  # occupancies 1, 0.61, 0.53; 0, 0.2, 0.69
    occupancy = read_map(write_map(tmp_path, pixels, origin="[1.0, 2.0, 0.0]", resolution=0.5))
    assert occupancy.frame == "map" and occupancy.resolution == 0.5
    assert occupancy.occupied.tolist() == [[False, False, True], [True, False, False]]  # bottom row first
    centres = [(1.25, 2.75), (1.75, 2.75), (2.25, 2.75), (1.25, 2.25), (1.75, 2.25), (2.25, 2.25), (0.9, 2.2), (1.2, 3.1)]
    assert occupancy.is_occupied(np.array(centres)).tolist() == [True, False, False, False, False, True, False, False]
    lower = read_map(write_map(tmp_path, pixels, occupied_thresh=0.55, free_thresh=0.1))
    assert lower.occupied.tolist() == [[False, False, True], [True, True, False]]
    negated = read_map(write_map(tmp_path, pixels, negate=1))  # occupancy v / 255: white is occupied
    assert negated.occupied.tolist() == [[True, True, False], [False, False, False]]
    raw = read_map(write_map(tmp_path, np.array([[66, 65, 100, 255]]), mode="raw"))  # percent; 255 unknown
    assert raw.occupied.tolist() == [[True, False, True, False]]


def test_the_origin_turns_by_its_yaw_and_colour_images_are_averaged(tmp_path: Path) -> None:
    colour = np.zeros((1, 2, 3), dtype=np.uint8)
    colour[0, 0] = (0, 0, 255)  # mean 85: occupancy 0.67
    colour[0, 1] = (255, 255, 0)  # mean 170: occupancy 0.33
    Image.fromarray(colour).save(tmp_path / "map.png")
    path = tmp_path / "map.yaml"
    path.write_text("image: map.png\nresolution: 1.0\norigin: [10.0, 0.0, 1.5707963267948966]\n")
    occupancy = read_map(path, frame="world")
    assert occupancy.frame == "world" and occupancy.occupied.tolist() == [[True, False]]
    # the image's x axis points along the map's y: cell (0, 0) spans y 10.0 to 11.0 ... x 9.0 to 10.0
    assert occupancy.is_occupied(np.array([[9.5, 0.5], [9.5, 1.5], [10.5, 0.5]])).tolist() == [True, False, False]



def tracker() -> PersonTracker:
    return PersonTracker(tracker=TrackerConfig(confirm_confidence=0.5), classifier=constant(0.6),
                         static_world=StaticWorldConfig())


def write_bag(path: Path, localised_from: int = 0) -> Path:
    """6 s at 10 Hz: a robot creeping forward, a 6 cm post at odom (3, 1), a person walking along y = -1
    at 1 m/s, and a localiser's map -> odom transform on /tf with every scan from scan `localised_from` on."""
    lidar = LidarSimulator(seed=4, posts=(np.array([POST]), np.array([0.06])))
    with BagWriter(path) as bag:
        bag.transforms([Transform(1_000_000_000, "base_link", "laser", Pose2D(), True)], "/tf_static")
        for k in range(60):
            t = 1.0 + 0.1 * k
            stamp = int(round(t * 1e9))
            base = Pose2D(0.05 * k * 0.1, 0.0, 0.0)
            bag.odometry(Odometry(stamp, "odom", "base_link", base, 0.05, 0.0))
            if k >= localised_from:
                bag.transforms([Transform(stamp, "map", "odom", MAP_TO_ODOM, False)])
            bag.scan(lidar.scan(t, base, np.array([[1.5 + 0.1 * k, -1.0]]), np.array([[1.0, 0.0]])))
    return path


@pytest.fixture(scope="module")
def post_and_walker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_bag(tmp_path_factory.mktemp("mapped") / "post.bag")


def near(table: TrackTable, point: tuple[float, float]) -> set[int]:
    """The scan indices at which some track lies within 0.3 m of `point`."""
    return {row.scan_index for row in table.rows if math.hypot(row.x - point[0], row.y - point[1]) < 0.3}


def walker_scans(table: TrackTable) -> set[int]:
    return {row.scan_index for row in table.rows if math.hypot(row.x - (1.5 + 0.1 * row.scan_index), row.y + 1.0) < 0.3}


def test_a_post_on_an_occupied_map_cell_is_never_a_person_and_the_walker_is_tracked(post_and_walker, tmp_path) -> None:
    without = track_log(post_and_walker, "odom", tracker=tracker())
    assert {3, 4, 5} <= near(without, POST)  # confirmed at first, before the accumulated grid knows it
    occupancy = read_map(post_map(tmp_path))
    assert occupancy.is_occupied(MAP_TO_ODOM.apply(np.array([POST]))).tolist() == [True]
    mapped = track_log(post_and_walker, "odom", tracker=tracker(), occupancy=occupancy)
    assert near(mapped, POST) == set()  # static from the first scan
    assert set(range(10, 60)) <= walker_scans(mapped)
    assert {row.frame for row in mapped.rows} == {"odom"}
    # tracked in the scan's own frame, the map is placed through odometry and tf just the same
    sensor = track_log(post_and_walker, "sensor", tracker=tracker(), occupancy=occupancy)
    assert not any(math.hypot(r.x + 0.005 * r.scan_index - POST[0], r.y - POST[1]) < 0.3 for r in sensor.rows)
    assert len(sensor.rows) == len(mapped.rows)


def test_a_map_taken_in_the_wrong_frame_rejects_nothing_there(post_and_walker, tmp_path) -> None:
    """The same map said to be drawn in the odometry frame: the post's map cell lies elsewhere, so the post stays."""
    occupancy = read_map(post_map(tmp_path), frame="odom")
    assert {3, 4, 5} <= near(track_log(post_and_walker, "odom", tracker=tracker(), occupancy=occupancy), POST)


def test_trials_log_track_takes_the_map(post_and_walker, tmp_path, capsys) -> None:
    """With the shipped detector: the walker is tracked, and never on a lane the map says is occupied."""
    plain, mapped = tmp_path / "plain.csv", tmp_path / "mapped.csv"
    command = ["log", "track", str(post_and_walker), "--frame", "odom", "--quiet", "--out"]
    assert main([*command, str(plain)]) == 0
    assert main([*command, str(mapped), "--map", str(lane_map(tmp_path))]) == 0
    assert mapped.read_text().startswith("stamp,scan_index,track_id,x,y,vx,vy,frame\n")
    assert len(walker_scans(TrackTable.read_csv(plain))) >= 25  # measured 28 (the simulated legs are new to it)
    assert walker_scans(TrackTable.read_csv(mapped)) == set()
    assert capsys.readouterr().err == ""


def test_scans_before_the_localiser_starts_are_tracked_without_the_map_and_counted(tmp_path, capsys) -> None:
    """tf's map -> odom from scan 30 on: scans up to 0.5 s before it (tf's gap) have a pose in the map."""
    late = write_bag(tmp_path / "late.bag", localised_from=30)
    out = tmp_path / "tracks.csv"
    assert main(["log", "track", str(late), "--frame", "odom", "--map", str(lane_map(tmp_path)), "--out", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ("warning: at 25 scans tf gave no pose in the map's frame 'map'; "
                                       "they were tracked without the map\n")
    seen = walker_scans(TrackTable.read_csv(out))
    assert seen and max(seen) < 25 + 10  # tracked before the map came; after it the track coasts and dies


def test_a_logged_trial_plays_the_tracks_made_with_the_map(post_and_walker, tmp_path) -> None:
    occupancy = read_map(lane_map(tmp_path))
    plain, mapped = prepare(post_and_walker, ReplayOptions()), prepare(post_and_walker, ReplayOptions(occupancy=occupancy))
    assert len(walker_scans(TrackTable(plain.rows))) >= 25 and walker_scans(TrackTable(mapped.rows)) == set()
    assert mapped.metadata()["static_map"] == f"{tmp_path / 'map.yaml'} in frame map" and "static_map" not in plain.metadata()


def bad_map(folder: Path, case: str) -> Path:
    pixels = np.full((4, 4), 254)
    if case == "no image":
        path = write_map(folder, pixels, image="missing.pgm")
    elif case == "not an image":
        path = write_map(folder, pixels)
        (folder / "map.pgm").write_text("P5 but not really\n")
    elif case == "not yaml":
        path = folder / "map.yaml"
        path.write_text("image: [map.pgm\n")
    elif case == "a list":
        path = folder / "map.yaml"
        path.write_text("- image\n- resolution\n")
    elif case == "no origin":
        path = folder / "map.yaml"
        write_pgm(folder / "map.pgm", pixels)
        path.write_text("image: map.pgm\nresolution: 0.05\n")
    else:
        field, value = case.split("=")
        path = write_map(folder, pixels, **{field: value})
    return path


@pytest.mark.parametrize(("case", "message"), [
    ("no image", "map.yaml: field image: no file {folder}/missing.pgm"),
    ("not an image", "map.yaml: cannot read image {folder}/map.pgm ("),  # then Pillow's reason
    ("not yaml", "map.yaml: not a map_server YAML file (line 2: expected ',' or ']', but got '<stream end>')"),
    ("a list", "map.yaml: expected a map_server YAML mapping (image, resolution, origin, ...), got list"),
    ("no origin", "map.yaml: missing field origin (a map_server map.yaml needs image, resolution and origin)"),
    ("resolution=-0.05", "map.yaml: field resolution: expected a cell size in metres above 0, got -0.05"),
    ("resolution=fine", "map.yaml: field resolution: expected a cell size in metres above 0, got 'fine'"),
    ("origin=[0.0, 0.0]", "map.yaml: field origin: expected [x, y, yaw] in metres and radians, got [0.0, 0.0]"),
    ("negate=2", "map.yaml: field negate: expected 0 or 1, got 2"),
    ("occupied_thresh=1.5", "map.yaml: field occupied_thresh: expected an occupancy from 0 to 1, got 1.5"),
    ("free_thresh=0.7", "map.yaml: field free_thresh: expected at most occupied_thresh (0.65), got 0.7"),
    ("mode=binary", "map.yaml: field mode: expected trinary, scale, raw, got 'binary'"),
])
def test_a_map_that_cannot_be_used_is_one_line_and_nothing_is_written(post_and_walker, tmp_path, capsys, case, message):
    path = bad_map(tmp_path, case)
    with pytest.raises(LogError) as error:
        read_map(path)
    expected = f"{path}: {message.split('map.yaml: ', 1)[1].format(folder=tmp_path)}"
    assert str(error.value) == expected or (expected.endswith("(") and str(error.value).startswith(expected))
    out = tmp_path / "tracks.csv"
    out.write_text("kept\n")
    assert main(["log", "track", str(post_and_walker), "--frame", "odom", "--map", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {error.value}\n" and out.read_text() == "kept\n"


def test_a_map_frame_the_log_cannot_reach_is_refused(post_and_walker, tmp_path, capsys) -> None:
    out = tmp_path / "tracks.csv"
    assert main(["log", "track", str(post_and_walker), "--frame", "odom", "--map", str(post_map(tmp_path)),
                 "--map-frame", "floor_plan", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {post_and_walker}: no transform connects frame 'odom' to 'floor_plan'")
    assert f"the map {tmp_path / 'map.yaml'} is in frame 'floor_plan'; name the frame it is drawn in (--map-frame)" in err
    assert not out.exists()


def test_a_map_needs_odometry(tmp_path, capsys) -> None:
    path = tmp_path / "scans.bag"
    with BagWriter(path) as bag:
        bag.scan(LidarSimulator(seed=1).scan(1.0, Pose2D(), np.zeros((0, 2)), None))
    assert main(["log", "track", str(path), "--map", str(post_map(tmp_path))]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Odometry" in err
