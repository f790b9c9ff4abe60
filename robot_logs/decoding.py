"""Deserialising ROS1 and ROS2 (CDR) messages from the type definitions a log embeds.

Used where rosbags' AnyReader does not open the file itself: plain MCAP files read with the
`mcap` library, and damaged bags read record by record.
"""

from __future__ import annotations

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

_IDL_SEPARATOR = "=" * 80 + "\n"


def ros2_type_name(msgtype: str) -> str:
    """'sensor_msgs/LaserScan' (ROS1 spelling) as 'sensor_msgs/msg/LaserScan'; others unchanged."""
    parts = msgtype.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return msgtype


class MessageDecoder:
    """Registers embedded message definitions and turns raw bytes into rosbags message objects."""

    def __init__(self) -> None:
        self._store = get_typestore(Stores.EMPTY)
        self._fallback = get_typestore(Stores.LATEST)
        self._known: set[str] = set()

    def add(self, msgtype: str, definition: str, kind: str = "msg") -> None:
        """Register `msgtype` from its .msg text ('msg', ROS1 or ROS2) or IDL text ('idl').

        An empty definition leaves the type to the standard ROS 2 type store.
        """
        msgtype = ros2_type_name(msgtype)
        if msgtype in self._known or not definition.strip():
            return
        if kind == "idl":
            blocks = definition.split(_IDL_SEPARATOR)[1:] if definition.startswith(_IDL_SEPARATOR) else [definition]
            types = {}
            for block in blocks:
                types.update(get_types_from_idl(block.split("\n", 1)[1] if block.startswith("IDL: ") else block))
        else:
            types = get_types_from_msg(definition, msgtype)
        self._store.register(types)
        self._known.add(msgtype)

    def decode(self, raw: bytes | memoryview, msgtype: str, encoding: str) -> object:
        """A message object from its bytes; encoding is 'ros1' or 'cdr'."""
        msgtype = ros2_type_name(msgtype)
        store = self._store if msgtype in self._known else self._fallback
        if encoding == "ros1":
            return store.deserialize_ros1(bytes(raw), msgtype)
        return store.deserialize_cdr(bytes(raw), msgtype)
