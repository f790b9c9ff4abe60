"""Checking a run log against the JSON schemas its channels declare, as Foxglove reads them."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from jsonschema import Draft202012Validator
from mcap.reader import make_reader


def validate_channels(path: Path) -> Counter[str]:
    """Validate every message of the MCAP at `path` against its channel's JSON schema; returns the count per schema.

    Raises:
        jsonschema.ValidationError: the first message that breaks its schema.
        AssertionError: a channel without a JSON schema or a schema that says nothing of its fields.
    """
    counts: Counter[str] = Counter()
    validators: dict[int, Draft202012Validator] = {}
    with path.open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            if channel.id not in validators:
                assert schema is not None and schema.encoding == "jsonschema", f"{channel.topic} has no JSON schema"
                definition = json.loads(schema.data)
                assert definition.get("properties"), f"{channel.topic}: schema {schema.name} names no fields"
                Draft202012Validator.check_schema(definition)
                validators[channel.id] = Draft202012Validator(definition)
            validators[channel.id].validate(json.loads(message.data))
            counts[schema.name] += 1
    return counts
