"""The message sources behind `LogReader`, one per way of opening a log.

- `RosbagsSource`: ROS1 bags and ROS2 bags (sqlite3 or MCAP storage) through rosbags' AnyReader.
- `McapSource`: plain MCAP files with ROS1 or ROS2 (CDR) messages through the `mcap` library;
  with `salvage=True` it skips damaged chunks, or reads a truncated file up to the damage.
- `BagWalkSource`: a ROS1 bag read record by record, for bags whose index is damaged.

Each yields `Message`s with deserialised rosbags message objects, so one conversion serves all.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.summary import Summary
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from robot_logs.decoding import MessageDecoder, ros2_type_name
from robot_logs.errors import LogError
from robot_logs.ros1_records import BagConnection, BagMessage, walk_bag


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a log: its name, message type (ROS 2 spelling) and message count."""

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class Message:
    """One message: topic, type, record time (ns, the logger's clock) and the decoded object."""

    topic: str
    msgtype: str
    record_ns: int
    data: object


def _summarise(pairs: Collection[tuple[str, str]], counts: Counter[str]) -> list[TopicInfo]:
    return [TopicInfo(topic, msgtype, counts[topic]) for topic, msgtype in sorted(set(pairs))]


class RosbagsSource:
    """ROS1 `.bag` files, ROS2 bag folders and `.db3` files via rosbags' AnyReader."""

    def __init__(self, path: Path, salvage: bool = False) -> None:
        self.salvage = salvage
        self.damage: str | None = None
        self._reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
        self._reader.open()

    def topics(self) -> list[TopicInfo]:
        counts: Counter[str] = Counter()
        for connection in self._reader.connections:
            counts[connection.topic] += connection.msgcount
        pairs = [(c.topic, c.msgtype) for c in self._reader.connections]
        return _summarise(pairs, counts)

    def messages(self, topics: Collection[str]) -> Iterator[Message]:
        connections = [c for c in self._reader.connections if c.topic in topics]
        for connection, record_ns, raw in self._reader.messages(connections=connections):
            try:
                data = self._reader.deserialize(raw, connection.msgtype)
            except Exception as exc:  # a garbled message: skipped when salvaging
                self.damage = self.damage or f"undecodable message on {connection.topic}: {exc}"
                if not self.salvage:
                    raise
                continue
            yield Message(connection.topic, connection.msgtype, record_ns, data)

    def close(self) -> None:
        self._reader.close()


_ROS_ENCODINGS = {("ros1msg", "ros1"): "msg", ("ros2msg", "cdr"): "msg", ("ros2idl", "cdr"): "idl"}


