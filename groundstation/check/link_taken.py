"""A link taken by another ground (SPEC.md s. 4, 1.2): the old connection gets one TEXT, then a graceful close.

An agent lacking it passed `dive check` 1.2 (spec review of 1.2); this check fails it
(tests/groundstation/broken_agent.py `no-link-taken-text`). It opens a second TCP connection to the agent, as a
second ground would, reads the probe's own (now replaced) connection to its end, then takes the link back.
"""

from __future__ import annotations

import contextlib
import socket
import time

from groundstation.check.agent import skip_unless
from groundstation.check.probe import Probe
from groundstation.check.registry import check, expect
from groundstation.errors import LinkError
from groundstation.links.tcp import parse_host_port
from protocol import NodeKind, definitions_hash
from protocol import messages as m
from protocol.enums import LINK_TAKEN_TEXT

SECTION = "4 Link life cycle: a link taken by another ground (1.3)"
CLOSE_WAIT_S = 8.0  # the old connection's TEXT and close, with room for the agent's lingering read (at most 5 s)


@check("link.taken", SECTION, """An agent with one connection slot [...] that accepts a new connection while it
       holds one first sends the old connection one TEXT, severity WARNING (2), text exactly `link taken by another
       ground`, with a 0x00 delimiter before it (ending any partial frame), then closes it [...] so that the close
       is not a reset that discards the TEXT""")
def taken(probe: Probe) -> str:
    url = probe.link.url
    skip_unless(url.startswith("tcp://"), "a TCP agent only (an agent behind a UART has no second connection)")
    host, port = parse_host_port(url)
    start = probe.end
    closed = ""
    keepalive, probe.keepalive = probe.keepalive, False  # only read: a write to the closing link is no answer
    other = socket.create_connection((host, port), timeout=5.0)
    try:
        deadline = time.monotonic() + CLOSE_WAIT_S
        while time.monotonic() < deadline:
            try:
                probe.pump(0.2)
            except LinkError as e:
                closed = str(e)
                break
    finally:
        other.close()
        probe.keepalive = keepalive
    texts = [t for t in probe.messages(m.Text, start) if t.text == LINK_TAKEN_TEXT]
    _take_back(probe)
    expect(bool(texts), f"no TEXT `{LINK_TAKEN_TEXT}` on the replaced connection"
           + (f" before it ended ({closed})" if closed else f" within {CLOSE_WAIT_S:g} s"))
    expect(texts[0].severity == 2, f"the TEXT's severity {texts[0].severity}, wanted 2 (WARNING)")
    expect(bool(closed), f"the replaced connection was still open after {CLOSE_WAIT_S:g} s")
    expect("closed by the agent" in closed, f"the replaced connection ended with a reset, not a close: {closed}")
    return f"TEXT `{LINK_TAKEN_TEXT}` (WARNING), then the old connection closed"


def _take_back(probe: Probe) -> None:
    """The probe's link again, and a session on it (the checks after this one need the agent)."""
    with contextlib.suppress(LinkError):
        probe.link.reconnect()
    start = probe.end
    probe.send(m.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND), definitions_hash=definitions_hash(),
                       node_id=0xC4EC, boot_id=1, name="dive check"))
    probe.wait_message(m.Hello, start, probe.timeouts.reply_s)
