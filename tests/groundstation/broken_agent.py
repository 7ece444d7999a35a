"""A deliberately broken virtual agent for `dive check`'s own tests: the real server process with one rule broken.

    python tests/groundstation/broken_agent.py FAULT[,FAULT] serve --tcp 127.0.0.1:0 ...

Faults: `unknown-no-ack` (no ACK for an unknown command id, as the 1.0 agent did), `rejects-as-frames` (HEARTBEAT
counts rejected chunks in rx_frames instead of rx_rejects), `silence-in-agent-time` (link silence measured on the
agent's clock, which at --speed max runs far ahead of the link's real one).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from protocol import AckResult, messages
from protocol.decoder import Frame
from simulator.agent import link as agent_link
from simulator.cli import main

Link = agent_link.AgentLink


def unknown_no_ack() -> None:
    original = Link._ack

    def ack(self: Link, frame: Frame, result: AckResult, reason: str) -> None:
        if result != AckResult.UNSUPPORTED:
            original(self, frame, result, reason)

    Link._ack = ack  # type: ignore[method-assign]


def rejects_as_frames() -> None:
    def heartbeat(self: Link) -> None:
        prog, stats = self._prog, self.decoder.stats
        self.send(messages.Heartbeat(
            uptime_ms=(prog.t_us // 1000) & 0xFFFFFFFF, mode=int(prog.mode), battery_mv=int(prog.hw.battery_v * 1000),
            rx_frames=stats.frames + stats.rejects, rx_rejects=0, rx_lost=stats.lost,
            log_first_sample=self.ring.first_sample, log_next_sample=prog.next_sample, episode=prog.episode,
            signing_rejects=self.signing_rejects & 0xFFFFFFFF,
        ))

    Link.heartbeat = heartbeat  # type: ignore[method-assign]


def silence_in_agent_time() -> None:
    original = Link.__init__

    def init(self: Link, *args: Any, **kwargs: Any) -> None:
        original(self, *args, **kwargs)
        self.link_clock_s = self._agent_clock_s  # link silence on the agent's clock, not the link's real one

    Link.__init__ = init  # type: ignore[method-assign]


FAULTS: dict[str, Callable[[], None]] = {"unknown-no-ack": unknown_no_ack, "rejects-as-frames": rejects_as_frames,
                                         "silence-in-agent-time": silence_in_agent_time}

if __name__ == "__main__":
    for name in sys.argv.pop(1).split(","):
        FAULTS[name]()
    main()
