"""The raw message sources behind `LogReader`, one per way of opening a log.

- `Ros1Source`: ROS1 bags through rosbags' rosbag1 reader.
- `Rosbag2Source`: ROS2 sqlite3 storage files (a bag folder's or a lone `.db3`) through rosbags,
  each file read on its own, so a folder and its files give the same counts.
- `McapSource`: MCAP files (plain, or a ROS2 bag folder's storage) through the `mcap` library, in
  any valid layout: indexed files by their index, the others (no chunk index, no summary,
  unchunked) by streaming; with `salvage=True` it skips damaged chunks, or reads a truncated
  file up to the damage.
- `BagWalkSource`: a ROS1 bag read record by record, for bags whose index is damaged.

Each yields `RawMessage`s: bytes with their `MessageType`; `robot_logs.decoding` decodes them.
"""

from __future__ import annotations

import sqlite3
from collections import Counter
from collections.abc import Callable, Collection, Iterator
from contextlib import closing
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Schema
from mcap.records import Message as McapMessage
from mcap.summary import Summary
from rosbags.interfaces import Connection, MessageDefinitionFormat
from rosbags.rosbag1 import Reader as Ros1Reader
from rosbags.rosbag2 import Reader as Rosbag2Reader

from robot_logs.decoding import CDR, ROS1, MessageType, is_service, ros2_type_name
from robot_logs.inflate import InflateError, inflate
from robot_logs.mcap_chunks import chunk_records, indexed_messages, stream_records
from robot_logs.ros1_records import BagConnection, BagMessage, chunk_header, walk_bag


