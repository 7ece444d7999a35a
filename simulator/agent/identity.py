"""Who the virtual agent says it is: its HELLO, built in one place for the program's link and the starting agent."""

from __future__ import annotations

from protocol import PROTOCOL_VERSION, NodeKind, definitions_hash, messages

FIRMWARE_VERSION = (0, 1, 1)
AGENT_NAME = "sim-agent"
FIRST_GENERATION = 1  # SPEC 1.3 s. 6: the learner's generation at boot, +1 at every learner restart
HELLO_REPEAT_S = 1.0  # SPEC s. 4: HELLO once per second of link time until the ground is heard


def agent_hello(node_id: int, boot_id: int, generation: int) -> messages.Hello:
    major, minor, patch = FIRMWARE_VERSION
    return messages.Hello(
        protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.AGENT), definitions_hash=definitions_hash(),
        firmware_major=major, firmware_minor=minor, firmware_patch=patch, node_id=node_id, boot_id=boot_id,
        name=AGENT_NAME, generation=generation,
    )
