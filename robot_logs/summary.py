"""What a log holds, topic by topic: counts, rates, time spans and frames (`trials log inspect`).

Every topic is read except recorded service events, which are listed with their counts only;
messages that cannot be decoded (types no definition covers, protobuf...) are counted and
skipped, never fatal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robot_logs.frames import frame_name
from robot_logs.reader import LogReader
from robot_logs.records import seconds

#: Rates are given only over at least this span (s): over a shorter one (a split bag's few
#: messages stamped microseconds apart) a rate says more about the clock than the topic.
MIN_RATE_SPAN_S = 0.1


@dataclass
class TopicSummary:
    """One topic's figures; stamps are header stamps, `record_*` the logger's clock (ns).

    `count` is the messages read (for a service topic, which is not read, the log's count);
    `undecoded` of them could not be decoded, for the reason `why`.
    """

    name: str
    msgtype: str
    encoding: str
    service: bool = False
    count: int = 0
    undecoded: int = 0
    why: str | None = None
    first_stamp_ns: int | None = None
    last_stamp_ns: int | None = None
    first_record_ns: int | None = None
    last_record_ns: int | None = None
    unstamped: int = 0
    frames: set[str] = field(default_factory=set)
    header_minus_record_ns: int | None = None

    @property
    def rate_hz(self) -> float | None:
        """Messages per second over the header-stamp span (record span if never stamped);
        None with fewer than three decoded messages (two intervals) or a span under `MIN_RATE_SPAN_S`."""
        first, last = (self.first_stamp_ns, self.last_stamp_ns) if self.first_stamp_ns is not None else (self.first_record_ns, self.last_record_ns)
        decoded = self.count - self.undecoded
        if decoded < 3 or first is None or last is None or seconds(last - first) < MIN_RATE_SPAN_S:
            return None
        return (decoded - 1) / seconds(last - first)


@dataclass(frozen=True)
class LogSummary:
    """A log's format, topics and overall spans (header stamps and record times)."""

    path: str
    format: str
    topics: list[TopicSummary]
    damage: str | None

    def span_s(self, record: bool = False) -> float | None:
        """Seconds from the first to the last message, by header stamps or record times."""
        starts = [t.first_record_ns if record else t.first_stamp_ns for t in self.topics]
        ends = [t.last_record_ns if record else t.last_stamp_ns for t in self.topics]
        starts, ends = [s for s in starts if s is not None], [e for e in ends if e is not None]
        return seconds(max(ends) - min(starts)) if starts and ends else None


def _headers(msg: Any) -> list[tuple[Any, str]]:
    """(header, frame label) pairs of a message: its own header, or those of tf transforms."""
    if hasattr(msg, "transforms"):
        return [(t.header, f"{frame_name(t.header.frame_id)}->{frame_name(t.child_frame_id)}") for t in msg.transforms]
    header = getattr(msg, "header", None)
    if not hasattr(header, "stamp"):  # no header, or a JSON record
        return []
    child = getattr(msg, "child_frame_id", None)
    label = frame_name(header.frame_id) + (f"->{frame_name(child)}" if child else "")
    return [(header, label)]


def summarise(log: LogReader, progress: Callable[[int], None] | None = None) -> LogSummary:
    """Read every message of an open log once (services aside) and summarise it per topic."""
    topics = {t.name: TopicSummary(t.name, t.msgtype, t.encoding, t.service, t.count if t.service else 0) for t in log.topics}
    for message in log.messages({t.name for t in topics.values() if not t.service}, skip_undecodable=True):
        entry = topics[message.topic]
        entry.count += 1
        record = message.record_ns
        entry.first_record_ns = record if entry.first_record_ns is None else min(entry.first_record_ns, record)
        entry.last_record_ns = record if entry.last_record_ns is None else max(entry.last_record_ns, record)
        headers = _headers(message.data)
        entry.frames.update(label for _, label in headers if label)
        stamps = [int(h.stamp.sec) * 1_000_000_000 + int(h.stamp.nanosec) for h, _ in headers]
        stamps = [s for s in stamps if s]
        if headers and not stamps:
            entry.unstamped += 1
        for stamp in stamps:
            entry.first_stamp_ns = stamp if entry.first_stamp_ns is None else min(entry.first_stamp_ns, stamp)
            entry.last_stamp_ns = stamp if entry.last_stamp_ns is None else max(entry.last_stamp_ns, stamp)
            if entry.header_minus_record_ns is None:
                entry.header_minus_record_ns = stamp - record
        if progress is not None:
            progress(1)
    for name, skipped in log.undecoded.items():
        topics[name].count += skipped
        topics[name].undecoded, topics[name].why = skipped, log.undecoded_why[name]
    return LogSummary(str(log.path), log.format, list(topics.values()), log.damage)
