"""hub:// links: attach to a running `dive run`'s session through its hub (hub:// = the one run, hub://RUN = that one).

The hub speaks the agent's frame protocol over loopback TCP, so this is a TCP link whose address comes from
the run's announcement file (groundstation/links/runs.py), looked up again on every reconnect.
"""

from __future__ import annotations

import time

from groundstation.links.hub_auth import HubAuthError, HubFullError, HubProofError, tool_side
from groundstation.links.runs import hub_address, withdraw
from groundstation.links.tcp import TcpLink, parse_host_port

# Not the agent link's 2 KiB: the hub does not wait for a slow reader (it queues for it, then drops it), so a small
# window keeps no backlog away and only stalls. With 2 KiB a tool's round trip at --speed max stalled 40-60 ms about
# one command in five (the size of Linux's delayed ACK: a window that small seems to reopen only with one); 16 KiB:
# p50 7.7 ms, p95 15.0 ms, max 17.3 ms against 10.6, 62.7 and 63.9 (benchmarks/link_latency_bench.py, load ~1).
HUB_RECEIVE_BUFFER_BYTES = 16 * 1024
FULL_RETRIES = 3  # a full hub is asked again this many times, FULL_RETRY_S apart, before the tool gives up
FULL_RETRY_S = 1.0
MARKER_CONFIRMATION = "marker recorded"  # the TEXT a hub answers a tool's marker (TEXT) with, once it is recorded


class HubLink(TcpLink):
    def __init__(self, url: str) -> None:
        self.hub_url = url
        info, address = hub_address(url)
        super().__init__(address, HUB_RECEIVE_BUFFER_BYTES)
        self.url = url if "://" in url and url.split("://", 1)[1] else f"hub://{info.run}"
        self.run = info

    def _connect(self) -> None:
        for attempt in range(FULL_RETRIES + 1):
            try:
                self._attach()
                return
            except HubFullError:
                if attempt == FULL_RETRIES:
                    raise
                time.sleep(FULL_RETRY_S)  # a tool ends and frees its slot: the owner's `dive surface` gets in

    def _attach(self) -> None:
        info, address = hub_address(self.url)
        self.host, self.port = parse_host_port(address)
        super()._connect()
        sock = self._socket()
        try:
            sock.setblocking(True)
            tool_side(sock, info.token, f"hub://{info.run} ({address})")
            sock.setblocking(False)
        except HubAuthError as e:
            self._disconnect()
            if isinstance(e, HubProofError):
                withdraw(info)  # a wrong proof: whatever answers there, it is not that run; its announcement is stale
            raise
