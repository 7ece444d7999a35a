"""The bytes an agent with one connection slot sends a connection a new one replaces (SPEC.md s.4, *A link taken*)."""

from __future__ import annotations

from protocol import messages
from protocol.encoder import FrameEncoder
from protocol.enums import LINK_TAKEN_TEXT, Severity


def link_taken_notice(t_us: int = 0) -> bytes:
    """A 0x00 delimiter (ending any partial frame sent before it), then the TEXT frame, severity WARNING, text
    `link taken by another ground`, with a seq of its own (SPEC: it need not follow the connection's).

    The one builder: the virtual agent (with its agent time), the QEMU relay and, through `python -m protocol.gen_c`
    (firmware/generated/link_taken_frame.h), the ESP8266 bridge, which knows no agent time (t_us 0: a ground acts
    on the text).
    """
    text = messages.Text(t_us=t_us, severity=int(Severity.WARNING), text=LINK_TAKEN_TEXT)
    return b"\x00" + FrameEncoder().encode(text).wire
