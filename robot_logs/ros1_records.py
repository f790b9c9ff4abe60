"""Reading a ROS1 bag record by record, for bags whose index is missing or damaged.

rosbags reads a bag through the index written at its end, so a truncated bag does not open.
A bag is a sequence of records (header length, header fields, data length, data); message
and connection records sit inside chunks. Walking them in order recovers every message up to
the first damaged byte.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from typing import BinaryIO

from robot_logs.inflate import InflateError, inflate

MAGIC = b"#ROSBAG V2.0\n"
OP_MESSAGE, OP_CHUNK, OP_CONNECTION = 0x02, 0x05, 0x07


class BagDamaged(Exception):
    """The record walk met bytes that are not a complete, valid record."""


@dataclass(frozen=True)
class BagConnection:
    """A connection record: topic, ROS1 message type and its full .msg definition."""

    conn_id: int
    topic: str
    msgtype: str
    definition: str


@dataclass(frozen=True)
class BagMessage:
    """A message data record: its connection, record time (ns) and serialised bytes."""

    conn_id: int
    record_ns: int
    data: bytes


def _fields(blob: bytes) -> dict[str, bytes]:
    fields, pos = {}, 0
    while pos < len(blob):
        if pos + 4 > len(blob):
            raise BagDamaged("record header field cut short")
        (size,) = struct.unpack_from("<I", blob, pos)
        entry = blob[pos + 4 : pos + 4 + size]
        if len(entry) != size or b"=" not in entry:
            raise BagDamaged("malformed record header field")
        name, value = entry.split(b"=", 1)
        fields[name.decode("ascii", "replace")] = value
        pos += 4 + size
    return fields


def _records(stream: BinaryIO) -> Iterator[tuple[dict[str, bytes], bytes]]:
    while head := stream.read(4):
        if len(head) < 4:
            raise BagDamaged("record cut short")
        (header_size,) = struct.unpack("<I", head)
        header = stream.read(header_size)
        size_bytes = stream.read(4)
        if len(header) != header_size or len(size_bytes) != 4:
            raise BagDamaged("record header cut short")
        (data_size,) = struct.unpack("<I", size_bytes)
        data = stream.read(data_size)
        if len(data) != data_size:
            raise BagDamaged("record data cut short")
        fields = _fields(header)
        if "op" not in fields:
            raise BagDamaged("record without an op code")
        yield fields, data


def _chunk_compression(fields: dict[str, bytes]) -> tuple[str, int | None]:
    """A chunk record's compression and the uncompressed size it declares (its `size` field, if there is one)."""
    size = fields.get("size", b"")
    return fields.get("compression", b"none").decode("ascii", "replace"), struct.unpack("<I", size)[0] if len(size) == 4 else None


def chunk_header(stream: BinaryIO, position: int) -> tuple[str, int | None]:
    """The compression and declared uncompressed size of the chunk record at `position` in a bag.

    Raises:
        BagDamaged: there is no complete record header there.
    """
    stream.seek(position)
    head = stream.read(4)
    if len(head) < 4:
        raise BagDamaged(f"chunk record at byte {position} cut short")
    header = stream.read(struct.unpack("<I", head)[0])
    return _chunk_compression(_fields(header))


def _connection(fields: dict[str, bytes], data: bytes) -> BagConnection:
    info = _fields(data)
    return BagConnection(
        conn_id=struct.unpack("<I", fields["conn"])[0],
        topic=fields["topic"].decode(),
        msgtype=info["type"].decode(),
        definition=info.get("message_definition", b"").decode(),
    )


def _message(fields: dict[str, bytes], data: bytes) -> BagMessage:
    sec, nsec = struct.unpack("<II", fields["time"])
    return BagMessage(struct.unpack("<I", fields["conn"])[0], sec * 1_000_000_000 + nsec, data)


def walk_bag(stream: BinaryIO) -> Iterator[BagConnection | BagMessage]:
    """Connections and messages of a bag in file order.

    Raises:
        BagDamaged: at the first record that is cut short or malformed (everything before it
            has been yielded).
    """
    if stream.read(len(MAGIC)) != MAGIC:
        raise BagDamaged("not a ROS1 bag (no '#ROSBAG V2.0' magic)")
    for fields, data in _records(stream):
        if fields["op"][0] != OP_CHUNK:
            continue
        compression, declared = _chunk_compression(fields)
        try:
            payload = inflate(data, compression, declared)
        except InflateError as exc:
            raise BagDamaged(str(exc)) from None
        for inner, inner_data in _records(io.BytesIO(payload)):
            try:
                if inner["op"][0] == OP_CONNECTION:
                    yield _connection(inner, inner_data)
                elif inner["op"][0] == OP_MESSAGE:
                    yield _message(inner, inner_data)
            except (KeyError, struct.error, UnicodeDecodeError) as exc:
                raise BagDamaged(f"malformed record in a chunk: {exc!r}") from None

