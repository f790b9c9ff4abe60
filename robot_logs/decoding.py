"""Turning a log's raw message bytes into objects: ROS 1, ROS 2 (CDR) and JSON encodings.

A message type is decoded with the first definition that fits: the one the log stores (a ROS1
connection's text, an MCAP schema, a ROS2 bag's `message_definitions`), then rosbags' type
store of the bag's ROS distribution, then the stores of `FALLBACK_STORES` newest first (so a bag
from an older release whose definitions differ still decodes). The first definition that
decodes a topic's first message is kept for the rest. Types no definition covers, and other
encodings (protobuf, flatbuffer...), raise `Undecodable`; callers decide whether that is fatal.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

_IDL_SEPARATOR = "=" * 80 + "\n"

#: ROS 2 type stores tried, in this order, for a CDR type the log does not define (after the
#: store of the bag's own `ros_distro`, where its metadata names one).
FALLBACK_STORES = (
    Stores.ROS2_LYRICAL,
    Stores.ROS2_KILTED,
    Stores.ROS2_JAZZY,
    Stores.ROS2_IRON,
    Stores.ROS2_HUMBLE,
    Stores.ROS2_GALACTIC,
    Stores.ROS2_FOXY,
    Stores.ROS2_ELOQUENT,
    Stores.ROS2_DASHING,
)

#: Message encodings decoded, as MCAP and rosbag2 name them.
ROS1, CDR, JSON = "ros1", "cdr", "json"


class Undecodable(Exception):
    """A message type or message robot_logs cannot decode; the text says why.

    `damaged` is True for a message that does not fit the definition that decoded the topic's
    earlier messages (corrupt bytes); False for a type problem: no definition found, none that
    fits the topic's first message (a variant no store knows), or an encoding robot_logs does
    not read. A type problem holds for every later message of the topic too.
    """

    def __init__(self, text: str, damaged: bool = False) -> None:
        super().__init__(text)
        self.damaged = damaged


def ros2_type_name(msgtype: str) -> str:
    """'sensor_msgs/LaserScan' (ROS1 spelling) as 'sensor_msgs/msg/LaserScan'; others unchanged."""
    parts = msgtype.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return msgtype


def is_service(msgtype: str) -> bool:
    """True for recorded service events (e.g. 'example_interfaces/srv/AddTwoInts_Event')."""
    return "/srv/" in msgtype


@dataclass(frozen=True)
class MessageType:
    """How one channel of a log is encoded.

    Attributes:
        name: the type in ROS 2 spelling ('sensor_msgs/msg/LaserScan') or the schema name.
        encoding: 'ros1', 'cdr', 'json', or whatever other encoding the log names.
        definition: the definition text the log stores ('' where it stores none).
        idl: True when `definition` is IDL rather than .msg text.
    """

    name: str
    encoding: str
    definition: str = ""
    idl: bool = False


def store_of_distro(distro: str | None) -> Stores | None:
    """rosbags' type store of a ROS 2 distribution name ('humble'), None for unknown names."""
    try:
        return Stores(f"ros2_{(distro or '').strip().lower()}")
    except ValueError:
        return None


@cache
def _builtin_store(store: Stores) -> Typestore:
    return get_typestore(store)


@cache
def _embedded_store(mtype: MessageType) -> Typestore:
    """A type store holding the types a log's definition text declares (parsed once per text)."""
    if mtype.idl:
        text = mtype.definition
        blocks = text.split(_IDL_SEPARATOR)[1:] if text.startswith(_IDL_SEPARATOR) else [text]
        types = {}
        for block in blocks:
            types.update(get_types_from_idl(block.split("\n", 1)[1] if block.startswith("IDL: ") else block))
    else:
        types = get_types_from_msg(mtype.definition, mtype.name)
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store


class _TypeDecoder:
    """Decodes one message type, settling on the first candidate store that decodes its first message."""

    def __init__(self, mtype: MessageType, stores: list[Typestore]) -> None:
        self.mtype = mtype
        self._stores = stores
        self._chosen: Callable[[bytes], object] | None = None
        self._problem: Undecodable | None = None

    def _function(self, store: Typestore) -> Callable[[bytes], object]:
        name = self.mtype.name
        if self.mtype.encoding == ROS1:
            return lambda raw: store.deserialize_ros1(raw, name)
        return lambda raw: store.deserialize_cdr(raw, name)

    def __call__(self, raw: bytes) -> object:
        if self._chosen is not None:
            return self._chosen(raw)
        if self._problem is not None:
            raise self._problem
        failures = []
        for store in self._stores:
            function = self._function(store)
            try:
                message = function(raw)
            except Exception as exc:  # rosbags raises several kinds for bytes that do not fit
                failures.append(str(exc) or type(exc).__name__)
                continue
            self._chosen = function
            return message
        if not failures:
            self._problem = Undecodable(f"no definition of {self.mtype.name} in the log or in rosbags' type stores")
        else:
            self._problem = Undecodable(f"no definition of {self.mtype.name} fits its messages ({failures[0]})")
        raise self._problem


class MessageDecoder:
    """Decodes raw messages of any channel of one log.

    Args:
        distro: the ROS 2 distribution the bag was recorded with (its metadata's `ros_distro`),
            or None; its type store is tried before the fallback order.
    """

    def __init__(self, distro: str | None = None) -> None:
        own = store_of_distro(distro)
        self._order = ((own,) if own else ()) + tuple(s for s in FALLBACK_STORES if s != own)
        self._decoders: dict[MessageType, Callable[[bytes], object]] = {}

    def _candidates(self, mtype: MessageType) -> Iterator[Typestore]:
        if mtype.definition.strip():
            try:
                store = _embedded_store(mtype)
            except Exception:  # a definition rosbags cannot parse (e.g. a service event's): try the stores
                store = None
            if store is not None and mtype.name in store.fielddefs:
                yield store
        for name in (Stores.ROS1_NOETIC,) if mtype.encoding == ROS1 else self._order:
            store = _builtin_store(name)
            if mtype.name in store.fielddefs:
                yield store

    def _decoder(self, mtype: MessageType) -> Callable[[bytes], object]:
        if mtype.encoding == JSON:
            return json.loads
        if mtype.encoding not in (ROS1, CDR):
            raise Undecodable(f"{mtype.encoding} messages are not decoded (robot_logs reads ROS 1, CDR and JSON)")
        return _TypeDecoder(mtype, list(self._candidates(mtype)))

    def decode(self, raw: bytes | memoryview, mtype: MessageType) -> object:
        """The message object of `raw`, a message of type `mtype`.

        Raises:
            Undecodable: no definition of the type is found, none decodes the message, or the
                encoding is not one robot_logs reads.
        """
        decoder = self._decoders.get(mtype)
        if decoder is None:
            decoder = self._decoders[mtype] = self._decoder(mtype)
        try:
            return decoder(bytes(raw))
        except Undecodable:
            raise
        except Exception as exc:  # a locked-in definition met bytes that do not fit it
            raise Undecodable(f"{mtype.name}: {exc}", damaged=True) from None
