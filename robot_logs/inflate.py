"""Decompressing a log's chunks and files within a bound, so that a few kilobytes crafted to expand to gigabytes
(a decompression bomb) are refused after at most the bound's worth of work and memory.

A chunk (an MCAP chunk, a ROS 1 bag chunk, a message of a ROS 2 bag compressed per message) may expand to the size
it declares and never beyond `MAX_CHUNK_BYTES`; a storage file of a ROS 2 bag compressed as whole files, which
declares no size, to `MAX_FILE_RATIO` times its compressed size (at least `MAX_CHUNK_BYTES`).
"""

from __future__ import annotations

import bz2
import io
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

import lz4.frame
import zstandard

#: The most one chunk may expand to: far above real chunks (rosbag2 and Foxglove write 1-4 MiB ones, a ROS 1
#: bag 768 KiB) and the largest single messages (a dense point cloud, a 4K image: tens of MiB).
MAX_CHUNK_BYTES = 256 * 2**20
#: The most a whole compressed storage file may expand, as a multiple of its compressed size: recorded sensor
#: data compresses a few times, a bomb thousands of times (zstd reaches 32,000:1 on zeros).
MAX_FILE_RATIO = 1000
#: Bytes read at a time when a whole file is decompressed to disk.
PIECE = 2**20


class InflateError(ValueError):
    """Compressed bytes that do not decompress, or would expand beyond their bound; the text says which."""


def inflate(data: bytes, compression: str, declared: int | None = None) -> bytes:
    """`data` decompressed ('zstd', 'lz4', 'bz2'; '' or 'none' is stored as is), at most `declared` bytes
    (the size its container records, if any) and never more than MAX_CHUNK_BYTES.

    Raises:
        InflateError: the chunk declares more than MAX_CHUNK_BYTES, expands beyond its bound, is damaged, or
            uses another compression.
    """
    if compression in ("", "none"):
        return data
    if declared is not None and declared > MAX_CHUNK_BYTES:
        raise InflateError(f"a {compression} chunk declares {declared:,} bytes uncompressed, more than the {MAX_CHUNK_BYTES:,} a chunk may have")
    limit = MAX_CHUNK_BYTES if declared is None else declared
    bound = f"the {limit:,} bytes it declares" if declared is not None else f"{limit:,} bytes, the most a chunk may have"
    if compression == "zstd":
        return _zstd(data, limit, bound)
    openers: dict[str, Callable[[BinaryIO], BinaryIO]] = {"lz4": lz4.frame.open, "bz2": bz2.open}
    if compression not in openers:
        raise InflateError(f"unknown chunk compression {compression!r} (expected zstd, lz4, bz2 or none)")
    try:
        with openers[compression](io.BytesIO(data)) as stream:
            out = stream.read(limit + 1)  # reading stops one byte past the bound, however far the data would go
    except (OSError, EOFError, RuntimeError, ValueError) as exc:
        raise InflateError(f"a {compression} chunk does not decompress ({exc})") from None
    if len(out) > limit:
        raise InflateError(f"a {compression} chunk expands beyond {bound}")
    return out


def _zstd(data: bytes, limit: int, bound: str) -> bytes:
    """One zstd frame within `limit` bytes. zstandard sizes its output by the size the frame header records,
    ignoring any smaller limit, so that size is checked first; a frame without one is capped at `limit`."""
    try:
        recorded = zstandard.frame_content_size(data)
    except zstandard.ZstdError as exc:
        raise InflateError(f"a zstd chunk does not decompress ({exc})") from None
    if recorded > limit:
        raise InflateError(f"a zstd chunk expands beyond {bound} (its frame records {recorded:,})")
    try:
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=limit)
    except zstandard.ZstdError as exc:  # a frame going past the limit fails as a damaged one does: tell them apart
        raise InflateError(f"a zstd chunk expands beyond {bound}" if _longer(data, limit) else f"a zstd chunk does not decompress ({exc})") from None


def _longer(data: bytes, limit: int) -> bool:
    """Whether the zstd `data` decompresses to more than `limit` bytes (reading at most one byte more)."""
    try:
        with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data)) as stream:
            return len(stream.read(limit + 1)) > limit
    except zstandard.ZstdError:
        return False


def inflate_file(source: Path, target: Path, magic: bytes, what: str) -> None:
    """Decompress a zstd-compressed storage file `source` to `target`, refusing at once one whose decompressed
    bytes do not start with `magic` (`what` names that format), and one that expands beyond MAX_FILE_RATIO times
    its size (at least MAX_CHUNK_BYTES) after writing no more than that.

    Raises:
        InflateError: as above, or the file does not decompress.
    """
    size = source.stat().st_size
    limit = max(MAX_CHUNK_BYTES, MAX_FILE_RATIO * size)
    try:
        with source.open("rb") as raw, zstandard.ZstdDecompressor().stream_reader(raw, read_across_frames=True) as stream, target.open("wb") as out:
            head = stream.read(len(magic))
            if head != magic:
                raise InflateError(f"{source.name} does not decompress to {what} (its first bytes are not {what}'s)")
            out.write(head)
            written = len(head)
            while piece := stream.read(min(PIECE, limit + 1 - written)):
                written += len(piece)
                if written > limit:
                    raise InflateError(f"{source.name} expands beyond {limit:,} bytes, the most a storage file of {size:,} bytes "
                                       f"compressed may give ({MAX_FILE_RATIO}:1, at least {MAX_CHUNK_BYTES:,})")
                out.write(piece)
    except zstandard.ZstdError as exc:
        raise InflateError(f"{source.name} does not decompress ({exc})") from None
