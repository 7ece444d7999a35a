"""TIMESYNC: the agent answers a request at once with its own clock, and never answers a reply (SPEC.md 9)."""

from __future__ import annotations

import time

from groundstation.check.probe import Probe
from groundstation.check.registry import check, expect
from protocol import messages as m

SECTION = "9 TIMESYNC"


def _exchange(probe: Probe, origin_us: int) -> m.Timesync:
    start = probe.end
    probe.send(m.Timesync(origin_us=origin_us, receive_us=0, transmit_us=0))
    found = probe.wait_message(m.Timesync, start, probe.timeouts.reply_s, lambda t: t.origin_us == origin_us)
    expect(found is not None, f"no TIMESYNC answer within {probe.timeouts.reply_s:g} s")
    assert found is not None
    return found[1]


@check("timesync.reply", SECTION, """The agent answers at once with origin_us echoed, receive_us = t2 (agent clock
       when the request arrived) and transmit_us = t3 (agent clock when it sends the reply).""")
def reply(probe: Probe) -> str:
    origin = time.time_ns() // 1000
    first = _exchange(probe, origin)
    second = _exchange(probe, origin + 1)
    for r in (first, second):
        expect(r.transmit_us >= r.receive_us, f"transmit_us {r.transmit_us} < receive_us {r.receive_us}")
    expect(second.receive_us >= first.transmit_us,
           f"the agent clock went back: {first.transmit_us} then {second.receive_us} µs")
    return f"agent clock {second.receive_us / 1e6:.3f} s, origin echoed"


@check("timesync.reply_not_request", SECTION, """A reply never carries transmit_us = 0: an agent whose clock reads 0
       sends 1.""")
def reply_not_request(probe: Probe) -> str:
    answer = _exchange(probe, 12345)
    expect(answer.transmit_us != 0, "a reply with transmit_us = 0 reads as a request")
    return f"transmit_us = {answer.transmit_us}"


@check("timesync.reply_unanswered", SECTION, """The agent ignores a TIMESYNC that is not a request.""")
def reply_unanswered(probe: Probe) -> str:
    start = probe.end
    probe.send(m.Timesync(origin_us=777, receive_us=5, transmit_us=6))
    probe.barrier()
    echoed = [t for t in probe.messages(m.Timesync, start) if t.origin_us == 777]
    expect(not echoed, "the agent answered a TIMESYNC reply")
    return "a reply got no answer"
