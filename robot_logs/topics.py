"""Choosing a log's topics by message type, with names the user can override."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from robot_logs.errors import LogError
from robot_logs.sources import TopicInfo

SCAN_TYPES = ("sensor_msgs/msg/LaserScan",)
ODOMETRY_TYPES = ("nav_msgs/msg/Odometry",)
TF_TYPES = ("tf2_msgs/msg/TFMessage", "tf/msg/tfMessage")
POINTS_TYPES = ("geometry_msgs/msg/PoseArray",)


@dataclass(frozen=True)
class TopicNames:
    """Topic names to use instead of choosing by type; None means "the one topic of that type".

    people: labelled or ground-truth positions (geometry_msgs/PoseArray).
    """

    scan: str | None = None
    odometry: str | None = None
    people: str | None = None


def listing(topics: list[TopicInfo]) -> str:
    """'/scan (sensor_msgs/msg/LaserScan, 1265), ...' for error messages."""
    return ", ".join(f"{t.name} ({t.msgtype}, {t.count})" for t in topics) or "none"


def _same(a: str, b: str) -> bool:
    return a.lstrip("/") == b.lstrip("/")


def pick_topic(
    topics: list[TopicInfo], types: tuple[str, ...], what: str, override: str | None, path: Path, option: str,
    hint: str = "",
) -> TopicInfo:
    """The topic to read for one kind of data.

    Args:
        topics: the log's topics.
        types: message types that carry this kind of data.
        what: the kind in words, for messages ("LaserScan").
        override: a topic name the user gave (leading slash optional), or None.
        path: the log, for messages.
        option: the command-line option that overrides the choice, for messages.
        hint: appended to the message when no topic has a fitting type (what to do instead).

    Raises:
        LogError: the named topic is missing or of another type, no topic has a fitting
            type, several do (the message lists them), or the topic holds no messages.
    """
    if override is not None:
        found = [t for t in topics if _same(t.name, override)]
        if not found:
            raise LogError(f"{path} has no topic {override}; its topics: {listing(topics)}")
        chosen = found[0]
        if chosen.msgtype not in types:
            raise LogError(f"topic {chosen.name} of {path} holds {chosen.msgtype}, not {what} ({' or '.join(types)})")
    else:
        fitting = [t for t in topics if t.msgtype in types]
        if not fitting:
            raise LogError(f"{path} has no {what} topic; its topics: {listing(topics)}{hint}")
        if len(fitting) > 1:
            names = ", ".join(t.name for t in fitting)
            raise LogError(f"{path} has several {what} topics ({names}); choose one with {option}")
        chosen = fitting[0]
    if chosen.count == 0:
        raise LogError(f"topic {chosen.name} of {path} holds no messages (an empty log)")
    return chosen


def tf_topics(topics: list[TopicInfo]) -> list[TopicInfo]:
    """Every tf topic (/tf, /tf_static or renamed ones), found by type."""
    return [t for t in topics if t.msgtype in TF_TYPES]


def is_static_tf(topic: str) -> bool:
    """True for tf_static topics, whose transforms hold at every time."""
    return topic.rstrip("/").endswith("tf_static")
