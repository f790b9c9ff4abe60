"""Every valid log reads, whatever else it holds (issue 19): ROS 2 bags with unknown types and
recorded services, old sqlite3 bags and metadata versions, split bags, MCAP files in every
layout the format allows, and the toolkit's own JSON run logs.

Each log is written here with the real writers (rosbags' rosbag2 writer, the `mcap` writer)
around the first scans of the stationary sample recording, and must give the same topic counts
and the same tracks as those scans written to a plain ROS1 bag.
"""

from __future__ import annotations

import shutil
import sqlite3
from contextlib import closing
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType
from mcap.writer import Writer as McapWriter
from rosbags.rosbag2 import CompressionMode
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

from robot_logs.foxglove_log import FoxgloveWriter, log_line
from robot_logs.frames import Pose2D
from robot_logs.log_tracking import read_scans, track_log
from robot_logs.pipeline import PersonTracker
from robot_logs.reader import LogReader
from robot_logs.records import Odometry, Scan, Transform
from robot_logs.summary import summarise
from robot_logs.tracks import TrackTable
from tests.support.bag_writer import BagWriter
from trials.cli import main

SCANS = 120  # scans of the sample recording written into each log
EVERY = 20  # one odometry, tf, custom and service message per this many scans
SERVICE = "/add_two_ints/_service_event"
# A service-event definition as Jazzy's recorder stores it; rosbags' parser cannot read it.
SERVICE_DEFINITION = """service_msgs/ServiceEventInfo info
AddTwoInts_Request[<=1] request
AddTwoInts_Response[<=1] response
================================================================================
MSG: service_msgs/ServiceEventInfo
uint8 event_type
builtin_interfaces/Time stamp
char[16] client_gid
int64 sequence_number
================================================================================
MSG: example_interfaces/srv/AddTwoInts_Request
int64 a
int64 b
================================================================================
MSG: example_interfaces/srv/AddTwoInts_Response
int64 sum
"""
CDR_HEADER = b"\x00\x01\x00\x00"
COUNTS = {"/custom": 6, "/odom": 6, "/scan": SCANS, "/tf": 6, SERVICE: 6}



def rules_tracks(path: Path, frame: str = "sensor") -> TrackTable:
    """Tracks by width rules: these tests are about reading every format, not about detection."""
    return track_log(path, frame, tracker=PersonTracker())  # type: ignore[arg-type]

@pytest.fixture(scope="module")
def scans(robot_logs_dir: Path) -> list[Scan]:
    with LogReader(robot_logs_dir / "stationary_ros1.bag") as log:
        return [scan for scan, _ in zip(read_scans(log, "/scan"), range(SCANS))]


@pytest.fixture(scope="module")
def reference(scans: list[Scan], tmp_path_factory: pytest.TempPathFactory) -> list[tuple]:
    """The tracks of the scans alone, from a ROS1 bag."""
    path = tmp_path_factory.mktemp("reference") / "scans.bag"
    with BagWriter(path) as bag:
        for scan in scans:
            bag.scan(scan)
    rows = rules_tracks(path).rows
    assert len(rows) == 672 and len({row.track_id for row in rows}) == 12  # as the whole recording tracked, cut at scan 120
    return rows


def write_bag(path: Path, scans: list[Scan], bag_format: str, version: int = 9, compression: CompressionMode = CompressionMode.NONE) -> Path:
    """Scans, odometry, tf, a type nobody defines and recorded service events, as a ROS2 bag."""
    with BagWriter(path, bag_format, Stores.ROS2_HUMBLE, version, compression) as bag:  # type: ignore[arg-type]
        for k, scan in enumerate(scans):
            bag.scan(scan)
            if k % EVERY == 0:
                bag.odometry(Odometry(scan.stamp_ns, "odom", "base_link", Pose2D(0.1 * k, 0.0, 0.0), 0.5, 0.0))
                bag.transforms([Transform(scan.stamp_ns, "base_link", "laser", Pose2D(0.2, 0.0, 0.0), False)])
                bag.raw("/custom", "my_tests/msg/Custom", CDR_HEADER + bytes(12), scan.stamp_ns)
                bag.raw(SERVICE, "example_interfaces/srv/AddTwoInts_Event", CDR_HEADER + bytes(48), scan.stamp_ns, SERVICE_DEFINITION)
    return path


