"""Logs that would stall or swell a reader: a FIFO named like a log, chunks that decompress beyond the size they
declare (MCAP zstd and lz4, a ROS 1 bz2 chunk), a ROS 2 bag compressed as whole files that inflates to junk.

Each is refused in one `error:` line naming the file and the bound, exit code 2, after at most the bound's worth
of work: a deadline guards every read so that a reader that would stall fails the test instead of hanging it.
"""

from __future__ import annotations

import bz2
import json
import os
import signal
import tempfile
import tracemalloc
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import lz4.frame
import mcap.writer
import pytest
import zstandard
from mcap.writer import MCAP0_MAGIC, CompressionType, IndexType, Writer
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import CompressionMode

import robot_logs.inflate
from robot_logs.frames import Pose2D
from robot_logs.inflate import InflateError, inflate
from robot_logs.records import Odometry
from tests.support.bag_writer import BagWriter
from trials.cli import main

#: What each bomb adds beyond the chunk it declares: small enough that the code before these bounds read it
#: (slowly) in the quick loop, large against every bound the tests set.
PAD = 8 * 2**20
NO_SUMMARY = {"index_types": IndexType.NONE, "repeat_channels": False, "repeat_schemas": False, "use_statistics": False,
              "use_summary_offsets": False, "use_chunking": True}


class Stalled(BaseException):
    """A read still going at its deadline (a BaseException, so no error handling on the way turns it into a refusal)."""


@contextmanager
def deadline(seconds: float) -> Iterator[None]:
    """Raise Stalled in the test if the block runs longer than `seconds`: generous, a guard and not a measurement."""

    def expire(signum: int, frame: object) -> None:
        raise Stalled(f"still reading after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def log_command(capsys: pytest.CaptureFixture[str], *args: object) -> tuple[int, str]:
    """`trials log ARGS` under a deadline: its exit code and its one `error:` line (or its output when it succeeds)."""
    with deadline(20):
        code = main(["log", *map(str, args)])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) <= 1, lines
    return code, lines[0] if lines else out


@pytest.mark.parametrize("name", ["x.bag", "x.mcap"])
def test_a_fifo_named_like_a_log_is_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str) -> None:
    fifo = tmp_path / name
    os.mkfifo(fifo)
    code, line = log_command(capsys, "inspect", fifo)
    assert code == 2 and line == f"error: {fifo} is not a regular file or a folder, so not a log"


def write_mcap(path: Path, compression: CompressionType, **options: object) -> None:
    """Three small JSON messages on one topic, in one chunk."""
    with path.open("wb") as stream:
        writer = Writer(stream, compression=compression, enable_crcs=False, **options)  # type: ignore[arg-type]
        writer.start()
        schema = writer.register_schema("Note", "jsonschema", b'{"type": "object"}')
        channel = writer.register_channel("/note", "json", schema)
        for k in range(3):
            writer.add_message(channel, log_time=k, publish_time=k, data=json.dumps({"k": k}).encode())
        writer.finish()


#: The mcap writer's compressors replaced by ones that add PAD zero bytes to what they compress; the chunk still
#: declares its own size (the CRC is off, as an MCAP may leave it, so only the size can tell).
BOMBS: dict[str, tuple[CompressionType, Callable[[pytest.MonkeyPatch], None]]] = {
    "zstd": (CompressionType.ZSTD, lambda patch: patch.setattr(
        mcap.writer, "zstandard", SimpleNamespace(compress=lambda data: zstandard.compress(data + bytes(PAD)))),),
    "zstd-unsized": (CompressionType.ZSTD, lambda patch: patch.setattr(mcap.writer, "zstandard", SimpleNamespace(
        compress=lambda data: zstandard.ZstdCompressor(write_content_size=False).compress(data + bytes(PAD))))),
    "lz4": (CompressionType.LZ4, lambda patch: patch.setattr(
        mcap.writer, "lz4", SimpleNamespace(frame=SimpleNamespace(compress=lambda data: lz4.frame.compress(data + bytes(PAD)))))),
}


@pytest.mark.parametrize("layout", ["indexed", "no-summary"])
@pytest.mark.parametrize("bomb", sorted(BOMBS))
def test_an_mcap_chunk_expanding_beyond_its_declared_size_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, bomb: str, layout: str) -> None:
    path = tmp_path / "bomb.mcap"
    compression, arm = BOMBS[bomb]
    with monkeypatch.context() as patch:
        arm(patch)
        write_mcap(path, compression, **(NO_SUMMARY if layout == "no-summary" else {}))
    assert path.stat().st_size < 100_000
    code, line = log_command(capsys, "inspect", path)
    assert code == 2 and line.startswith(f"error: {path} is damaged (truncated or corrupt: ")
    kind = bomb.split("-")[0]
    assert f"a {kind} chunk expands beyond the " in line and " bytes it declares" in line


