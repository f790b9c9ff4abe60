"""Foxglove MCAP run logs: well-known schemas, round trip, and no half-written files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from robot_logs.errors import LogError
from robot_logs.foxglove_log import (
    FoxgloveReader,
    FoxgloveWriter,
    entity,
    frame_transform,
    laser_scan,
    line_strip,
    log_line,
    pose_in_frame,
    poses_in_frame,
    scene_update,
    sphere,
)
from robot_logs.foxglove_schemas import foxglove_schema
from robot_logs.frames import Pose2D
from robot_logs.records import Scan
from tests.support.mcap_schemas import validate_channels


def write_run(path: Path) -> None:
    with FoxgloveWriter(path, metadata={"run": {"code": "R07", "seed": "42"}}) as log:
        log.write("/robot/pose", "foxglove.PoseInFrame", pose_in_frame(1_500_000_000, "map", Pose2D(1.0, 2.0, 0.5)), 1_500_000_000)
        log.write("/plan", "foxglove.PosesInFrame", poses_in_frame(1_500_000_000, "map", np.array([[1.0, 2.0], [1.4, 2.1]])), 1_500_000_000)
        log.write("/tf", "foxglove.FrameTransform", frame_transform(1_500_000_000, "map", "base_link", Pose2D(1.0, 2.0, 0.5)), 1_500_000_000)
        people = entity(1_500_000_000, "map", "pedestrians", spheres=[sphere(3.0, 1.0, 0.5, (1, 0, 0, 1))],
                        lines=[line_strip(np.array([[0, 0], [1, 1]]), (0, 1, 0, 1))])
        log.write("/pedestrians", "foxglove.SceneUpdate", scene_update([people]), 1_500_000_000)
        log.write("/events", "navtrials.Event", {"kind": "goal_reached", "time": 12.4}, 2_000_000_000)
        log.write("/log", "foxglove.Log", log_line(2_000_000_000, "run finished"), 2_000_000_000)


def test_round_trip_with_schemas_and_metadata(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path)
    log = FoxgloveReader(path)
    assert log.metadata == {"run": {"code": "R07", "seed": "42"}}
    assert log.topics["/pedestrians"] == "foxglove.SceneUpdate" and log.topics["/events"] == "navtrials.Event"
    messages = list(log.messages())
    assert [m.topic for m in messages][-2:] in (["/events", "/log"], ["/log", "/events"])
    pose = next(m for m in messages if m.topic == "/robot/pose").data
    assert pose["timestamp"] == {"sec": 1, "nsec": 500_000_000}
    assert pose["pose"]["orientation"]["z"] == pytest.approx(np.sin(0.25))
    assert next(m for m in messages if m.topic == "/events").data == {"kind": "goal_reached", "time": 12.4}


def test_schemas_carry_foxglove_names_and_json_schema(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path)
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    schemas = {s.name: s for s in summary.schemas.values()}
    for name in ("foxglove.PoseInFrame", "foxglove.PosesInFrame", "foxglove.FrameTransform", "foxglove.SceneUpdate", "foxglove.Log"):
        assert schemas[name].encoding == "jsonschema"
        assert json.loads(schemas[name].data) == foxglove_schema(name)
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}
    assert json.loads(schemas["navtrials.Event"].data) == {"title": "navtrials.Event", "type": "object"}  # no schema given: any object
    scene = foxglove_schema("foxglove.SceneUpdate")["properties"]["entities"]["items"]["properties"]
    assert scene["timestamp"]["title"] == "time" and "spheres" in scene and "cylinders" in scene


def test_given_schemas_are_declared_and_foxglove_messages_fit_foxglove_schemas(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    event = {"title": "navtrials.Event", "type": "object", "properties": {"kind": {"type": "string"}}, "required": ["kind"]}
    with FoxgloveWriter(path, schemas={"navtrials.Event": event}) as log:
        log.write("/events", "navtrials.Event", {"kind": "goal"}, 0)
        people = entity(0, "map", "people", spheres=[sphere(1.0, 2.0, 0.5, (1, 0, 0, 1))], lines=[line_strip(np.zeros((2, 2)), (0, 1, 0, 1))])
        log.write("/scene", "foxglove.SceneUpdate", scene_update([people], delete_all_before_ns=0), 0)
        log.write("/scan", "foxglove.LaserScan", laser_scan(Scan(0, "laser", -0.5, 0.5, 0.5, 5.0, np.array([1.0, 2.0, np.inf]))), 0)
        log.write("/log", "foxglove.Log", log_line(0, "hello", "warning"), 0)
    counts = validate_channels(path)
    assert counts == {"navtrials.Event": 1, "foxglove.SceneUpdate": 1, "foxglove.LaserScan": 1, "foxglove.Log": 1}
    with path.open("rb") as stream:
        schemas = {s.name: json.loads(s.data) for s in make_reader(stream).get_summary().schemas.values()}
    assert schemas["navtrials.Event"] == event


def test_the_file_appears_only_when_finished(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    writer = FoxgloveWriter(path)
    writer.write("/log", "foxglove.Log", log_line(0, "started"), 0)
    assert not path.exists() and (tmp_path / ".run.mcap.partial").exists()
    writer.close()
    assert path.exists() and not (tmp_path / ".run.mcap.partial").exists()


def test_a_failed_run_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    path.write_bytes(b"previous finished log")
    with pytest.raises(ValueError, match="Out of range float"):
        with FoxgloveWriter(path) as log:
            log.write("/metrics", "navtrials.Metrics", {"ttc": float("inf")}, 0)  # JSON has no infinity
    assert path.read_bytes() == b"previous finished log" and list(tmp_path.iterdir()) == [path]


def test_scans_write_invalid_beams_as_zero() -> None:
    scan = Scan(0, "laser", -0.5, 0.5, 0.1, 5.0, np.array([1.0, np.inf, np.nan]))
    message = laser_scan(scan)
    assert message["ranges"] == [1.0, 0.0, 0.0]
    assert message["end_angle"] == pytest.approx(0.5)


def test_an_unfinished_log_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:300])
    with pytest.raises(LogError, match="cut.mcap is damaged or unfinished"):
        FoxgloveReader(cut)
