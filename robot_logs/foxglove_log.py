"""MCAP run logs that open in Foxglove with no plugin: JSON messages with Foxglove's schemas.

`FoxgloveWriter` writes messages on named topics, each with a schema name: a well-known
Foxglove type (scene updates, poses, transforms, scans, log lines; its JSON schema from
`foxglove_schema`), a type whose JSON schema the writer is given (a run log's own records), or
any other name for a plain JSON record. The file is written
under a hidden temporary name and renamed on `close()`, so a file under its real name is
always complete. `FoxgloveReader` reads such a file back. The builder functions below make
the message dictionaries from planar poses and positions.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO

import numpy as np
from mcap.reader import make_reader
from mcap.records import Channel as McapChannel
from mcap.records import Message as McapMessage
from mcap.records import Metadata as McapMetadata
from mcap.records import Schema as McapSchema
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer

from robot_logs.errors import LogError
from robot_logs.foxglove_schemas import Schema, foxglove_schema, open_schema
from robot_logs.frames import Pose2D
from robot_logs.inflate import InflateError
from robot_logs.mcap_chunks import indexed_messages, stream_records
from robot_logs.records import Scan

Message = dict[str, Any]
Color = tuple[float, float, float, float]

LOG_LEVELS = {"debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}


def timestamp(stamp_ns: int) -> dict[str, int]:
    """A Foxglove time {"sec", "nsec"} from nanoseconds."""
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def pose(x: float, y: float, yaw: float = 0.0, z: float = 0.0) -> Message:
    """A Foxglove Pose from a planar position and heading."""
    return {
        "position": {"x": float(x), "y": float(y), "z": float(z)},
        "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)},
    }


def color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    """A Foxglove Color, components 0-1."""
    return {"r": r, "g": g, "b": b, "a": a}


def laser_scan(scan: Scan) -> Message:
    """foxglove.LaserScan of a scan; beams with no valid return are written as range 0."""
    ranges = np.where(scan.valid(), scan.ranges, 0.0)
    return {
        "timestamp": timestamp(scan.stamp_ns),
        "frame_id": scan.frame_id,
        "pose": pose(0.0, 0.0),
        "start_angle": scan.angle_min,
        "end_angle": scan.angle_min + scan.angle_increment * (len(scan.ranges) - 1),
        "ranges": [round(float(r), 4) for r in ranges],
        "intensities": [],
    }


def frame_transform(stamp_ns: int, parent: str, child: str, transform: Pose2D) -> Message:
    """foxglove.FrameTransform placing `child` in `parent`."""
    placed = pose(transform.x, transform.y, transform.yaw)
    return {
        "timestamp": timestamp(stamp_ns),
        "parent_frame_id": parent,
        "child_frame_id": child,
        "translation": placed["position"],
        "rotation": placed["orientation"],
    }


def pose_in_frame(stamp_ns: int, frame: str, where: Pose2D) -> Message:
    """foxglove.PoseInFrame of one planar pose (e.g. the robot or the goal)."""
    return {"timestamp": timestamp(stamp_ns), "frame_id": frame, "pose": pose(where.x, where.y, where.yaw)}


def poses_in_frame(stamp_ns: int, frame: str, points: np.ndarray) -> Message:
    """foxglove.PosesInFrame of (N, 2) positions or (N, 3) poses (e.g. a plan's way-points)."""
    points = np.asarray(points, dtype=float)
    rows = points if points.shape[-1] == 3 else np.column_stack((points.reshape(-1, 2), np.zeros(len(points))))
    return {"timestamp": timestamp(stamp_ns), "frame_id": frame, "poses": [pose(x, y, yaw) for x, y, yaw in rows]}


def log_line(stamp_ns: int, text: str, level: str = "info", name: str = "navtrials") -> Message:
    """foxglove.Log of one line of text (level: debug, info, warning, error, fatal)."""
    return {"timestamp": timestamp(stamp_ns), "level": LOG_LEVELS[level], "message": text, "name": name, "file": "", "line": 0}


def cylinder(x: float, y: float, radius: float, height: float, rgba: Color) -> Message:
    """A CylinderPrimitive standing on the ground at (x, y)."""
    return {
        "pose": pose(x, y, z=height / 2.0),
        "size": {"x": 2.0 * radius, "y": 2.0 * radius, "z": height},
        "bottom_scale": 1.0,
        "top_scale": 1.0,
        "color": color(*rgba),
    }


def sphere(x: float, y: float, diameter: float, rgba: Color, z: float = 0.0) -> Message:
    """A SpherePrimitive centred at (x, y, z)."""
    return {"pose": pose(x, y, z=z), "size": {"x": diameter, "y": diameter, "z": diameter}, "color": color(*rgba)}


def text(x: float, y: float, label: str, rgba: Color = (1.0, 1.0, 1.0, 1.0), z: float = 2.0, size: float = 0.3) -> Message:
    """A TextPrimitive facing the camera above (x, y)."""
    return {"pose": pose(x, y, z=z), "billboard": True, "font_size": size, "scale_invariant": False, "color": color(*rgba), "text": label}


def line_strip(points: np.ndarray, rgba: Color, thickness: float = 0.05) -> Message:
    """A LinePrimitive through (N, 2) points on the ground (e.g. a path or a cone's edge)."""
    return {
        "type": 0,
        "pose": pose(0.0, 0.0),
        "thickness": thickness,
        "scale_invariant": False,
        "points": [{"x": float(x), "y": float(y), "z": 0.0} for x, y in np.asarray(points, dtype=float).reshape(-1, 2)],
        "color": color(*rgba),
        "colors": [],
        "indices": [],
    }


def entity(stamp_ns: int, frame: str, entity_id: str, lifetime_s: float = 0.0, **primitives: list[Message]) -> Message:
    """A SceneEntity with primitive lists (spheres=, cylinders=, lines=, texts=, arrows=, cubes=, triangles=, models=).

    lifetime_s: seconds until Foxglove removes it (0: until replaced or deleted).
    """
    lifetime = timestamp(int(lifetime_s * 1e9))
    entry: Message = {"timestamp": timestamp(stamp_ns), "frame_id": frame, "id": entity_id, "lifetime": lifetime, "frame_locked": False, "metadata": []}
    for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"):
        entry[kind] = primitives.pop(kind, [])
    if primitives:
        raise TypeError(f"unknown primitive kinds: {', '.join(primitives)}")
    return entry


def scene_update(entities: Iterable[Message], delete_all_before_ns: int | None = None) -> Message:
    """foxglove.SceneUpdate adding or replacing entities, optionally clearing older ones first."""
    deletions = [] if delete_all_before_ns is None else [{"timestamp": timestamp(delete_all_before_ns), "type": 1, "id": ""}]
    return {"deletions": deletions, "entities": list(entities)}


def partial_path(path: Path) -> Path:
    """Where a log is written until it is finished: a hidden file beside its final name."""
    return path.with_name(f".{path.name}.partial")


def recover(partial: Path, path: Path) -> int:
    """Write the complete records of an unfinished log (a writer's partial file, cut off where its process was killed)
    as a finished log at `path`: its metadata, schemas, channels and every message of its complete chunks. Returns the
    number of messages kept.

    Raises:
        LogError: `partial` is not the start of an MCAP file.
    """
    with partial.open("rb") as stream:
        if stream.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:
            raise LogError(f"{partial} is not an MCAP file")
    records = []
    with partial.open("rb") as stream:
        try:
            records.extend(stream_records(stream))
        except Exception:  # noqa: BLE001 - the cut-off record, or any damage after it: keep what came before
            pass
    target = partial_path(path).with_suffix(".recovering")
    kept = 0
    with target.open("wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(profile="", library="navtrials robot_logs (recovered)")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for record in records:
            if isinstance(record, McapSchema):
                schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, McapChannel) and record.schema_id in schemas | {0: 0}:
                channels[record.id] = writer.register_channel(record.topic, record.message_encoding, schemas.get(record.schema_id, 0),
                                                              dict(record.metadata))
            elif isinstance(record, McapMetadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, McapMessage) and record.channel_id in channels:
                writer.add_message(channels[record.channel_id], log_time=record.log_time, data=record.data,
                                   publish_time=record.publish_time, sequence=record.sequence)
                kept += 1
        writer.finish()
        out.flush()
        os.fsync(out.fileno())
    os.replace(target, path)
    return kept


class FoxgloveWriter:
    """Writes an MCAP file of JSON messages; the file gets its name only when closed.

    Use as a context manager: leaving it normally renames the finished file into place,
    leaving it by an exception deletes the partial file.

    Args:
        path: where the finished log goes (an existing file there is replaced on close).
        metadata: named string maps stored as MCAP metadata (seed, factor settings...).
        schemas: JSON schemas of the writer's own (non-Foxglove) types, by schema name.
        chunk_size: bytes of messages gathered into one compressed chunk before it is written out; a smaller one loses
            less to a process killed while writing (what `recover` can read back from the partial file).
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, Mapping[str, str]] | None = None,
                 schemas: Mapping[str, Schema] | None = None, chunk_size: int = 1024 * 1024) -> None:
        self.path = Path(path)
        self._definitions = dict(schemas or {})
        self.partial = partial_path(self.path)
        self._stream: BinaryIO = self.partial.open("wb")
        self._writer = Writer(self._stream, compression=CompressionType.ZSTD, chunk_size=chunk_size)
        self._writer.start(profile="", library="navtrials robot_logs")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        for name, values in (metadata or {}).items():
            self.add_metadata(name, values)

    def add_metadata(self, name: str, values: Mapping[str, str]) -> None:
        """Store a named string map (e.g. "run": {"code": ..., "seed": ...}) in the file."""
        self._writer.add_metadata(name, {str(k): str(v) for k, v in values.items()})

    def _channel(self, topic: str, schema: str) -> int:
        known = self._channels.get(topic)
        if known is not None:
            if known[1] != schema:
                raise ValueError(f"topic {topic} already carries {known[1]}, not {schema}")
            return known[0]
        if schema not in self._schemas:
            definition = self._schema(schema)
            self._schemas[schema] = self._writer.register_schema(schema, "jsonschema", json.dumps(definition).encode())
        channel = self._writer.register_channel(topic, "json", self._schemas[schema])
        self._channels[topic] = (channel, schema)
        return channel

    def _schema(self, name: str) -> Schema:
        if name in self._definitions:
            return self._definitions[name]
        try:
            return foxglove_schema(name)
        except KeyError:
            return open_schema(name)

    def write(self, topic: str, schema: str, message: Mapping[str, Any], stamp_ns: int) -> None:
        """Log one message on `topic` at `stamp_ns`.

        Args:
            topic: channel name, e.g. "/robot/pose"; one schema per topic.
            schema: a Foxglove type, one of the writer's `schemas`, or any other name for a plain JSON record.
            message: the JSON-able message; NaN and infinities are not allowed (JSON has none).
            stamp_ns: log and publish time in nanoseconds.
        """
        data = json.dumps(message, allow_nan=False, separators=(",", ":")).encode()
        self._writer.add_message(self._channel(topic, schema), log_time=int(stamp_ns), data=data, publish_time=int(stamp_ns))

    def close(self) -> None:
        """Finish the file and move it to its real name."""
        self._writer.finish()
        self._stream.flush()
        os.fsync(self._stream.fileno())
        self._stream.close()
        os.replace(self.partial, self.path)

    def abort(self) -> None:
        """Drop the partial file; nothing appears under the real name."""
        self._stream.close()
        self.partial.unlink(missing_ok=True)

    def __enter__(self) -> FoxgloveWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


@dataclass(frozen=True)
class LoggedMessage:
    """A message read back from a run log: topic, schema name, time (ns) and decoded JSON."""

    topic: str
    schema: str
    stamp_ns: int
    data: Any


class FoxgloveReader:
    """Reads a JSON MCAP log written by `FoxgloveWriter` (or any JSON-encoded MCAP).

    Raises:
        LogError: the file is missing, not an MCAP file, unfinished or damaged; `messages`
            refuses non-JSON channels.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise LogError(f"{self.path}: no such run log")
        with self.path.open("rb") as stream:
            if stream.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:
                raise LogError(f"{self.path} is not an MCAP file (a run log is an .mcap written by trials)")
        try:
            with self.path.open("rb") as stream:
                reader = make_reader(stream)
                summary = reader.get_summary()
                self.metadata: dict[str, dict[str, str]] = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        except Exception as exc:  # the mcap library's errors all mean a damaged file
            raise LogError(f"{self.path} is damaged or unfinished ({exc})") from None
        if summary is None:
            raise LogError(f"{self.path} is damaged or unfinished (no summary section)")
        self._summary = summary

    @property
    def topics(self) -> dict[str, str]:
        """Topic -> schema name."""
        schemas = self._summary.schemas
        return {c.topic: schemas[c.schema_id].name if c.schema_id else "" for c in self._summary.channels.values()}

    @property
    def schemas(self) -> dict[str, tuple[str, tuple[str, ...]]]:
        """Schema name -> its encoding and, for a JSON schema, the top-level fields it declares (what
        Foxglove's panels offer); a schema in another encoding, or one that is not valid JSON, lists none."""
        found: dict[str, tuple[str, tuple[str, ...]]] = {}
        for schema in self._summary.schemas.values():
            fields: tuple[str, ...] = ()
            if schema.encoding == "jsonschema":
                try:
                    fields = tuple(json.loads(schema.data).get("properties", {}))
                except (ValueError, AttributeError):
                    fields = ()
            found[schema.name] = (schema.encoding, fields)
        return found

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[LoggedMessage]:
        """Messages in time order, all or those of the given topics; each chunk decompressed within the size it
        declares (`robot_logs.mcap_chunks`).

        Raises:
            LogError: a chunk that expands beyond its declared size or does not decompress.
        """
        wanted = None if topics is None else list(topics)
        bad = [c.topic for c in self._summary.channels.values() if c.message_encoding != "json" and (wanted is None or c.topic in wanted)]
        if bad:
            raise LogError(f"{self.path}: topics {', '.join(bad)} are not JSON-encoded")
        channels = {c.id: c for c in self._summary.channels.values() if wanted is None or c.topic in wanted}
        with self.path.open("rb") as stream:
            try:
                if self._summary.chunk_indexes:
                    found: Iterable[McapMessage] = indexed_messages(stream, self._summary, channels)
                else:  # unchunked, or chunks without an index: the whole file, ordered by time as an index would give it
                    found = sorted((r for r in stream_records(stream) if isinstance(r, McapMessage) and r.channel_id in channels),
                                   key=lambda r: r.log_time)
                for message in found:
                    channel = channels[message.channel_id]
                    schema = self._summary.schemas.get(channel.schema_id)
                    yield LoggedMessage(channel.topic, schema.name if schema else "", message.log_time, json.loads(message.data))
            except InflateError as exc:
                raise LogError(f"{self.path} is damaged ({exc})") from None
