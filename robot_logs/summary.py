"""What a log holds, topic by topic: counts, rates, time spans and frames (`trials log inspect`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robot_logs.frames import frame_name
from robot_logs.reader import LogReader
from robot_logs.records import seconds


@dataclass
class TopicSummary:
    """One topic's figures; stamps are header stamps, `record_*` the logger's clock (ns)."""

    name: str
    msgtype: str
    count: int = 0
    first_stamp_ns: int | None = None
    last_stamp_ns: int | None = None
    first_record_ns: int | None = None
    last_record_ns: int | None = None
    unstamped: int = 0
    frames: set[str] = field(default_factory=set)
    header_minus_record_ns: int | None = None

    @property
    def rate_hz(self) -> float | None:
        """Messages per second over the header-stamp span (record span if never stamped)."""
        first, last = (self.first_stamp_ns, self.last_stamp_ns) if self.first_stamp_ns is not None else (self.first_record_ns, self.last_record_ns)
        if self.count < 2 or first is None or last is None or last <= first:
            return None
        return (self.count - 1) / seconds(last - first)


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
    if header is None:
        return []
    child = getattr(msg, "child_frame_id", None)
    label = frame_name(header.frame_id) + (f"->{frame_name(child)}" if child else "")
    return [(header, label)]


def summarise(log: LogReader, progress: Callable[[int], None] | None = None) -> LogSummary:
    """Read every message of an open log once and summarise it per topic."""
    topics = {t.name: TopicSummary(t.name, t.msgtype) for t in log.topics}
    for message in log.messages(set(topics)):
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
    return LogSummary(str(log.path), log.format, list(topics.values()), log.damage)
