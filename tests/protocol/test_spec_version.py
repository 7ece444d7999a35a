"""SPEC.md's version and the wire's: 1.3 is the document's, the wire keeps major 1; 1.3 appends the learner's
generation to four messages, so its table hash differs, and a 1.3 ground still talks to a 1.0-1.2 agent."""

from __future__ import annotations

from groundstation.session.hello import incompatibility, sends_generation
from protocol import PROTOCOL_VERSION, FrameEncoder, NodeKind, StreamDecoder, definitions_hash, messages
from protocol.enums import SPEC_VERSION
from protocol.spec import SPEC_PATH

SPEC_TEXT = SPEC_PATH.read_text(encoding="utf-8")
# The definitions hash printed by SPEC.md 1.0-1.2 (section 3), which such a peer hard-codes and sends in its HELLO.
HASH_OF_1_2 = 0x69BE26C5


def test_the_spec_says_its_version_and_the_wire_keeps_major_1() -> None:
    assert SPEC_TEXT.startswith(f"# Diving agent wire protocol, version {SPEC_VERSION}\n")
    assert SPEC_VERSION.split(".")[0] == str(PROTOCOL_VERSION) == "1"
    assert "## 14. Changes from 1.2" in SPEC_TEXT
    assert SPEC_TEXT.count("(1.3)") >= 8  # the checklist of s. 15 and the new fields mark every 1.3 item


def test_the_1_2_table_is_the_1_3_table_without_the_generation_fields() -> None:
    assert definitions_hash(before_1_3=True) == HASH_OF_1_2 != definitions_hash()
    assert f"0x{HASH_OF_1_2:08X}" in SPEC_TEXT and f"0x{definitions_hash():08X}" in SPEC_TEXT


def test_a_1_3_ground_talks_to_a_1_2_agent_whose_generation_reads_0() -> None:
    """A 1.2 agent's HELLO and EPISODE_END are shorter by the generation: they zero-extend, 0 = not sent."""
    old = messages.Hello(protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.AGENT),
                         definitions_hash=HASH_OF_1_2, node_id=7, boot_id=1)
    assert incompatibility(old) is None and not sends_generation(old)
    end = messages.EpisodeEnd(episode=3, generation=2)
    short = FrameEncoder(first_seq=0).encode_payload(messages.EpisodeEnd.DEFINITION.msg_id, end.pack()[:-4]).wire
    (frame,) = StreamDecoder(agent=False).feed(short)
    assert frame.message.episode == 3 and frame.message.generation == 0
    new = messages.Hello(protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.AGENT),
                         definitions_hash=definitions_hash(), node_id=7, boot_id=1, generation=1)
    assert incompatibility(new) is None and sends_generation(new)
    stranger = messages.Hello(protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.AGENT),
                              definitions_hash=0x12345678, node_id=7, boot_id=1)
    assert incompatibility(stranger) is not None
