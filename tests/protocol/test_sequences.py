"""tests/vectors/sequences.jsonl, SPEC.md's example sequences: the virtual agent sends exactly these bytes, each frame
decodes to its fields, and each example shows the rule SPEC.md 1.2 states (sessions, ACK memory, episode order)."""

from __future__ import annotations

import json

import pytest

from protocol import StreamDecoder
from tests.protocol.sequence_rules import (
    check_episode_order,
    check_learner_restart,
    check_reused_seq_is_executed,
    check_session_start,
    shown,
)
from tests.vectors.generate_sequences import SEQUENCES_PATH, render

EXAMPLES = [json.loads(line) for line in SEQUENCES_PATH.read_text(encoding="utf-8").splitlines()]


@pytest.mark.slow  # runs the virtual agent through three examples (its kernels compile on a first run)
def test_the_virtual_agent_sends_exactly_these_bytes() -> None:
    assert render() == SEQUENCES_PATH.read_text(encoding="utf-8"), \
        "run `python -m tests.vectors.generate_sequences` and review the difference"


def test_each_frame_decodes_to_its_fields() -> None:
    for example in EXAMPLES:
        for f in shown(example["frames"]):
            (frame,) = StreamDecoder(agent=f["dir"] == "g").feed(bytes.fromhex(f["wire_hex"]))
            assert frame.message.DEFINITION.name == f["msg"]
            assert json.loads(json.dumps(frame.message.to_dict())) == f["fields"], f


def test_a_session_starts_with_hellos_and_a_reused_seq_is_executed_in_the_next() -> None:
    check_session_start(EXAMPLES[0]["frames"])
    check_session_start(EXAMPLES[1]["frames"])
    check_reused_seq_is_executed(EXAMPLES[0]["frames"], EXAMPLES[1]["frames"])


def test_an_episode_starts_and_ends_in_the_order_spec_6_fixes() -> None:
    check_episode_order(EXAMPLES[2]["frames"])


def test_a_learner_restart_is_a_new_generation_with_episodes_from_1() -> None:
    check_learner_restart(EXAMPLES[3]["frames"])
