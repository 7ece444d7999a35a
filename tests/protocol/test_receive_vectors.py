"""tests/vectors/receive.jsonl through an agent's decoder: counters by cause, and which commands are handed over."""

from __future__ import annotations

import json
from typing import Any

import pytest

from protocol import StreamDecoder
from protocol.decoder import COMMAND_IDS_FROM, UndecodedCommand
from tests.vectors.generate_receive import RECEIVE_VECTORS_PATH, render

VECTORS: list[dict[str, Any]] = [json.loads(line) for line in RECEIVE_VECTORS_PATH.read_text().splitlines()]


def test_the_file_is_what_the_generator_writes() -> None:
    assert RECEIVE_VECTORS_PATH.read_text(encoding="utf-8") == render()


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v["name"][:40])
def test_an_agent_decoder_counts_and_hands_over_as_the_vector_says(vector: dict[str, Any]) -> None:
    decoder = StreamDecoder(agent=True)
    frames = decoder.feed(bytes.fromhex(vector["wire_hex"]))
    stats = decoder.stats
    assert (stats.frames, stats.rejects, stats.lost) == (vector["rx_frames"], vector["rx_rejects"], vector["rx_lost"])
    if vector["cause"] is not None:
        assert getattr(stats, vector["cause"]) == 1
    commands = [f for f in frames if f.msg_id >= COMMAND_IDS_FROM]
    assert len(commands) == len(vector["ack"])
    for frame, ack in zip(commands, vector["ack"], strict=True):
        undecoded = isinstance(frame.message, UndecodedCommand)
        assert undecoded == (ack in ("UNSUPPORTED", "UNAUTHORIZED"))


def test_a_ground_decoder_drops_unknown_command_ids_as_before() -> None:
    unknown = next(v for v in VECTORS if v["name"].startswith("unknown command id 0x8C"))
    decoder = StreamDecoder()
    assert decoder.feed(bytes.fromhex(unknown["wire_hex"])) == [] and decoder.stats.unknown_id == 1
