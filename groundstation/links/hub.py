"""hub:// links: attach to a running `dive run`'s session through its hub (hub:// = the one run, hub://RUN = that one).

The hub speaks the agent's frame protocol over loopback TCP, so this is a TCP link whose address comes from
the run's announcement file (groundstation/runs.py), looked up again on every reconnect.
"""

from __future__ import annotations

from groundstation.links.tcp import TcpLink, parse_host_port
from groundstation.runs import hub_address


class HubLink(TcpLink):
    def __init__(self, url: str) -> None:
        self.hub_url = url
        info, address = hub_address(url)
        super().__init__(address)
        self.url = url if "://" in url and url.split("://", 1)[1] else f"hub://{info.run}"
        self.run = info

    def _connect(self) -> None:
        _, address = hub_address(self.url)
        self.host, self.port = parse_host_port(address)
        super()._connect()
