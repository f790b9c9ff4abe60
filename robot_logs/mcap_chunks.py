"""MCAP records and messages read with every chunk decompressed through `robot_logs.inflate`, within the size the
chunk declares: the `mcap` library decompresses a chunk to whatever size its data gives (or its zstd frame claims)."""

from __future__ import annotations

import heapq
from collections.abc import Collection, Iterator
from dataclasses import replace
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.records import Chunk, ChunkIndex, McapRecord
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.summary import Summary

from robot_logs.inflate import inflate

#: A chunk record's opcode and length, before its fields.
RECORD_PREFIX = 9


def chunk_records(chunk: Chunk) -> list[McapRecord]:
    """The records of a chunk, decompressed within its declared `uncompressed_size` and checked against its CRC.

    Raises:
        InflateError: the chunk expands beyond its declared size (or the most any chunk may have), or is damaged.
        mcap's errors: a CRC that does not match, a malformed record.
    """
    data = inflate(chunk.data, chunk.compression, chunk.uncompressed_size)
    return breakup_chunk(replace(chunk, compression="", data=data), validate_crc=True)


def stream_records(stream: BinaryIO) -> Iterator[McapRecord]:
    """Every record of an MCAP file in file order, the records of each chunk in its place (as mcap's
    `StreamReader(...).records` gives them), CRCs checked."""
    for record in StreamReader(stream, validate_crcs=True, emit_chunks=True).records:
        if isinstance(record, Chunk):
            yield from chunk_records(record)
        else:
            yield record


def indexed_messages(stream: BinaryIO, summary: Summary, channels: Collection[int]) -> Iterator[McapMessage]:
    """The messages of `channels` in log-time order (ties in file order), through the summary's chunk indexes as
    mcap's `SeekingReader.iter_messages` reads them: a chunk is opened only when its first message is due."""
    # (log time, chunk offset, place in the chunk or -1 for the chunk itself, item): every key is unique
    queue: list[tuple[int, int, int, ChunkIndex | McapMessage]] = []
    for index in summary.chunk_indexes:
        if not index.message_index_offsets or any(channel in channels for channel in index.message_index_offsets):
            heapq.heappush(queue, (index.message_start_time, index.chunk_start_offset, -1, index))
    while queue:
        _, offset, _, item = heapq.heappop(queue)
        if isinstance(item, McapMessage):
            yield item
            continue
        stream.seek(item.chunk_start_offset + RECORD_PREFIX)
        for place, record in enumerate(chunk_records(Chunk.read(ReadDataStream(stream)))):
            if isinstance(record, McapMessage) and record.channel_id in channels:
                heapq.heappush(queue, (record.log_time, offset, place, record))
