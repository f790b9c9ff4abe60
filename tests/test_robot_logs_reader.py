"""Reading real logs in every format through one interface, topics by type, timestamps."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer as McapWriter
from rosbags.rosbag1 import Reader as Ros1Reader

from robot_logs.convert import to_scan
from robot_logs.errors import LogError
from robot_logs.log_tracking import read_scans
from robot_logs.reader import LogReader
from robot_logs.topics import SCAN_TYPES, pick_topic
from tests.support.bag_writer import BagWriter
from trials.cli import main

SCAN_COUNT = 1265


@pytest.fixture(scope="module")
def stationary(robot_logs_dir: Path) -> dict[str, Path]:
    """The real stationary recording as ROS1 bag, ROS2 MCAP bag and plain MCAP file."""
    folder = robot_logs_dir / "stationary_ros2"
    return {
        "ros1": robot_logs_dir / "stationary_ros1.bag",
        "ros2-mcap": folder,
        "mcap": folder / "demo_stationary_simple_environment_ros2_mcap.mcap",
    }


@pytest.fixture(scope="module")
def converted(stationary: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same scans as a ROS2 sqlite3 bag and as a ROS1-encoded MCAP file (as `mcap convert` makes)."""
    root = tmp_path_factory.mktemp("converted")
    with LogReader(stationary["ros1"]) as log, BagWriter(root / "sqlite", "ros2-sqlite3") as bag:
        for message in log.messages({"/scan"}):
            bag.scan(to_scan(message.data, message.record_ns, "scan"), record_ns=message.record_ns)
    ros1_mcap = root / "ros1_encoded.mcap"
    with Ros1Reader(stationary["ros1"]) as reader, ros1_mcap.open("wb") as stream:
        writer = McapWriter(stream)
        writer.start(profile="ros1")
        connection = reader.connections[0]
        schema = writer.register_schema("sensor_msgs/LaserScan", "ros1msg", connection.msgdef.data.encode())
        channel = writer.register_channel(connection.topic, "ros1", schema)
        for _, record_ns, raw in reader.messages():
            writer.add_message(channel, record_ns, raw, record_ns)
        writer.finish()
    return {"ros2-sqlite3": root / "sqlite", "ros1-mcap": ros1_mcap}


def test_every_format_gives_the_same_scans(stationary: dict[str, Path], converted: dict[str, Path]) -> None:
    reference = None
    for name, path in {**stationary, **converted}.items():
        with LogReader(path) as log:
            assert [(t.name, t.msgtype, t.count) for t in log.topics] == [("/scan", "sensor_msgs/msg/LaserScan", SCAN_COUNT)], name
            scans = list(read_scans(log, "/scan"))
        stamps = np.array([s.stamp_ns for s in scans])
        ranges = np.stack([s.ranges for s in scans])
        if reference is None:
            reference = (stamps, ranges)
            continue
        assert np.array_equal(stamps, reference[0]), name
        assert np.array_equal(ranges, reference[1], equal_nan=True), name


def test_formats_are_told_apart(stationary: dict[str, Path], converted: dict[str, Path]) -> None:
    formats = {name: LogReader(path).format for name, path in {**stationary, **converted}.items()}
    assert formats == {
        "ros1": "ROS1 bag",
        "ros2-mcap": "ROS2 bag (mcap storage)",
        "mcap": "MCAP file",
        "ros2-sqlite3": "ROS2 bag (sqlite3 storage)",
        "ros1-mcap": "MCAP file",
    }


def test_scan_contents_match_the_recording(stationary: dict[str, Path]) -> None:
    with LogReader(stationary["ros1"]) as log:
        first = next(read_scans(log, "/scan"))
    assert first.frame_id == "laser"
    assert len(first.ranges) == 512
    assert first.angle_min == pytest.approx(-np.pi / 2, abs=1e-6)
    assert first.range_max == pytest.approx(5.6, abs=1e-6)
    assert np.isinf(first.ranges).mean() == pytest.approx(0.66, abs=0.02)


def test_header_stamps_are_the_time_of_every_record(robot_logs_dir: Path) -> None:
    """The labelled bag was re-recorded a year after its scans: stamps are the sensor's."""
    with LogReader(robot_logs_dir / "legs_labelled_ros1.bag") as log:
        scan_topic = pick_topic(log.topics, SCAN_TYPES, "LaserScan", None, log.path, "--scan-topic")
        assert scan_topic.name == "/training_scan"
        first_scan = next(read_scans(log, "/training_scan"))
        first_label = next(log.messages({"/leg_cluster_positions"}))
    assert first_scan.stamp_ns == 1393615837429165250  # header stamp, not record time 1426475811...
    assert first_label.record_ns == 1426475811629238938  # an unstamped label keeps its record time


def test_topic_names_override_the_choice_by_type(stationary: dict[str, Path]) -> None:
    with LogReader(stationary["ros1"]) as log:
        assert pick_topic(log.topics, SCAN_TYPES, "LaserScan", "scan", log.path, "--scan-topic").name == "/scan"
        with pytest.raises(LogError, match=r"no topic /front_scan; its topics: /scan \(sensor_msgs/msg/LaserScan, 1265\)"):
            pick_topic(log.topics, SCAN_TYPES, "LaserScan", "/front_scan", log.path, "--scan-topic")


def test_several_scan_topics_ask_for_a_choice(tmp_path: Path, stationary: dict[str, Path]) -> None:
    with LogReader(stationary["ros1"]) as log:
        scan = next(read_scans(log, "/scan"))
    with BagWriter(tmp_path / "two.bag") as bag:
        bag.scan(scan, "/front")
        bag.scan(scan, "/rear")
    with LogReader(tmp_path / "two.bag") as log:
        with pytest.raises(LogError, match=r"several LaserScan topics \(/front, /rear\); choose one with --scan-topic"):
            pick_topic(log.topics, SCAN_TYPES, "LaserScan", None, log.path, "--scan-topic")


def test_inspect_reports_topics_rates_and_frames(stationary: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["log", "inspect", str(stationary["ros2-mcap"])]) == 0
    out = capsys.readouterr().out
    assert "ROS2 bag (mcap storage)" in out
    assert "duration: 125.989 s by header stamps" in out
    line = next(row for row in out.splitlines() if row.startswith("/scan"))
    assert line.split() == ["/scan", "sensor_msgs/msg/LaserScan", "cdr", "1265", "10.03", "laser"]


def test_inspect_flags_stamps_far_from_record_times(robot_logs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["log", "inspect", str(robot_logs_dir / "legs_labelled_ros1.bag")]) == 0
    out = capsys.readouterr().out
    assert "/training_scan: header stamps are 380.3 days older than record times" in out
    assert "/leg_cluster_positions: 197 messages have unset (zero) header stamps" in out
    assert "duration: 51.812 s by header stamps, 0.480 s by record times" in out


def test_a_copied_bag_folder_reads_like_the_original(stationary: dict[str, Path], tmp_path: Path) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(stationary["ros2-mcap"], copy)
    with LogReader(copy) as log:
        assert sum(1 for _ in log.messages({"/scan"})) == SCAN_COUNT