class SourceDamaged(Exception):
    """Bytes of a log that are not a complete, valid record; the text says where."""


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a log: its name, message type (ROS 2 spelling or schema name), message count and encoding."""

    name: str
    msgtype: str
    count: int
    encoding: str

    @property
    def service(self) -> bool:
        """True for a topic of recorded service events."""
        return is_service(self.msgtype)


@dataclass(frozen=True)
class RawMessage:
    """One message as stored: topic, type, record time (ns, the logger's clock) and bytes."""

    topic: str
    mtype: MessageType
    record_ns: int
    data: bytes | memoryview


def _summarise(counts: Counter[tuple[str, MessageType]]) -> list[TopicInfo]:
    totals: Counter[tuple[str, str, str]] = Counter()
    for (topic, mtype), count in counts.items():
        totals[topic, mtype.name, mtype.encoding] += count
    return [TopicInfo(topic, name, count, encoding) for (topic, name, encoding), count in sorted(totals.items())]


def _rosbags_type(connection: Connection, encoding: str) -> MessageType:
    return MessageType(
        connection.msgtype, encoding, connection.msgdef.data or "", connection.msgdef.format == MessageDefinitionFormat.IDL
    )


def _per_message(compressed: bool) -> Callable[[bytes], bytes] | None:
    """How the messages of a ROS2 bag compressed message by message (zstd) are decompressed: within `inflate`'s bound."""
    return partial(inflate, compression="zstd") if compressed else None


class Ros1Source:
    """A ROS1 `.bag` file through rosbags (its index must be intact); its chunks decompressed within the size each
    declares (`inflate`), where rosbags would decompress them whole."""

    distro = None

    def __init__(self, path: Path) -> None:
        self._reader = Ros1Reader(path)
        self._reader.open()
        self._types = {c.id: _rosbags_type(c, ROS1) for c in self._reader.connections}
        with path.open("rb") as stream:
            for position, chunk in self._reader.chunks.items():
                compression, declared = chunk_header(stream, position)
                self._reader.chunks[position] = chunk._replace(decompressor=partial(inflate, compression=compression, declared=declared))

    def topics(self) -> list[TopicInfo]:
        counts: Counter[tuple[str, MessageType]] = Counter()
        for connection in self._reader.connections:
            counts[connection.topic, self._types[connection.id]] += connection.msgcount
        return _summarise(counts)

    def messages(self, topics: Collection[str]) -> Iterator[RawMessage]:
        connections = [c for c in self._reader.connections if c.topic in topics]
        if not connections:  # rosbags reads every connection when given none
            return
        for connection, record_ns, raw in self._reader.messages(connections=connections):
            yield RawMessage(connection.topic, self._types[connection.id], record_ns, raw)

    def close(self) -> None:
        self._reader.close()


class Rosbag2Source:
    """ROS2 sqlite3 storage files (in bag order) through rosbags, each file opened on its own.

    Args:
        files: the `.db3` files.
        distro: the bag's `ros_distro` from its metadata, if any.
        compressed: messages are zstd-compressed one by one (metadata compression_mode 'message').
    """

    def __init__(self, files: list[Path], distro: str | None = None, compressed: bool = False) -> None:
        self.distro = distro or (_sqlite_distro(files[0]) if files else None)
        self._decompress = _per_message(compressed)
        self._readers: list[Rosbag2Reader] = []
        for path in files:
            reader = Rosbag2Reader(path)
            reader.open()
            self._readers.append(reader)

    def topics(self) -> list[TopicInfo]:
        counts: Counter[tuple[str, MessageType]] = Counter()
        for reader in self._readers:
            for connection in reader.connections:
                counts[connection.topic, _rosbags_type(connection, CDR)] += connection.msgcount
        return _summarise(counts)

    def messages(self, topics: Collection[str]) -> Iterator[RawMessage]:
        for reader in self._readers:
            connections = [c for c in reader.connections if c.topic in topics]
            if not connections:  # rosbags reads every connection when given none
                continue
            types = {c.id: _rosbags_type(c, CDR) for c in connections}
            for connection, record_ns, raw in reader.messages(connections=connections):
                data = self._decompress(raw) if self._decompress else raw
                yield RawMessage(connection.topic, types[connection.id], record_ns, data)

    def close(self) -> None:
        for reader in self._readers:
            reader.close()


def _sqlite_distro(path: Path) -> str | None:
    """The ROS distribution a sqlite3 storage file records in its `schema` table (newer recorders), if any."""
    with closing(sqlite3.connect(f"file:{path}?immutable=1", uri=True)) as database:
        try:
            row = database.execute("SELECT ros_distro FROM schema").fetchone()
        except sqlite3.Error:  # older files have no schema table
            return None
    return str(row[0]) if row and row[0] else None


def _mcap_type(channel: Channel, schema: Schema | None) -> MessageType:
    """The `MessageType` of an MCAP channel: ROS types in ROS 2 spelling with their schema text."""
    encoding = channel.message_encoding
    if schema is None:
        return MessageType("(no schema)", encoding)
    name = ros2_type_name(schema.name) if encoding in (ROS1, CDR) else schema.name
    definition = schema.data.decode(errors="replace") if schema.encoding in ("ros1msg", "ros2msg", "ros2idl") else ""
    return MessageType(name, encoding, definition, schema.encoding == "ros2idl")


class McapSource:
    """MCAP files in order, in any valid layout (see the module docstring).

    Args:
        files: the MCAP files (one, or the storage files of a split ROS2 bag).
        distro: the bag's `ros_distro` from its metadata, if any.
        salvage: skip damaged chunks and read truncated files up to the cut instead of raising.
        compressed: messages are zstd-compressed one by one (a bag's compression_mode 'message').

    Raises:
        SourceDamaged: a file without an index breaks off or holds a malformed record (salvage off).
    """

    def __init__(self, files: list[Path], distro: str | None = None, salvage: bool = False, compressed: bool = False) -> None:
        self.files = files
        self.distro = distro
        self.salvage = salvage
        self._decompress = _per_message(compressed)
        self.damage: str | None = None
        self._schemas: dict[tuple[int, int], Schema] = {}
        self._types: dict[tuple[int, int], tuple[str, MessageType]] = {}
        self._counts: Counter[tuple[str, MessageType]] = Counter()
        self._summaries: dict[int, Summary] = {}
        for index, path in enumerate(files):
            summary = _usable_summary(path)
            if summary is None:
                for _ in self._walk(index, path, topics=None):
                    pass
                continue
            self._summaries[index] = summary
            for channel in summary.channels.values():
                self._types[index, channel.id] = (channel.topic, _mcap_type(channel, summary.schemas.get(channel.schema_id)))
                self._counts[self._types[index, channel.id]] += 0  # listed even without messages
            assert summary.statistics is not None  # a usable summary has them
            for channel_id, count in summary.statistics.channel_message_counts.items():
                self._counts[self._types[index, channel_id]] += count

    def _note(self, path: Path, exc: Exception) -> None:
        self.damage = self.damage or _what(path, exc)

    def _walk(self, index: int, path: Path, topics: Collection[str] | None) -> Iterator[McapMessage]:
        """Records in file order (counting them when `topics` is None).

        A damaged record ends the walk: noted in `damage` when salvaging, raised otherwise.
        """
        counting = topics is None
        with path.open("rb") as stream:
            try:
                for record in stream_records(stream):
                    if isinstance(record, Schema):
                        self._schemas[index, record.id] = record
                    elif isinstance(record, Channel):
                        schema = self._schemas.get((index, record.schema_id))
                        self._types[index, record.id] = (record.topic, _mcap_type(record, schema))
                        if counting:
                            self._counts[self._types[index, record.id]] += 0  # listed even without messages
                    elif isinstance(record, McapMessage):
                        known = self._types[index, record.channel_id]
                        if counting:
                            self._counts[known] += 1
                        elif known[0] in topics:
                            yield record
            except Exception as exc:  # any malformed byte ends the readable part
                if not self.salvage:
                    raise SourceDamaged(_what(path, exc)) from None
                self._note(path, exc)

    def _chunks(self, index: int, path: Path, topics: Collection[str]) -> Iterator[McapMessage]:
        """Messages chunk by chunk, skipping chunks that fail to read or to pass their CRC."""
        summary = self._summaries[index]
        wanted = {c.id for c in summary.channels.values() if c.topic in topics}
        with path.open("rb") as stream:
            for chunk_index in sorted(summary.chunk_indexes, key=lambda c: c.message_start_time):
                try:
                    stream.seek(chunk_index.chunk_start_offset + 9)  # past the opcode and length
                    records = chunk_records(Chunk.read(ReadDataStream(stream)))
                except Exception as exc:  # a damaged chunk is skipped, the others still read
                    self._note(path, exc)
                    continue
                found = [r for r in records if isinstance(r, McapMessage) and r.channel_id in wanted]
                yield from sorted(found, key=lambda r: r.log_time)

    def _indexed(self, index: int, path: Path, topics: Collection[str]) -> Iterator[McapMessage]:
        summary = self._summaries[index]
        with path.open("rb") as stream:
            yield from indexed_messages(stream, summary, {c.id for c in summary.channels.values() if c.topic in topics})

    def topics(self) -> list[TopicInfo]:
        return _summarise(self._counts)

    def messages(self, topics: Collection[str]) -> Iterator[RawMessage]:
        for index, path in enumerate(self.files):
            if index not in self._summaries:
                records = self._walk(index, path, topics)
            elif self.salvage:
                records = self._chunks(index, path, topics)
            else:
                records = self._indexed(index, path, topics)
            for record in records:
                topic, mtype = self._types[index, record.channel_id]
                data = self._decompress(record.data) if self._decompress else record.data
                yield RawMessage(topic, mtype, record.log_time, data)

    def close(self) -> None:
        """Nothing stays open between calls."""


def _what(path: Path, exc: Exception) -> str:
    """A damaged MCAP record in words: the file, and the error (named by type where mcap's own text is terse)."""
    return f"{path.name}: {exc}" if isinstance(exc, InflateError) else f"{path.name}: {type(exc).__name__} {exc}".strip()


def _usable_summary(path: Path) -> Summary | None:
    """A file's summary if it indexes every message (chunk indexes, channels, statistics), else None.

    Files without one are valid MCAP too (the summary and indexes are optional); they are
    streamed. A damaged end also gives None: the stream then finds where the damage is.
    """
    try:
        with path.open("rb") as stream:
            summary = SeekingReader(stream, validate_crcs=True).get_summary()
    except Exception:  # no footer, a cut or garbled summary: stream the file instead
        return None
    if summary is None or not summary.chunk_indexes or summary.statistics is None:
        return None
    stats = summary.statistics
    if len(summary.chunk_indexes) != stats.chunk_count or any(c not in summary.channels for c in stats.channel_message_counts):
        return None
    return summary


class BagWalkSource:
    """A ROS1 bag read record by record up to its first damaged byte (`damage` says where)."""

    distro = None

    def __init__(self, path: Path) -> None:
        self.path = path
        self.damage: str | None = None
        self._connections: dict[int, tuple[str, MessageType]] = {}
        self._counts: Counter[tuple[str, MessageType]] = Counter()
        for item in self._walk():
            if isinstance(item, BagMessage):
                self._counts[self._connections[item.conn_id]] += 1

    def _walk(self) -> Iterator[BagConnection | BagMessage]:
        with self.path.open("rb") as stream:
            try:
                for item in walk_bag(stream):
                    if isinstance(item, BagConnection):
                        self._connections[item.conn_id] = (item.topic, MessageType(ros2_type_name(item.msgtype), ROS1, item.definition))
                        self._counts[self._connections[item.conn_id]] += 0  # listed even without messages
                    yield item
            except Exception as exc:  # any malformed byte ends the readable part
                self.damage = f"{self.path.name}: {exc}"

    def topics(self) -> list[TopicInfo]:
        return _summarise(self._counts)

    def messages(self, topics: Collection[str]) -> Iterator[RawMessage]:
        for item in self._walk():
            if isinstance(item, BagMessage):
                topic, mtype = self._connections[item.conn_id]
                if topic in topics:
                    yield RawMessage(topic, mtype, item.record_ns, item.data)

    def close(self) -> None:
        """Nothing stays open between calls."""