class McapSource:
    """Plain MCAP files (or a ROS2 bag's MCAP storage files) through the `mcap` library.

    Messages encoded as ROS1 or CDR with embedded definitions are decoded; other encodings
    (JSON, protobuf...) are listed by `topics()` but cannot be read as robot data. With
    `salvage`, chunks that fail their CRC are skipped (`damage` says so), and a file without
    a readable summary (truncated) is read in file order up to its first damaged record.
    """

    def __init__(self, files: list[Path], salvage: bool = False) -> None:
        self.files = files
        self.salvage = salvage
        self.damage: str | None = None
        self._decoder = MessageDecoder()
        self._schemas: dict[tuple[int, int], Schema] = {}
        self._channels: dict[tuple[int, int], tuple[Channel, Schema | None]] = {}
        self._counts: Counter[str] = Counter()
        self._summaries: dict[int, Summary] = {}
        for index, path in enumerate(files):
            try:
                self._read_summary(index, path)
            except Exception:
                if not salvage:
                    raise
                for _ in self._walk(index, path, topics=None):
                    pass

    def _read_summary(self, index: int, path: Path) -> None:
        with path.open("rb") as stream:
            summary = SeekingReader(stream, validate_crcs=True).get_summary()
        if summary is None or not summary.chunk_indexes:
            raise LogError(f"{path} has no summary section (an unfinished recording); pass --salvage to read it in file order")
        self._summaries[index] = summary
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            self._channels[index, channel.id] = (channel, schema)
        stats = summary.statistics
        for channel_id, count in (stats.channel_message_counts if stats else {}).items():
            self._counts[summary.channels[channel_id].topic] += count

    def _note(self, path: Path, exc: Exception) -> None:
        self.damage = self.damage or f"{path.name}: {type(exc).__name__} {exc}".strip()

    def _walk(self, index: int, path: Path, topics: Collection[str] | None) -> Iterator[McapMessage]:
        """Records in file order; a damaged record ends the walk (noted in `damage`)."""
        counting = topics is None
        with path.open("rb") as stream:
            try:
                for record in StreamReader(stream, validate_crcs=True).records:
                    if isinstance(record, Schema):
                        self._schemas[index, record.id] = record
                    elif isinstance(record, Channel):
                        self._channels[index, record.id] = (record, self._schemas.get((index, record.schema_id)))
                    elif isinstance(record, McapMessage):
                        channel = self._channels[index, record.channel_id][0]
                        if counting:
                            self._counts[channel.topic] += 1
                        elif channel.topic in topics:
                            yield record
            except Exception as exc:  # any malformed byte ends the readable part
                self._note(path, exc)

    def _chunks(self, index: int, path: Path, topics: Collection[str]) -> Iterator[McapMessage]:
        """Messages chunk by chunk, skipping chunks that fail to read or to pass their CRC."""
        summary = self._summaries[index]
        wanted = {c.id for c in summary.channels.values() if c.topic in topics}
        with path.open("rb") as stream:
            for chunk_index in sorted(summary.chunk_indexes, key=lambda c: c.message_start_time):
                try:
                    stream.seek(chunk_index.chunk_start_offset + 9)
                    records = breakup_chunk(Chunk.read(ReadDataStream(stream)), validate_crc=True)
                except Exception as exc:  # a damaged chunk is skipped, the others still read
                    self._note(path, exc)
                    continue
                found = [r for r in records if isinstance(r, McapMessage) and r.channel_id in wanted]
                yield from sorted(found, key=lambda r: r.log_time)

    def topics(self) -> list[TopicInfo]:
        pairs = [(channel.topic, self._msgtype(channel, schema)) for channel, schema in self._channels.values()]
        return _summarise(pairs, self._counts)

    @staticmethod
    def _msgtype(channel: Channel, schema: Schema | None) -> str:
        if schema is None:
            return f"(no schema, {channel.message_encoding})"
        if (schema.encoding, channel.message_encoding) in _ROS_ENCODINGS:
            return ros2_type_name(schema.name)
        return schema.name

    def _decode(self, index: int, record: McapMessage) -> Message:
        channel, schema = self._channels[index, record.channel_id]
        kind = _ROS_ENCODINGS.get((schema.encoding if schema else "", channel.message_encoding))
        if kind is None or schema is None:
            raise LogError(
                f"topic {channel.topic} of {self.files[index]} is encoded as {channel.message_encoding!r}; "
                "robot_logs reads ROS1 and ROS2 (CDR) messages"
            )
        self._decoder.add(schema.name, schema.data.decode(), kind)
        data = self._decoder.decode(record.data, schema.name, channel.message_encoding)
        return Message(channel.topic, ros2_type_name(schema.name), record.log_time, data)

    def messages(self, topics: Collection[str]) -> Iterator[Message]:
        for index, path in enumerate(self.files):
            if index not in self._summaries:
                records = self._walk(index, path, topics)
            elif self.salvage:
                records = self._chunks(index, path, topics)
            else:
                records = self._indexed(path, topics)
            for record in records:
                try:
                    message = self._decode(index, record)
                except LogError:
                    raise
                except Exception as exc:  # a garbled message: skipped when salvaging
                    if not self.salvage:
                        raise
                    self._note(path, exc)
                    continue
                yield message

    @staticmethod
    def _indexed(path: Path, topics: Collection[str]) -> Iterator[McapMessage]:
        with path.open("rb") as stream:
            reader = SeekingReader(stream, validate_crcs=True)
            for _, _, record in reader.iter_messages(topics=list(topics), log_time_order=True):
                yield record

    def close(self) -> None:
        """Nothing stays open between calls."""


class BagWalkSource:
    """A ROS1 bag read record by record up to its first damaged byte (`damage` says where)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.damage: str | None = None
        self._decoder = MessageDecoder()
        self._connections: dict[int, BagConnection] = {}
        self._counts: Counter[str] = Counter()
        for item in self._walk():
            if isinstance(item, BagMessage):
                self._counts[self._connections[item.conn_id].topic] += 1

    def _walk(self) -> Iterator[BagConnection | BagMessage]:
        with self.path.open("rb") as stream:
            try:
                for item in walk_bag(stream):
                    if isinstance(item, BagConnection):
                        self._connections[item.conn_id] = item
                        self._decoder.add(item.msgtype, item.definition)
                    yield item
            except Exception as exc:  # any malformed byte ends the readable part
                self.damage = f"{self.path.name}: {exc}"

    def topics(self) -> list[TopicInfo]:
        pairs = [(c.topic, ros2_type_name(c.msgtype)) for c in self._connections.values()]
        return _summarise(pairs, self._counts)

    def messages(self, topics: Collection[str]) -> Iterator[Message]:
        for item in self._walk():
            if isinstance(item, BagMessage):
                connection = self._connections[item.conn_id]
                if connection.topic in topics:
                    try:
                        data = self._decoder.decode(item.data, connection.msgtype, "ros1")
                    except Exception as exc:  # a garbled message is skipped
                        self.damage = self.damage or f"undecodable message on {connection.topic}: {exc}"
                        continue
                    yield Message(connection.topic, ros2_type_name(connection.msgtype), item.record_ns, data)

    def close(self) -> None:
        """Nothing stays open between calls."""
