"""JSON Schema of each message, with units, generated from the definition table (for MCAP channels)."""

from __future__ import annotations

from typing import Any

from protocol.registry import MessageDef


def message_json_schema(definition: MessageDef) -> dict[str, Any]:
    """A draft 2020-12 JSON Schema for `Message.to_dict()` of one message (bytes as hex strings)."""
    properties: dict[str, Any] = {}
    for f in definition.fields:
        prop: dict[str, Any] = {"type": f.wire.json_type, "description": f.doc}
        if f.unit:
            prop["description"] = f"{f.doc} [{f.unit}]"
            prop["unit"] = f.unit
        if f.wire.minimum is not None:
            prop["minimum"] = f.wire.minimum
            prop["maximum"] = f.wire.maximum
        if f.wire.spec_name == "bytes[]":
            prop["contentEncoding"] = "base16"
        prop["x-wire-type"] = f.wire.spec_name
        properties[f.name] = prop
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": definition.name,
        "description": definition.doc,
        "type": "object",
        "properties": properties,
        "required": [f.name for f in definition.fields],
        "x-msg-id": definition.msg_id,
    }
