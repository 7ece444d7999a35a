"""Who we are and whether an agent speaks our protocol: the HELLO both sides send (SPEC.md section 4)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from protocol import PROTOCOL_VERSION, NodeKind, definitions_hash
from protocol import messages as m

NAME_BYTES = 23  # HELLO.name is char[24], NUL-terminated when shorter


def tool_version() -> str:
    try:
        return version("diving-agent")
    except PackageNotFoundError:
        return "0.0.0"


def ground_hello(node_id: int, boot_id: int, name: str = "dive") -> m.Hello:
    """The ground station's HELLO: protocol version, definitions hash, and dive's version as firmware x.y.z."""
    major, minor, patch = (int(x) if x.isdigit() else 0 for x in (tool_version().split(".") + ["0"] * 3)[:3])
    return m.Hello(protocol_version=PROTOCOL_VERSION, node_kind=int(NodeKind.GROUND),
                   definitions_hash=definitions_hash(), firmware_major=major, firmware_minor=minor,
                   firmware_patch=patch, node_id=node_id, boot_id=boot_id,
                   name=name.encode()[:NAME_BYTES].decode(errors="ignore"))


def incompatibility(hello: m.Hello) -> str | None:
    """Why we cannot talk to the sender of `hello`, naming both sides' versions; None when we can."""
    if hello.protocol_version != PROTOCOL_VERSION:
        return (f"the agent speaks protocol version {hello.protocol_version}, this ground station speaks "
                f"version {PROTOCOL_VERSION}")
    if hello.definitions_hash not in (definitions_hash(), definitions_hash(before_1_3=True)):
        return (f"the agent's message table (hash {hello.definitions_hash:08x}, firmware "
                f"{hello.firmware_major}.{hello.firmware_minor}.{hello.firmware_patch}) differs from ours "
                f"(hash {definitions_hash():08x}, dive {tool_version()})")
    return None


def sends_generation(hello: m.Hello) -> bool:
    """A 1.3 agent numbers its learner generations (SPEC.md s. 6); a 1.0-1.2 agent's `generation` fields read 0."""
    return hello.definitions_hash == definitions_hash()