def counts(path: Path) -> dict[str, int]:
    with LogReader(path) as log:
        return {t.name: t.count for t in log.topics}


def inspect_lines(path: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, list[str]]:
    """`trials log inspect` of a log: exit code 0, each line split, keyed by its first word."""
    assert main(["log", "inspect", str(path)]) == 0
    out = capsys.readouterr().out
    return {line.split()[0]: line.split() for line in out.splitlines() if line.strip()}


@pytest.mark.parametrize("bag_format", ["ros2-mcap", "ros2-sqlite3"])
def test_unknown_types_and_services_are_listed_and_skipped(
    bag_format: str, scans: list[Scan], reference: list[tuple], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = write_bag(tmp_path / "bag", scans, bag_format)
    lines = inspect_lines(bag, capsys)
    assert lines["/scan"] == ["/scan", "sensor_msgs/msg/LaserScan", "cdr", str(SCANS), "10.03", "laser"]
    assert lines["/odom"] == ["/odom", "nav_msgs/msg/Odometry", "cdr", "6", "0.50", "odom->base_link"]
    assert lines["/custom"] == ["/custom", "my_tests/msg/Custom", "cdr", "6", "-", "-"]
    assert lines["/custom:"] == "/custom: 6 of 6 messages (no definition of my_tests/msg/Custom in the log or in rosbags' type stores)".split()
    assert lines[SERVICE] == [SERVICE, "example_interfaces/srv/AddTwoInts_Event", "cdr", "6"]
    assert "services" in lines
    assert rules_tracks(bag).rows == reference
    assert rules_tracks(bag, frame="odom").rows[0].frame == "odom"


def test_asking_for_an_unknown_type_is_one_line(scans: list[Scan], tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", scans[:EVERY], "ros2-mcap")
    with LogReader(bag) as log:
        with pytest.raises(Exception, match=r"^topic /custom of .*bag cannot be decoded: no definition of my_tests/msg/Custom"):
            list(log.messages({"/custom"}))


@pytest.mark.parametrize("bag_format", ["ros2-mcap", "ros2-sqlite3"])
def test_a_folder_and_its_storage_file_read_alike(bag_format: str, scans: list[Scan], reference: list[tuple], tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", scans, bag_format)
    (storage,) = [p for p in bag.iterdir() if p.name != "metadata.yaml"]
    assert counts(bag) == counts(storage) == COUNTS
    assert rules_tracks(storage).rows == reference


QUICK_VERSIONS = (1, 4, 8)  # one of each database schema in the quick loop; the rest are slow

FOXY_QOS = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n"
    "    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false"
)


@pytest.mark.slow
@pytest.mark.parametrize("bag_format", ["ros2-mcap", "ros2-sqlite3"])
@pytest.mark.parametrize("compression", [CompressionMode.FILE, CompressionMode.MESSAGE])
def test_compressed_bags_read(bag_format: str, compression: CompressionMode, scans: list[Scan], reference: list[tuple], tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", scans, bag_format, compression=compression)
    assert counts(bag) == COUNTS
    assert rules_tracks(bag).rows == reference


def make_old(bag: Path, version: int) -> None:
    """Turn a sqlite3 bag written by rosbags into one as an older recorder wrote it: metadata of
    `version` (1-9) and, before version 8, a database without stored definitions or distro.

    Its metadata and database then describe a topic's QoS differently, as fixture bags of older
    releases do; the counts and messages must come from the database all the same.
    """
    yaml = YAML(typ="safe")
    meta = yaml.load((bag / "metadata.yaml").read_text())
    info = meta["rosbag2_bagfile_information"]
    info["version"] = version
    dropped = {8: ["ros_distro"], 6: ["custom_data"], 5: ["files"], 3: ["compression_format", "compression_mode"]}
    for since, keys in dropped.items():
        if version < since:
            for key in keys:
                info.pop(key, None)
    for topic in info["topics_with_message_count"]:
        if version < 7:
            topic["topic_metadata"].pop("type_description_hash", None)
        if version < 4:
            topic["topic_metadata"].pop("offered_qos_profiles", None)
        elif version < 9:  # the QoS as a YAML string, which the database does not repeat
            topic["topic_metadata"]["offered_qos_profiles"] = FOXY_QOS
    if version < 4:
        info["relative_file_paths"] = [f"{bag.name}/{name}" for name in info["relative_file_paths"]]
    with (bag / "metadata.yaml").open("w") as stream:
        yaml.dump(meta, stream)
    if version >= 8:
        return
    (database,) = bag.glob("*.db3")
    with closing(sqlite3.connect(database)) as db:
        db.execute("DROP TABLE message_definitions")
        db.execute("DROP TABLE schema")
        db.execute("DROP TABLE metadata")
        db.execute("ALTER TABLE topics DROP COLUMN type_description_hash")
        if version < 4:
            db.execute("ALTER TABLE topics DROP COLUMN offered_qos_profiles")
        db.commit()


@pytest.mark.parametrize("version", [v if v in QUICK_VERSIONS else pytest.param(v, marks=pytest.mark.slow) for v in range(1, 10)])
def test_old_sqlite3_bags_read_by_folder_and_file(version: int, scans: list[Scan], reference: list[tuple], tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "old", scans, "ros2-sqlite3", version=min(max(version, 8), 9))
    make_old(bag, version)
    (database,) = bag.glob("*.db3")
    assert counts(bag) == counts(database) == COUNTS
    assert rules_tracks(bag).rows == reference


def write_foxy_bag(path: Path, version: int, distro: str | None) -> None:
    """A Foxy-era bag: sensor_msgs/Range without the `variance` field newer releases added, and
    rcl_interfaces/Log; no stored definitions, and the distro in its metadata only if given."""
    store = get_typestore(Stores.ROS2_FOXY)
    types = store.types
    with BagWriter(path, "ros2-sqlite3", Stores.ROS2_FOXY) as bag:
        for k in range(10):
            stamp = types["builtin_interfaces/msg/Time"](sec=100 + k, nanosec=0)
            header = types["std_msgs/msg/Header"](stamp=stamp, frame_id="sonar")
            sonar = types["sensor_msgs/msg/Range"](header=header, radiation_type=0, field_of_view=0.5, min_range=0.1, max_range=4.0, range=1.0 + k)
            bag.write("/sonar", "sensor_msgs/msg/Range", sonar, (100 + k) * 1_000_000_000)
            log = types["rcl_interfaces/msg/Log"](stamp=stamp, level=20, name="node", msg=f"line {k}", file="f.cpp", function="f", line=k)
            bag.write("/rosout", "rcl_interfaces/msg/Log", log, (100 + k) * 1_000_000_000)
    make_old(path, version)
    (database,) = path.glob("*.db3")
    with closing(sqlite3.connect(database)) as db:
        if version >= 8:  # a recorder that stored no definitions even in a newer layout
            db.execute("DELETE FROM message_definitions")
            db.commit()
    if distro is not None:
        yaml = YAML(typ="safe")
        meta = yaml.load((path / "metadata.yaml").read_text())
        meta["rosbag2_bagfile_information"]["ros_distro"] = distro
        with (path / "metadata.yaml").open("w") as stream:
            yaml.dump(meta, stream)


@pytest.mark.parametrize(("version", "distro"), [(4, None), (8, "foxy")])
def test_an_older_definition_decodes_with_its_release_types(version: int, distro: str | None, tmp_path: Path) -> None:
    bag = tmp_path / "foxy"
    write_foxy_bag(bag, version, distro)
    with LogReader(bag) as log:
        sonar = [m.data.range for m in log.messages({"/sonar"})]
        lines = [m.data.msg for m in log.messages({"/rosout"})]
    assert sonar == [1.0 + k for k in range(10)]
    assert lines == [f"line {k}" for k in range(10)]


def test_the_newest_definition_alone_would_not_fit(tmp_path: Path) -> None:
    """The check above is real: today's Range definition does not decode the Foxy bytes."""
    bag = tmp_path / "foxy"
    write_foxy_bag(bag, 4, None)
    (database,) = bag.glob("*.db3")
    with closing(sqlite3.connect(database)) as db:
        raw = db.execute("SELECT data FROM messages JOIN topics ON topics.id = topic_id WHERE name = '/sonar'").fetchone()[0]
    with pytest.raises(Exception, match="Range"):
        get_typestore(Stores.LATEST).deserialize_cdr(raw, "sensor_msgs/msg/Range")


def test_a_split_bag_reads_as_one(scans: list[Scan], reference: list[tuple], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two storage files listed in one metadata.yaml; a topic stamped microseconds apart gets no rate."""
    half = SCANS // 2
    first, second = write_bag(tmp_path / "a", scans[:half], "ros2-mcap"), write_bag(tmp_path / "b", scans[half:], "ros2-mcap")
    with BagWriter(tmp_path / "c", "ros2-mcap") as bag:
        for k in range(5):
            bag.transforms([Transform(1_403_201_190_000_000_000 + 1_000 * k, "map", "odom", Pose2D(), False)], topic="/burst")
    split = tmp_path / "split"
    split.mkdir()
    names = []
    for part, source in enumerate((first, second, tmp_path / "c")):
        (storage,) = source.glob("*.mcap")
        names.append(f"split_{part}.mcap")
        shutil.copy(storage, split / names[-1])
    yaml = YAML(typ="safe")
    meta = yaml.load((first / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["relative_file_paths"] = names
    with (split / "metadata.yaml").open("w") as stream:
        yaml.dump(meta, stream)
    assert counts(split) == {**COUNTS, "/burst": 5}
    lines = inspect_lines(split, capsys)
    assert lines["/burst"] == ["/burst", "tf2_msgs/msg/TFMessage", "cdr", "5", "-", "map->odom"]
    assert lines["/scan"][3:5] == [str(SCANS), "10.03"]
    assert rules_tracks(split).rows == reference


def rewrite_mcap(source: Path, target: Path, **options: object) -> None:
    """The messages of an MCAP file written again with the `mcap` writer's `options`, plus a
    JSON topic and a protobuf topic."""
    with source.open("rb") as stream, target.open("wb") as out:
        reader = make_reader(stream)
        writer = McapWriter(out, **options)  # type: ignore[arg-type]
        writer.start(profile="ros2")
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(channel.topic, channel.message_encoding, schemas[schema.id])
            writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time)
        status = writer.register_channel("/status", "json", writer.register_schema("demo.Status", "jsonschema", b"{}"))
        proto = writer.register_channel("/camera", "protobuf", writer.register_schema("demo.Image", "protobuf", b"\x0a\x00"))
        for k in range(4):
            writer.add_message(status, 1_403_201_184_000_000_000 + k * 500_000_000, b'{"ok": true}', 0)
            writer.add_message(proto, 1_403_201_184_000_000_000 + k * 500_000_000, b"\x08\x01", 0)
        writer.finish()


NO_SUMMARY = {"index_types": IndexType.NONE, "repeat_channels": False, "repeat_schemas": False, "use_statistics": False, "use_summary_offsets": False}
LAYOUTS = {
    "chunked-zstd": {"compression": CompressionType.ZSTD},
    "chunked-lz4": {"compression": CompressionType.LZ4},
    "chunked-uncompressed": {"compression": CompressionType.NONE, "chunk_size": 64 * 1024},
    "unchunked": {"use_chunking": False},
    "no-chunk-index": {"compression": CompressionType.LZ4, "index_types": IndexType.NONE},
    "no-statistics": {"use_statistics": False},
    "no-summary": {"compression": CompressionType.ZSTD, **NO_SUMMARY},
    "unchunked-no-summary": {"use_chunking": False, **NO_SUMMARY},
}


@pytest.fixture(scope="module")
def mcap_source(scans: list[Scan], tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = write_bag(tmp_path_factory.mktemp("mcap") / "bag", scans, "ros2-mcap")
    return next(bag.glob("*.mcap"))


QUICK_LAYOUTS = ("chunked-lz4", "no-summary", "unchunked-no-summary")


@pytest.mark.parametrize("layout", [k if k in QUICK_LAYOUTS else pytest.param(k, marks=pytest.mark.slow) for k in sorted(LAYOUTS)])
def test_every_mcap_layout_reads(
    layout: str, mcap_source: Path, reference: list[tuple], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / f"{layout}.mcap"
    rewrite_mcap(mcap_source, path, **LAYOUTS[layout])
    assert counts(path) == {**COUNTS, "/status": 4, "/camera": 4}
    lines = inspect_lines(path, capsys)
    assert lines["/status"] == ["/status", "demo.Status", "json", "4", "2.00", "-"]
    assert lines["/camera"] == ["/camera", "demo.Image", "protobuf", "4", "-", "-"]
    assert lines["/camera:"][1:4] == ["4", "of", "4"]
    assert rules_tracks(path).rows == reference


def test_a_truncated_mcap_without_index_is_refused_and_salvaged(
    mcap_source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = tmp_path / "whole.mcap"
    rewrite_mcap(mcap_source, whole, compression=CompressionType.NONE, chunk_size=32 * 1024, **NO_SUMMARY)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size * 2 // 3])
    assert main(["log", "inspect", str(cut)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {cut} is damaged (truncated or corrupt") and "--salvage" in err[0]
    with LogReader(cut, salvage=True) as log:
        read = sum(1 for _ in log.messages({"/scan"}))
        assert log.damage is not None
    assert 0.5 * SCANS < read < SCANS


def test_inspect_reads_a_toolkit_run_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "ABCDE.mcap"
    with FoxgloveWriter(path, metadata={"run": {"run_code": "ABCDE"}}) as log:
        for k in range(11):
            log.write("/robot/state", "navtrials.RobotState", {"t": k * 0.1, "x": 0.0}, k * 100_000_000)
        log.write("/log", "foxglove.Log", log_line(0, "started"), 0)
    lines = inspect_lines(path, capsys)
    assert lines["/robot/state"] == ["/robot/state", "navtrials.RobotState", "json", "11", "10.00", "-"]
    assert lines["/log"] == ["/log", "foxglove.Log", "json", "1", "-", "-"]


def test_inspect_summary_counts_what_it_skips(scans: list[Scan], tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", scans[:EVERY * 2], "ros2-sqlite3")
    with LogReader(bag) as log:
        summary = {t.name: t for t in summarise(log).topics}
    assert (summary["/custom"].count, summary["/custom"].undecoded) == (2, 2)
    assert (summary["/scan"].count, summary["/scan"].undecoded) == (EVERY * 2, 0)
    assert summary[SERVICE].service and summary[SERVICE].count == 2


def test_log_show_takes_a_path_and_names_what_is_not_a_run_log(robot_logs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = robot_logs_dir / "stationary_ros1.bag"
    assert main(["log", "show", str(bag)]) == 2
    assert capsys.readouterr().err.strip() == f"error: {bag} is not an MCAP file (a run log is an .mcap written by trials)"
    mcap = robot_logs_dir / "stationary_ros2" / "demo_stationary_simple_environment_ros2_mcap.mcap"
    assert main(["log", "show", str(mcap)]) == 2
    assert capsys.readouterr().err.strip() == f"error: {mcap} is not a trials run log (no `run` metadata or /robot/state topic)"
