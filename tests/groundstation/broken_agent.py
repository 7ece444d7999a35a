"""A deliberately broken virtual agent for `dive check`'s own tests: the real server process with one rule broken.

    python tests/groundstation/broken_agent.py FAULT[,FAULT] serve --tcp 127.0.0.1:0 ...

Faults: `unknown-no-ack` (no ACK for an unknown command id, as the 1.0 agent did), `rejects-as-frames` (HEARTBEAT
counts rejected chunks in rx_frames instead of rx_rejects), `silence-in-agent-time` (link silence measured on the
agent's clock, which at --speed max runs far ahead of the link's real one).

Conformant variants (what another lab's agent may do, and `dive check` must pass): `optional-unimplemented` (the
optional parameters of SPEC.md 13, `start_at_rest` and those from `shared_model` on, listed with minimum = maximum
= default, as a real agent without the shared-model learners reports them; with `--preset hardware`, whose
`start_at_rest` is 0, it recovers before every episode as a real agent does), `slow-surface` (SURFACING lasts at
least 1 s of agent time, at the surface too: a CMD_SURFACE in IDLE shows SURFACING for a second, as an agent whose
depth filter settles slowly does; SPEC.md 6 says only "until shallower than 0.02 m").

SPEC 1.3's rules, one fault each: `generation-stuck` (a learner restart leaves the generation as it was),
`slow-answers` (every ground frame answered 1.5 s late, over the 1 s bound), `no-cross-refusals` (velocity_filter
with vel_diff_steps, plan_stable_sweeps without shared_model accepted), `no-estimate-cap` (a timestamp ahead becomes
the estimate however far), `no-resync` (PARAM_SET `resync` unknown), `no-link-taken-text` (a replaced connection
closed without its TEXT).
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


def optional_unimplemented() -> None:
    from protocol.parameters import PARAMS
    from simulator.agent.params_table import ParamTable

    original = ParamTable.message

    def message(self: ParamTable, index: int) -> messages.ParamValue:
        built = original(self, index)
        d = PARAMS[index]
        if d.optional:
            return messages.ParamValue(index=index, count=built.count, param_type=built.param_type, value=d.default,
                                       minimum=d.default, maximum=d.default, name=built.name)
        return built

    ParamTable.message = message  # type: ignore[method-assign]


SLOW_SURFACE_US = 1_000_000


def slow_surface() -> None:
    from protocol import Mode
    from simulator.agent.program import OnboardProgram

    original = OnboardProgram._enter

    def enter(self: OnboardProgram, mode: Mode, why: str) -> None:
        if mode == Mode.SURFACING and self.mode != Mode.SURFACING:
            self.surfacing_since_us = self.t_us  # type: ignore[attr-defined]
        elif self.mode == Mode.SURFACING and mode == Mode.IDLE and \
                self.t_us - getattr(self, "surfacing_since_us", 0) < SLOW_SURFACE_US:
            return  # not yet: the surface is noticed a second later
        original(self, mode, why)

    OnboardProgram._enter = enter  # type: ignore[method-assign]


def generation_stuck() -> None:
    """A learner restart that does not count: the 1.3 rule an agent moved from 1.2 may miss."""
    from simulator.agent.modes import ModeMachine

    original = ModeMachine.restarted_learner

    def restarted(self: ModeMachine, why: str) -> None:
        original(self, why)
        self.generation -= 1

    ModeMachine.restarted_learner = restarted  # type: ignore[method-assign]


SLOW_ANSWER_S = 1.5


def slow_answers() -> None:
    """Every ground frame answered 1.5 s late (as an agent compiling its kernels before it answers would be)."""
    import time

    original = Link.receive

    def receive(self: Link, data: bytes) -> None:
        time.sleep(SLOW_ANSWER_S)
        original(self, data)

    Link.receive = receive  # type: ignore[method-assign]


def no_cross_refusals() -> None:
    """velocity_filter with vel_diff_steps (and plan_stable_sweeps without shared_model) stored, not refused."""
    from simulator.agent.program import OK, OnboardProgram

    original = OnboardProgram.set_param

    def set_param(self: OnboardProgram, index: int, value: float) -> tuple[AckResult, str]:
        verdict = original(self, index, value)
        if verdict[0] == AckResult.BAD_VALUE and self.table.defs[index].name in ("velocity_filter",
                                                                                  "plan_stable_sweeps"):
            self.table.values[index] = value  # kept on the list, never applied to the learner
            return OK
        return verdict

    OnboardProgram.set_param = set_param  # type: ignore[method-assign]


def no_estimate_cap() -> None:
    """1.1's rule: a timestamp higher than the estimate becomes the estimate, however far ahead (no 10 s cap)."""
    import protocol.signing

    protocol.signing.ESTIMATE_STEP_S = 1e9  # type: ignore[misc]


def no_resync() -> None:
    """No signed re-sync: PARAM_SET `resync` is an unknown parameter (BAD_VALUE), as for a 1.1 agent."""
    agent_link.is_resync = lambda message: False  # type: ignore[assignment]


def no_link_taken_text() -> None:
    """A replaced connection closed without the TEXT `link taken by another ground` (as a 1.1 agent does)."""
    from simulator.serve.loop import AgentServer

    AgentServer._replaced_notice = lambda self: b""  # type: ignore[method-assign]


FAULTS: dict[str, Callable[[], None]] = {"unknown-no-ack": unknown_no_ack, "rejects-as-frames": rejects_as_frames,
                                         "silence-in-agent-time": silence_in_agent_time,
                                         "optional-unimplemented": optional_unimplemented,
                                         "slow-surface": slow_surface, "generation-stuck": generation_stuck,
                                         "slow-answers": slow_answers, "no-cross-refusals": no_cross_refusals,
                                         "no-estimate-cap": no_estimate_cap, "no-resync": no_resync,
                                         "no-link-taken-text": no_link_taken_text}

if __name__ == "__main__":
    for name in sys.argv.pop(1).split(","):
        FAULTS[name]()
    main()
