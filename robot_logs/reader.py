"""`LogReader`: one reader over ROS1 bags, ROS2 bags (sqlite3 or MCAP storage) and MCAP files.

Which file is which is told by its first bytes (a folder with metadata.yaml is a ROS2 bag).
ROS1 bags and ROS2 bags open through rosbags' AnyReader, plain MCAP files through the `mcap`
library. A damaged file raises `LogError` naming it; with `salvage=True` what can be read is
read instead (undecodable messages and damaged MCAP chunks are skipped, a truncated file is
read up to the cut) and `damage` says what was met.

Timestamps: robot_logs times everything by the messages' header stamps (acquisition time, the
clock tf lookups use). Record times, which can differ from header stamps by seconds or years
(a bag re-recorded later), only order the messages and pair unstamped ones.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from pathlib import Path
from types import TracebackType

from robot_logs.errors import LogError
from robot_logs.sources import BagWalkSource, McapSource, Message, RosbagsSource, TopicInfo

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"
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
        LogError: the path is missing, empty or not a log of a known format.
    """
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise LogError(f"{path} is a folder without metadata.yaml, so not a ROS2 bag")
        return "ros2"
    with path.open("rb") as stream:
        head = stream.read(16)
    if not head:
        raise LogError(f"{path} is empty (0 bytes)")
    for kind, magic in (("ros1", ROS1_MAGIC), ("mcap", MCAP_MAGIC), ("sqlite", SQLITE_MAGIC)):
        if head.startswith(magic):
            return kind
    raise LogError(
        f"{path} is not a log robot_logs reads (or its start is damaged): expected a ROS1 .bag, "
        "a ROS2 bag folder with metadata.yaml, an .mcap or a .db3 file"
    )


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
        self._source: RosbagsSource | McapSource | BagWalkSource | None = None

    @property
    def format(self) -> str:
        """The format in words, e.g. 'ROS2 bag (mcap storage)'."""
        if self.kind == "ros2":
            storage = "mcap" if any(self.path.glob("*.mcap")) else "sqlite3"
            return f"ROS2 bag ({storage} storage)"
        return FORMATS[self.kind]

    def _damaged(self, detail: str) -> LogError:
        return LogError(
            f"{self.path} is damaged (truncated or corrupt: {detail}); "
            "pass --salvage to read what can be read"
        )

    def open(self) -> None:
        """Open the file (or its salvageable part).

        Raises:
            LogError: the file is damaged and salvage is off, or nothing could be salvaged.
        """
        storage = [self.path] if self.kind == "mcap" else sorted(self.path.glob("*.mcap")) if self.kind == "ros2" else []
        try:
            if storage and (self.kind == "mcap" or self.salvage):
                self._source = McapSource(storage, salvage=self.salvage)
            else:
                self._source = RosbagsSource(self.path, salvage=self.salvage)
        except LogError:
            raise
        except Exception as exc:  # rosbags, mcap, sqlite3 and decompressors each raise their own
            if not self.salvage:
                raise self._damaged(_describe(exc)) from None
            if self.kind != "ros1":
                raise LogError(f"{self.path} is damaged ({_describe(exc)}) and no part of it can be read") from None
            self._source = BagWalkSource(self.path)
        self.damage = getattr(self._source, "damage", None)

    def close(self) -> None:
        """Release the file."""
        if self._source is not None:
            self._source.close()
            self._source = None

    def __enter__(self) -> LogReader:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    @property
    def topics(self) -> list[TopicInfo]:
        """Every topic with its type and message count, sorted by name."""
        if self._source is None:
            raise LogError(f"{self.path} is not open")
        return self._source.topics()

    def messages(self, topics: Collection[str]) -> Iterator[Message]:
        """Decoded messages of the given topics, in record-time order (file order when salvaging).

        Raises:
            LogError: damage met while reading (with salvage on, the damaged part is skipped
                or reading stops there, and `damage` tells what was met).
        """
        if self._source is None:
            raise LogError(f"{self.path} is not open")
        if not topics:
            return
        try:
            yield from self._source.messages(set(topics))
        except LogError:
            raise
        except Exception as exc:  # the format libraries' own errors mean damaged bytes
            if not self.salvage:
                raise self._damaged(_describe(exc)) from None
            self.damage = _describe(exc)
        self.damage = getattr(self._source, "damage", None) or self.damage


def _describe(exc: Exception) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text if len(text) < 200 else text[:197] + "..."
