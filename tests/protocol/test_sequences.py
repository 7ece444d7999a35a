"""tests/vectors/sequences.jsonl, SPEC.md's example sequences: the virtual agent sends exactly these bytes, each frame
decodes to its fields, and each example shows the rule SPEC.md 1.2 states (sessions, ACK memory, episode order)."""

from __future__ import annotations

import json
from typing import Any

import pytest

from protocol import AckResult, EndReason, Mode, StreamDecoder
from tests.vectors.generate_sequences import SEQUENCES_PATH, render

EXAMPLES = [json.loads(line) for line in SEQUENCES_PATH.read_text(encoding="utf-8").splitlines()]


def _frames(example: dict[str, Any]) -> list[dict[str, Any]]:
    return [f for f in example["frames"] if "elided" not in f]


@pytest.mark.slow  # runs the virtual agent through three examples (its kernels compile on a first run)
def test_the_virtual_agent_sends_exactly_these_bytes() -> None:
    assert render() == SEQUENCES_PATH.read_text(encoding="utf-8"), \
        "run `python -m tests.vectors.generate_sequences` and review the difference"


def test_each_frame_decodes_to_its_fields() -> None:
    for example in EXAMPLES:
        for f in _frames(example):
            (frame,) = StreamDecoder(agent=f["dir"] == "g").feed(bytes.fromhex(f["wire_hex"]))
            assert frame.message.DEFINITION.name == f["msg"]
            assert json.loads(json.dumps(frame.message.to_dict())) == f["fields"], f


def test_a_session_starts_with_hellos_and_a_reused_seq_is_executed_in_the_next() -> None:
    session, reconnect = EXAMPLES[0], EXAMPLES[1]
    for example in (session, reconnect):
        kinds = [(f["dir"], f["msg"]) for f in _frames(example)][:3]
        assert kinds == [("a", "HELLO"), ("g", "HELLO"), ("a", "HELLO")]
        assert bytes.fromhex(_frames(example)[1]["wire_hex"])[0] == 0  # the ground flushes with 0x00 first
    again = [f for f in _frames(reconnect) if f["dir"] == "g" and f["msg"] == "PARAM_GET"][0]
    first = [f for f in _frames(session) if f["dir"] == "g" and f["msg"] == "PARAM_GET"][0]
    assert again["wire_hex"] == first["wire_hex"]  # the same (msg_id, seq)
    after = _frames(reconnect)[_frames(reconnect).index(again) + 1:]
    assert after[0]["msg"] == "ACK" and after[0]["fields"]["result"] == AckResult.ACCEPTED
    assert after[1]["msg"] == "PARAM_VALUE"  # executed: the ACK memory was emptied by the session's start
    replayed = [f["fields"]["sample"] for f in after if f["msg"] == "SAMPLE"]
    log_range = [f for f in after if f["msg"] == "LOG_RANGE"][0]["fields"]
    assert replayed and log_range["replayed"] == len(replayed)


def test_an_episode_starts_and_ends_in_the_order_spec_6_fixes() -> None:
    frames = _frames(EXAMPLES[2])
    starts = [i for i, f in enumerate(frames) if f["msg"] == "EPISODE_START"]
    ends = [i for i, f in enumerate(frames) if f["msg"] == "EPISODE_END"]
    assert len(starts) == len(ends) == 2
    for i in starts:  # the first SAMPLE after EPISODE_START is the episode's first, with the index it announced
        first = next(f for f in frames[i + 1:] if f["msg"] == "SAMPLE")["fields"]
        assert first["sample"] == frames[i]["fields"]["sample"] and first["mode"] == Mode.LEARNING
        assert first["step"] == 0
    natural, aborted = frames[ends[0]], frames[ends[1]]
    last = frames[ends[0] - 1]["fields"]  # the ending step's SAMPLE comes right before its EPISODE_END
    assert natural["fields"]["reason"] != EndReason.ABORTED
    assert last["action"] == 255 and last["sample"] == natural["fields"]["sample"]
    assert aborted["fields"]["reason"] == EndReason.ABORTED
    before = frames[ends[1] - 1]
    assert before["msg"] == "ACK" and frames[ends[1] - 2]["msg"] == "CMD_STOP"  # the ACK first (SPEC 5 and 6)
    shown = [f["fields"]["sample"] for f in frames[: ends[1]] if f["msg"] == "SAMPLE"]
    assert aborted["fields"]["sample"] == shown[-1]
    assert aborted["fields"]["episode"] == natural["fields"]["episode"] + 1
    assert next(f for f in frames[ends[1]:] if f["msg"] == "SAMPLE")["fields"]["mode"] == Mode.SURFACING
