"""Bad input to `trials log`: damaged, empty and inconsistent logs, missing topics.

Each is one `error:` line naming the file, exit code 2, and nothing already written lost.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from robot_logs.errors import LogError
from robot_logs.log_tracking import track_log
from robot_logs.records import Scan
from tests.support.bag_writer import BagWriter
from trials.cli import main

CUT = 1_500_000  # bytes kept of a truncated log


def run(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str, str]:
    code = main(["log", *map(str, args)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


@pytest.fixture(scope="module")
def damaged(robot_logs_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("damaged")
    bag = root / "cut.bag"
    bag.write_bytes((robot_logs_dir / "stationary_ros1.bag").read_bytes()[:CUT])
    folder = root / "cut_ros2"
    folder.mkdir()
    shutil.copy(robot_logs_dir / "stationary_ros2" / "metadata.yaml", folder)
    storage = robot_logs_dir / "stationary_ros2" / "demo_stationary_simple_environment_ros2_mcap.mcap"
    (folder / storage.name).write_bytes(storage.read_bytes()[:CUT])
    plain = root / "cut.mcap"
    plain.write_bytes(storage.read_bytes()[:CUT])
    garbled = root / "garbled.mcap"
    data = bytearray(storage.read_bytes())
    data[900_000:904_000] = np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    garbled.write_bytes(bytes(data))
    return {"bag": bag, "ros2": folder, "mcap": plain, "garbled": garbled}


@pytest.mark.parametrize("kind", ["bag", "ros2", "mcap", "garbled"])
def test_a_damaged_log_is_refused_by_name(damaged: dict[str, Path], kind: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "track", damaged[kind])
    line = one_error_line(err)
    assert code == 2 and out == ""
    assert str(damaged[kind]) in line and "is damaged" in line and "--salvage" in line


@pytest.mark.parametrize(("kind", "scans"), [("bag", 365), ("ros2", 490), ("mcap", 490), ("garbled", 1195)])
@pytest.mark.slow
def test_salvage_reads_what_can_be_read(damaged: dict[str, Path], kind: str, scans: int, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "inspect", damaged[kind], "--salvage")
    assert code == 0
    assert next(line for line in out.splitlines() if line.startswith("/scan")).split()[3] == str(scans)
    assert "warning: the log is damaged" in err
    table = track_log(damaged[kind], salvage=True)
    assert len(table) > 0


def test_missing_topic_lists_the_topics_there_are(robot_logs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "track", robot_logs_dir / "stationary_ros1.bag", "--frame", "odom")
    assert code == 2
    assert one_error_line(err).endswith("has no Odometry topic; its topics: /scan (sensor_msgs/msg/LaserScan, 1265); "
                                        "no tf moves its scan frame either; "
                                        "scan odometry (--odometry scan) places its scans by scan matching instead")
    code, _, err = run(capsys, "track", robot_logs_dir / "legs_labelled_ros1.bag", "--scan-topic", "/scan")
    assert code == 2
    line = one_error_line(err)
    assert "has no topic /scan; its topics: /leg_cluster_positions (geometry_msgs/msg/PoseArray, 197)" in line
    assert "/training_scan (sensor_msgs/msg/LaserScan, 197)" in line


def test_a_map_needs_the_logs_own_odometry(robot_logs_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    Image.new("L", (10, 10), 255).save(tmp_path / "map.pgm")
    (tmp_path / "map.yaml").write_text("image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    bag = robot_logs_dir / "stationary_ros1.bag"
    code, out, err = run(capsys, "track", bag, "--odometry", "scan", "--map", tmp_path / "map.yaml")
    assert code == 2 and out == ""
    assert one_error_line(err) == f"error: {bag}: a map is placed by the log's odometry and tf; scan odometry has no map frame"


def test_a_topic_of_the_wrong_type_is_refused(robot_logs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "track", robot_logs_dir / "legs_labelled_ros1.bag", "--scan-topic", "/leg_cluster_positions")
    assert code == 2
    assert "holds geometry_msgs/msg/PoseArray, not LaserScan" in one_error_line(err)


def _scan(count: int, stamp_ns: int = 1_000_000_000) -> Scan:
    return Scan(stamp_ns, "laser", -1.0, 0.01, 0.1, 10.0, np.full(count, 3.0))


def test_a_scan_with_inconsistent_sizes_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad_scan.bag"
    out = tmp_path / "tracks.csv"
    out.write_text("earlier results\n")
    with BagWriter(path) as bag:
        bag.scan(_scan(201, 1_000_000_000))
        bag.scan(_scan(150, 1_100_000_000), angle_max=1.0)  # 201 beams promised, 150 sent
    code, _, err = run(capsys, "track", path, "--out", out, "--mcap", tmp_path / "view.mcap")
    assert code == 2
    assert one_error_line(err) == (
        f"error: scan 1 on /scan of {path}: 150 ranges, but angle_min..angle_max at angle_increment "
        "gives 201 beams (inconsistent LaserScan sizes)"
    )
    assert out.read_text() == "earlier results\n"  # nothing already written is lost
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad_scan.bag", "tracks.csv"]  # no partial MCAP


def test_an_empty_log_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with BagWriter(tmp_path / "empty.bag"):
        pass
    code, _, err = run(capsys, "track", tmp_path / "empty.bag")
    assert code == 2 and "has no LaserScan topic; its topics: none" in one_error_line(err)
    (tmp_path / "zero.bag").write_bytes(b"")
    code, _, err = run(capsys, "inspect", tmp_path / "zero.bag")
    assert code == 2 and one_error_line(err) == f"error: {tmp_path / 'zero.bag'} is empty (0 bytes)"


def test_not_a_log_and_no_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = tmp_path / "notes.bag"
    text.write_text("field notes, not a bag\n")
    code, _, err = run(capsys, "inspect", text)
    assert code == 2 and "is not a log robot_logs reads" in one_error_line(err)
    code, _, err = run(capsys, "track", tmp_path / "missing.mcap")
    assert code == 2 and one_error_line(err) == f"error: {tmp_path / 'missing.mcap'}: no such file or folder"
    code, _, err = run(capsys, "inspect", tmp_path)
    assert code == 2 and "folder without metadata.yaml" in one_error_line(err)


def test_scans_and_odometry_on_different_clocks(tmp_path: Path) -> None:
    from robot_logs.frames import Pose2D
    from robot_logs.records import Odometry

    path = tmp_path / "clocks.bag"
    year = 365 * 86400 * 1_000_000_000
    with BagWriter(path) as bag:
        for k in range(5):
            stamp = 1_000_000_000 + k * 100_000_000
            bag.odometry(Odometry(stamp + year, "odom", "laser", Pose2D(), 0.0, 0.0))
            bag.scan(_scan(201, stamp))
    with pytest.raises(LogError, match="falls within its odometry's time span.*different clocks"):
        track_log(path, frame="odom")


def test_a_scan_frame_without_tf_to_the_robot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from robot_logs.frames import Pose2D
    from robot_logs.records import Odometry

    path = tmp_path / "no_tf.bag"
    with BagWriter(path) as bag:
        for k in range(3):
            stamp = 1_000_000_000 + k * 100_000_000
            bag.odometry(Odometry(stamp, "/odom", "base_link", Pose2D(), 0.0, 0.0))
            bag.scan(_scan(201, stamp))
    code, _, err = run(capsys, "track", path, "--frame", "odom")
    assert code == 2
    assert one_error_line(err) == f"error: {path}: no transform connects frame 'laser' to 'odom' (frames in the log: base_link, odom)"
