"""A recording read back by the mcap library itself, every JSON message validated against its schema."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
from mcap.reader import make_reader


def validate_with_mcap_library(path: Path) -> dict[str, int]:
    """Read with the mcap library itself (indexed reader) and validate every JSON message."""
    counts: dict[str, int] = {}
    validators: dict[int, jsonschema.Draft202012Validator] = {}
    with path.open("rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "diving-agent"
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.message_encoding == "json":
                assert schema is not None and schema.encoding == "jsonschema"
                if schema.id not in validators:
                    body = json.loads(schema.data)
                    jsonschema.Draft202012Validator.check_schema(body)
                    validators[schema.id] = jsonschema.Draft202012Validator(body)
                validators[schema.id].validate(json.loads(message.data))
            else:
                assert channel.message_encoding == "diving-agent-frame-v1"
            assert message.log_time > 1_600_000_000 * 10**9
        names = {m.name for m in reader.iter_metadata()}
    assert {"agent_hello", "parameters", "host", "session"} <= names
    return counts
