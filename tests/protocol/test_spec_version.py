"""SPEC.md's version and the wire's: 1.2 is the document's, the wire keeps major 1, so a 1.1 ground and a 1.2 agent
(and the other way round) greet and understand each other."""

from __future__ import annotations

from protocol import PROTOCOL_VERSION, FrameEncoder, NodeKind, StreamDecoder, definitions_hash, messages
from protocol.enums import SPEC_VERSION
from protocol.spec import SPEC_PATH

SPEC_TEXT = SPEC_PATH.read_text(encoding="utf-8")
# The definitions hash printed by SPEC.md 1.1 (section 3), which a 1.1 peer hard-codes and sends in its HELLO.
HASH_OF_1_1 = 0x69BE26C5


def test_the_spec_says_its_version_and_the_wire_keeps_major_1() -> None:
    assert SPEC_TEXT.startswith(f"# Diving agent wire protocol, version {SPEC_VERSION}\n")
    assert SPEC_VERSION.split(".")[0] == str(PROTOCOL_VERSION) == "1"
    assert "## 14. Changes from 1.1" in SPEC_TEXT
    assert SPEC_TEXT.count("(1.2)") >= 15  # the checklist of s. 15 marks every 1.2 item


def test_a_1_1_hello_and_a_1_2_hello_are_the_same_bytes() -> None:
    """Nothing in HELLO (protocol_version, definitions_hash) tells 1.1 from 1.2: neither refuses the other."""
    hello = messages.Hello(protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.GROUND),
                           definitions_hash=definitions_hash(), node_id=7, boot_id=1)
    assert definitions_hash() == HASH_OF_1_1
    wire = FrameEncoder(first_seq=0).encode(hello).wire
    (frame,) = StreamDecoder(agent=True).feed(wire)
    assert frame.message == hello and frame.message.protocol_version == 1