def test_a_chunk_declaring_more_than_any_chunk_may_have_is_refused_before_decompressing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "large.mcap"
    write_mcap(path, CompressionType.ZSTD, **NO_SUMMARY)
    monkeypatch.setattr(robot_logs.inflate, "MAX_CHUNK_BYTES", 100)  # the written chunk is a few hundred bytes
    code, line = log_command(capsys, "inspect", path)
    assert code == 2 and "a zstd chunk declares " in line and " bytes uncompressed, more than the 100 a chunk may have" in line


def test_a_ros1_bz2_bomb_chunk_is_refused_in_bounded_memory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bomb.bag"
    zeros = bz2.compress(bytes(2**20))  # a bz2 stream per MiB of zeros: bz2 reads concatenated streams as one
    bag = BagWriter(path)
    bag._writer.set_compression(Ros1Writer.CompressionFormat.BZ2)
    bag._writer.compressor = lambda data: bz2.compress(data) + zeros * (PAD // 2**20)
    with bag:
        for k in range(3):
            bag.odometry(Odometry(k * 10**8, "odom", "base_link", Pose2D(0.1 * k, 0.0, 0.0), 0.5, 0.0))
    assert path.stat().st_size < 20_000
    tracemalloc.start()
    try:
        code, line = log_command(capsys, "inspect", path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert code == 2 and line.startswith(f"error: {path} is damaged (truncated or corrupt: a bz2 chunk expands beyond the ")
    assert peak < PAD // 2  # the chunk's declared size and the reader's own needs, never the bomb's


@pytest.fixture
def file_compressed_bag(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path]:
    """A ROS 2 bag (MCAP storage) compressed as whole files, and its one .zstd storage file; temporary files in
    a folder of the test's own, so that what the reader leaves there can be seen."""
    folder = tmp_path / "bag"
    with BagWriter(folder, "ros2-mcap", compression=CompressionMode.FILE) as bag:
        bag.odometry(Odometry(10**8, "odom", "base_link", Pose2D(0.0, 0.0, 0.0), 0.5, 0.0))
    (storage,) = folder.glob("*.zstd")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    return folder, storage


def test_a_whole_file_that_inflates_to_something_else_is_refused_at_its_first_bytes(
        file_compressed_bag: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    folder, storage = file_compressed_bag
    storage.write_bytes(zstandard.compress(bytes(PAD)))
    code, line = log_command(capsys, "inspect", folder)
    assert code == 2
    assert line == f"error: {folder}: storage file {storage.name} does not decompress to an MCAP file (its first bytes are not an MCAP file's)"
    assert not any(Path(tempfile.tempdir or "").iterdir())


def test_a_whole_file_that_inflates_beyond_its_bound_is_refused(
        file_compressed_bag: tuple[Path, Path], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    folder, storage = file_compressed_bag
    storage.write_bytes(zstandard.compress(MCAP0_MAGIC + bytes(PAD)))
    monkeypatch.setattr(robot_logs.inflate, "MAX_CHUNK_BYTES", 2**20)
    code, line = log_command(capsys, "inspect", folder)
    assert code == 2
    assert line.startswith(f"error: {folder}: storage file {storage.name} expands beyond 1,048,576 bytes, the most a storage file of ")
    assert not any(Path(tempfile.tempdir or "").iterdir())


def test_a_file_compressed_bag_still_reads(file_compressed_bag: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    folder, _ = file_compressed_bag
    code, out = log_command(capsys, "inspect", folder)
    assert code == 0 and "/odom" in out


@pytest.mark.parametrize(("data", "compression", "declared", "message"), [
    (zstandard.compress(bytes(PAD)), "zstd", 1000, "a zstd chunk expands beyond the 1,000 bytes it declares (its frame records 8,388,608)"),
    (zstandard.compress(bytes(PAD)), "zstd", None, None),
    (zstandard.compress(bytes(1000)), "zstd", 2**40, "a zstd chunk declares 1,099,511,627,776 bytes uncompressed, more than the "),
    (zstandard.compress(bytes(1000))[:-4], "zstd", 1000, "a zstd chunk does not decompress ("),
    (lz4.frame.compress(bytes(1000))[:-4], "lz4", 1000, "a lz4 chunk does not decompress ("),
    (b"not bz2 at all", "bz2", 1000, "a bz2 chunk does not decompress ("),
    (b"", "lzma", 1000, "unknown chunk compression 'lzma' (expected zstd, lz4, bz2 or none)"),
])
def test_inflate_names_what_it_refuses(data: bytes, compression: str, declared: int | None, message: str | None) -> None:
    if message is None:  # no declared size (a ROS 2 message): the frame's own, within the bound, is kept
        assert inflate(data, compression, declared) == bytes(PAD)
        return
    with pytest.raises(InflateError) as refused:
        inflate(data, compression, declared)
    assert str(refused.value).startswith(message)
