"""JSON schemas of Foxglove's message types, derived from the definitions Foxglove's own SDK publishes.

Foxglove recognises a channel by its schema name ("foxglove.SceneUpdate", ...) and reads its JSON
schema for the field types. foxglove-sdk ships every type as a protobuf descriptor; this module turns
one into the JSON schema of Foxglove's JSON encoding (times and durations as {"sec", "nsec"} titled
"time" and "duration", enums as integers, bytes as base64 text), so the logs stay JSON, which
robot_logs and any MCAP tool read, and the schemas stay Foxglove's, every field of them.
"""

from __future__ import annotations

from functools import cache
from typing import Any

from google.protobuf.descriptor_pb2 import DescriptorProto, FieldDescriptorProto, FileDescriptorSet

Schema = dict[str, Any]

NUMBER: Schema = {"type": "number"}
INTEGER: Schema = {"type": "integer"}
STRING: Schema = {"type": "string"}
BOOLEAN: Schema = {"type": "boolean"}
NANOSECONDS: Schema = {"type": "integer", "minimum": 0, "maximum": 999_999_999}
TIME: Schema = {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": NANOSECONDS}}
DURATION: Schema = {"type": "object", "title": "duration", "properties": {"sec": INTEGER, "nsec": NANOSECONDS}}
#: Protobuf's well-known types as Foxglove's JSON encoding writes them.
WELL_KNOWN: dict[str, Schema] = {".google.protobuf.Timestamp": TIME, ".google.protobuf.Duration": DURATION}

_F = FieldDescriptorProto
SCALARS: dict[int, Schema] = {
    **dict.fromkeys((_F.TYPE_DOUBLE, _F.TYPE_FLOAT), NUMBER),
    **dict.fromkeys((_F.TYPE_INT32, _F.TYPE_INT64, _F.TYPE_UINT32, _F.TYPE_UINT64, _F.TYPE_SINT32, _F.TYPE_SINT64,
                     _F.TYPE_FIXED32, _F.TYPE_FIXED64, _F.TYPE_SFIXED32, _F.TYPE_SFIXED64, _F.TYPE_ENUM), INTEGER),
    _F.TYPE_BOOL: BOOLEAN,
    _F.TYPE_STRING: STRING,
    _F.TYPE_BYTES: {"type": "string", "contentEncoding": "base64"},
}

def _messages(name: str) -> dict[str, DescriptorProto]:
    """Every message type in the SDK's descriptor set of `name`, by full name (".foxglove.Pose")."""
    from foxglove import messages

    data = getattr(messages, name.removeprefix("foxglove.")).get_schema().data
    found: dict[str, DescriptorProto] = {}

    def add(prefix: str, message: DescriptorProto) -> None:
        found[f"{prefix}.{message.name}"] = message
        for nested in message.nested_type:
            add(f"{prefix}.{message.name}", nested)

    for file in FileDescriptorSet.FromString(data).file:
        for message in file.message_type:
            add(f".{file.package}", message)
    return found


def _object(full_name: str, types: dict[str, DescriptorProto]) -> Schema:
    properties: Schema = {}
    for field in types[full_name].field:
        if field.type == _F.TYPE_MESSAGE:
            value = WELL_KNOWN.get(field.type_name) or _object(field.type_name, types)
        else:
            value = SCALARS[field.type]
        properties[field.name] = {"type": "array", "items": value} if field.label == _F.LABEL_REPEATED else value
    return {"title": full_name.lstrip("."), "type": "object", "properties": properties}


@cache
def foxglove_schema(name: str) -> Schema:
    """The JSON schema of Foxglove type `name` (e.g. "foxglove.SceneUpdate"), every field of the SDK's definition.

    Raises:
        KeyError: foxglove-sdk has no such type.
    """
    if not name.startswith("foxglove."):
        raise KeyError(name)
    try:
        types = _messages(name)
    except AttributeError:
        raise KeyError(name) from None
    return _object(f".{name}", types)


def open_schema(name: str) -> Schema:
    """Schema of a JSON record with no schema of its own: any object, titled with its name."""
    return {"title": name, "type": "object"}
