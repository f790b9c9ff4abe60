"""`LogReader`: one reader over ROS1 bags, ROS2 bags (sqlite3 or MCAP storage) and MCAP files.

Which file is which is told by its first bytes (a folder with metadata.yaml is a ROS2 bag).
ROS1 bags and sqlite3 storage open through rosbags, MCAP files (plain or a bag's storage)
through the `mcap` library (`robot_logs.sources`); only the topics asked for are read, and their
messages are decoded by `robot_logs.decoding`. A damaged file raises `LogError` naming it; with
`salvage=True` what can be read is read instead (undecodable messages and damaged MCAP chunks
are skipped, a truncated file is read up to the cut) and `damage` says what was met.

Timestamps: robot_logs times everything by the messages' header stamps (acquisition time, the
clock tf lookups use). Record times, which can differ from header stamps by seconds or years
(a bag re-recorded later), only order the messages and pair unstamped ones.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from tempfile import TemporaryDirectory
from types import TracebackType

from mcap.writer import MCAP0_MAGIC

from robot_logs.bag_metadata import read_bag_metadata
from robot_logs.decoding import MessageDecoder, Undecodable
from robot_logs.errors import LogError
from robot_logs.inflate import InflateError, inflate_file
from robot_logs.sources import BagWalkSource, McapSource, Ros1Source, Rosbag2Source, TopicInfo

Source = Ros1Source | Rosbag2Source | McapSource | BagWalkSource

ROS1_MAGIC = b"#ROSBAG V2.0\n"
SQLITE_MAGIC = b"SQLite format 3\x00"

FORMATS = {
    "ros1": "ROS1 bag",
    "ros2": "ROS2 bag",
    "mcap": "MCAP file",
    "sqlite": "ROS2 sqlite3 database",
}


def detect_format(path: Path) -> str:
    """'ros1', 'ros2', 'mcap' or 'sqlite' for a log path.

    Raises:
        LogError: the path is missing, empty, not a regular file or a folder (a FIFO or a device, which reading
            would wait on or never finish), or not a log of a known format.
    """
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise LogError(f"{path} is a folder without metadata.yaml, so not a ROS2 bag")
        return "ros2"
    if not path.is_file():
        raise LogError(f"{path} is not a regular file or a folder, so not a log")
    with path.open("rb") as stream:
        head = stream.read(16)
    if not head:
        raise LogError(f"{path} is empty (0 bytes)")
    for kind, magic in (("ros1", ROS1_MAGIC), ("mcap", MCAP0_MAGIC), ("sqlite", SQLITE_MAGIC)):
        if head.startswith(magic):
            return kind
    raise LogError(
        f"{path} is not a log robot_logs reads (or its start is damaged): expected a ROS1 .bag, "
        "a ROS2 bag folder with metadata.yaml, an .mcap or a .db3 file"
    )


@dataclass(frozen=True)
class Message:
    """One decoded message: topic, type, record time (ns, the logger's clock) and the message object."""

    topic: str
    msgtype: str
    record_ns: int
    data: object


class LogReader:
    """Topics and decoded messages of one log file, whatever its format.

    Use as a context manager::

        with LogReader("run.bag") as log:
            for message in log.messages({"/scan"}): ...

    Args:
        path: a ROS1 `.bag`, a ROS2 bag folder, an `.mcap` or a `.db3` file.
        salvage: read what can be read of a damaged file instead of refusing it.
    """

    def __init__(self, path: str | Path, *, salvage: bool = False) -> None:
        self.path = Path(path)
        self.salvage = salvage
        self.kind = detect_format(self.path)
        self.damage: str | None = None
        #: Messages skipped by `messages(..., skip_undecodable=True)`, per topic, and why.
        self.undecoded: Counter[str] = Counter()
        self.undecoded_why: dict[str, str] = {}
        self._source: Source | None = None
        self._scratch: TemporaryDirectory[str] | None = None
        self._decoder = MessageDecoder()

    @property
    def format(self) -> str:
        """The format in words, e.g. 'ROS2 bag (mcap storage)'."""
        if self.kind == "ros2":
            return f"ROS2 bag ({read_bag_metadata(self.path).storage} storage)"
        return FORMATS[self.kind]

    def _damaged(self, detail: str) -> LogError:
        return LogError(
            f"{self.path} is damaged (truncated or corrupt: {detail}); "
            "pass --salvage to read what can be read"
        )

    def _make_source(self) -> Source:
        if self.kind == "ros1":
            return Ros1Source(self.path)
        if self.kind == "mcap":
            return McapSource([self.path], salvage=self.salvage)
        if self.kind == "sqlite":
            return Rosbag2Source([self.path])
        bag = read_bag_metadata(self.path)
        files = self._decompressed(bag.files, bag.storage) if bag.compression == "file" else bag.files
        per_message = bag.compression == "message"
        if bag.storage == "mcap":
            return McapSource(files, bag.distro, salvage=self.salvage, compressed=per_message)
        if bag.storage == "sqlite3":
            return Rosbag2Source(files, bag.distro, compressed=per_message)
        raise LogError(f"{self.path}: storage {bag.storage!r} in metadata.yaml; robot_logs reads 'sqlite3' and 'mcap'")

    def _decompressed(self, files: list[Path], storage: str) -> list[Path]:
        """Copies of zstd-compressed storage files, decompressed into a folder removed on close; one that is not a
        file of the bag's storage, or expands beyond `inflate`'s bound, is refused before it fills the disk."""
        magic, what = {"mcap": (MCAP0_MAGIC, "an MCAP file"), "sqlite3": (SQLITE_MAGIC, "an sqlite3 database")}.get(storage, (b"", storage))
        self._scratch = TemporaryDirectory(prefix="robot_logs-")
        copies = []
        try:
            for path in files:
                copy = Path(self._scratch.name) / path.name.removesuffix(".zstd")
                inflate_file(path, copy, magic, what)
                copies.append(copy)
        except InflateError as exc:
            self.close()
            raise LogError(f"{self.path}: storage file {exc}") from None
        return copies

    def open(self) -> None:
        """Open the file (or its salvageable part).

        Raises:
            LogError: the file is damaged and salvage is off, or nothing could be salvaged.
        """
        try:
            self._source = self._make_source()
        except LogError:
            raise
        except Exception as exc:  # rosbags, mcap, sqlite3 and decompressors each raise their own
            if not self.salvage:
                raise self._damaged(_describe(exc)) from None
            if self.kind != "ros1":
                raise LogError(f"{self.path} is damaged ({_describe(exc)}) and no part of it can be read") from None
            self._source = BagWalkSource(self.path)
        self._decoder = MessageDecoder(self._source.distro)
        self.damage = getattr(self._source, "damage", None)

    def close(self) -> None:
        """Release the file."""
        if self._source is not None:
            self._source.close()
            self._source = None
        if self._scratch is not None:
            self._scratch.cleanup()
            self._scratch = None

    def __enter__(self) -> LogReader:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    @property
    def topics(self) -> list[TopicInfo]:
        """Every topic with its type, message count and encoding, sorted by name."""
        if self._source is None:
            raise LogError(f"{self.path} is not open")
        return self._source.topics()

    def messages(self, topics: Collection[str], *, skip_undecodable: bool = False) -> Iterator[Message]:
        """Decoded messages of the given topics, in record-time order (file order when salvaging
        or streaming an MCAP file without index).

        Args:
            topics: the topics to read; no other topic is read or decoded.
            skip_undecodable: skip messages whose type cannot be decoded, counting them in
                `undecoded` (with the reason in `undecoded_why`), instead of raising; corrupt
                messages stay damage.

        Raises:
            LogError: damage met while reading (with salvage on, the damaged part is skipped
                or reading stops there, and `damage` tells what was met), or a message that
                cannot be decoded (unknown type, another encoding) unless skipped.
        """
        if self._source is None:
            raise LogError(f"{self.path} is not open")
        if not topics:
            return
        try:
            for raw in self._source.messages(set(topics)):
                try:
                    data = self._decoder.decode(raw.data, raw.mtype)
                except Undecodable as exc:
                    self._undecodable(raw.topic, exc, skip_undecodable)
                    continue
                yield Message(raw.topic, raw.mtype.name, raw.record_ns, data)
        except LogError:
            raise
        except Exception as exc:  # the format libraries' own errors mean damaged bytes
            if not self.salvage:
                raise self._damaged(_describe(exc)) from None
            self.damage = self.damage or _describe(exc)
        self.damage = getattr(self._source, "damage", None) or self.damage

    def _undecodable(self, topic: str, exc: Undecodable, skip: bool) -> None:
        """A message that cannot be decoded: corrupt bytes are damage (skipped when salvaging),
        a type problem is counted when skipping and refused otherwise."""
        if exc.damaged and self.salvage:
            self.damage = self.damage or f"undecodable message on {topic}: {exc}"
        elif exc.damaged:
            raise self._damaged(f"undecodable message on {topic}: {_describe(exc)}")
        elif skip:
            self.undecoded[topic] += 1
            self.undecoded_why.setdefault(topic, str(exc))
        else:
            raise LogError(f"topic {topic} of {self.path} cannot be decoded: {_describe(exc)}")


def _describe(exc: Exception) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text if len(text) < 200 else text[:197] + "..."
