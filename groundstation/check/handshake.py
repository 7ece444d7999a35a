"""Handshake and sequence tracking: HELLO both ways, the agent's seq counter, loss counted from ours (SPEC.md 1, 4)."""

from __future__ import annotations

import os

from groundstation.check.errors import CheckFailed, CheckSkipped
from groundstation.check.probe import Probe
from groundstation.check.registry import check, expect
from groundstation.session.hello import ground_hello
from protocol import PROTOCOL_VERSION, NodeKind, definitions_hash
from protocol import messages as m

LINK = "4 Link life cycle"
FRAME = "1 Frame: sequence numbers"
UNPROMPTED_HELLO_S = 1.5  # a serial agent repeats its HELLO once per second until it hears the ground
HELLO_REPEAT_S = 1.5  # one repeat is due within a second of link time after the first HELLO (plus the reply wait)


def _ground_hello() -> m.Hello:
    return ground_hello(int.from_bytes(os.urandom(4), "little"), int.from_bytes(os.urandom(4), "little"))


@check("handshake.agent_hello", LINK, """The agent sends HELLO when it boots and whenever it sees a link come up (a new
       TCP connection). Until it has received a frame from the ground that passed the CRC and version checks, it
       repeats its HELLO once per second of link time.""")
def agent_hello(probe: Probe) -> str:
    probe.keepalive = False  # the ground stays silent until the agent has repeated its HELLO (next check)
    found = probe.wait_message(m.Hello, 0, UNPROMPTED_HELLO_S)
    if found is not None:
        return "HELLO arrived unprompted"
    start = probe.end
    probe.send(_ground_hello())
    answer = probe.wait_message(m.Hello, start, probe.timeouts.reply_s)
    if answer is None:
        raise CheckFailed(f"no HELLO, neither unprompted within {UNPROMPTED_HELLO_S:g} s nor in answer to ours")
    if probe.link.url.startswith(("tcp://", "sim://")):
        raise CheckFailed("no HELLO on the new TCP connection (only in answer to ours)")
    return "no unprompted HELLO (a serial agent that already heard a ground); it answered ours"


@check("handshake.hello_repeat", LINK, """Until it has received a frame from the ground that passed the CRC and
       version checks, it repeats its HELLO once per second of link time.""")
def hello_repeat(probe: Probe) -> str:
    if probe.sent_valid:
        raise CheckSkipped("the agent had to be asked for its HELLO (it heard a ground before this run)")
    try:
        found = probe.wait(lambda _: len(probe.messages(m.Hello, 0)) >= 2, 0, HELLO_REPEAT_S + probe.timeouts.reply_s)
    finally:
        probe.keepalive = True
    hellos = len(probe.messages(m.Hello, 0))
    waited = HELLO_REPEAT_S + probe.timeouts.reply_s
    expect(found is not None, f"{hellos} HELLO in {waited:g} s of silence from the ground, wanted a repeat")
    return "HELLO repeated while the ground was silent"


@check("handshake.hello_fields", "3 Messages: HELLO", """protocol_version: protocol major version; 1.
       node_kind: 1 = agent. definitions_hash: hash of the message definition table. boot_id: random, new after
       every reboot.""")
def hello_fields(probe: Probe) -> str:
    hello = probe.hello
    expect(hello is not None, "no HELLO received")
    assert hello is not None
    expect(hello.protocol_version == PROTOCOL_VERSION,
           f"protocol_version {hello.protocol_version}, wanted {PROTOCOL_VERSION}")
    expect(hello.node_kind == NodeKind.AGENT, f"node_kind {hello.node_kind}, wanted {int(NodeKind.AGENT)} (agent)")
    expect(hello.definitions_hash == definitions_hash(),
           f"definitions_hash 0x{hello.definitions_hash:08X}, this dive has 0x{definitions_hash():08X}")
    expect(hello.boot_id != 0, "boot_id is 0")
    return (f"{hello.name!r} firmware {hello.firmware_major}.{hello.firmware_minor}.{hello.firmware_patch}, "
            f"hash 0x{hello.definitions_hash:08X}")


@check("handshake.answers_every_hello", LINK, """The agent answers every HELLO from the ground with its own HELLO (on
       any link), at once.""")
def answers_every_hello(probe: Probe) -> str:
    boot = probe.hello.boot_id if probe.hello else None
    answers = 0
    for _ in range(2):
        start = probe.end
        probe.send(_ground_hello())
        found = probe.wait_message(m.Hello, start, probe.timeouts.reply_s)
        expect(found is not None, f"ground HELLO {answers + 1} got no HELLO back within {probe.timeouts.reply_s:g} s")
        assert found is not None
        expect(found[1].boot_id == boot, f"boot_id changed from {boot} to {found[1].boot_id} without a reboot")
        answers += 1
    return "2 ground HELLOs, 2 HELLOs back"


@check("handshake.heartbeat", LINK, """Both sides send HEARTBEAT once per second of their own clock (the agent: agent
       time). HEARTBEAT reports log_first_sample (the oldest SAMPLE index held) and log_next_sample.""")
def heartbeat(probe: Probe) -> str:
    start = probe.end
    beats: list[m.Heartbeat] = []
    while len(beats) < 3:
        found = probe.wait_message(m.Heartbeat, start, probe.timeouts.heartbeat_s)
        expect(found is not None, f"{len(beats)} HEARTBEATs, then none for {probe.timeouts.heartbeat_s:g} s")
        assert found is not None
        start = found[0] + 1
        beats.append(found[1])
    gaps = [(b.uptime_ms - a.uptime_ms) & 0xFFFFFFFF for a, b in zip(beats, beats[1:], strict=False)]
    expect(all(800 <= g <= 1200 for g in gaps), f"uptime_ms between HEARTBEATs {gaps}, wanted about 1000")
    last = beats[-1]
    expect(last.log_first_sample <= last.log_next_sample,
           f"log_first_sample {last.log_first_sample} > log_next_sample {last.log_next_sample}")
    return f"uptime_ms steps {gaps}"


@check("seq.agent_counter", FRAME, """seq: sender's frame counter, +1 per frame sent (any message), wraps
       65535 → 0. Each side keeps one counter for all frames it sends.""")
def agent_counter(probe: Probe) -> str:
    probe.settle(0.3)
    stats = probe.decoder.stats
    expect(stats.lost == 0 and stats.duplicates == 0,
           f"the agent's frames so far: {stats.lost} lost, {stats.duplicates} duplicates by seq on a clean link")
    return f"{stats.frames} frames in order"


@check("seq.gap_counted", FRAME, """Synchronised, a frame with seq gives gap = (seq - expected) mod 65536. If
       gap < 32768, gap frames were lost (lost += gap) and expected = seq + 1. rx_lost: the sum of the sequence
       gaps.""")
def gap_counted(probe: Probe) -> str:
    before = probe.counters()
    probe.skip_seqs(5)
    after = probe.counters()
    lost = (after.rx_lost - before.rx_lost) & 0xFFFFFFFF
    expect(lost == 5, f"5 seqs skipped, rx_lost grew by {lost}")
    return "5 seqs skipped, rx_lost +5"


@check("seq.late_not_lost", FRAME, """otherwise the frame is late or a retry (duplicates += 1) and expected is
       unchanged.""")
def late_not_lost(probe: Probe) -> str:
    before = probe.counters()
    old = (probe.upcoming_seq - 100) & 0xFFFF
    probe.send(m.Timesync(origin_us=1, receive_us=2, transmit_us=3), seq=old)  # a reply: nothing answers it
    after = probe.counters()
    lost = (after.rx_lost - before.rx_lost) & 0xFFFFFFFF
    expect(lost == 0, f"a frame 100 seqs late made rx_lost grow by {lost}")
    return "a late frame is not a loss"


@check("seq.hello_resets", FRAME, """Any HELLO received resets tracking to unsynchronised before the HELLO is
       counted, so the HELLO itself synchronises.""")
def hello_resets(probe: Probe) -> str:
    before = probe.counters()
    probe.skip_seqs(1000)
    start = probe.end
    probe.send(_ground_hello())
    expect(probe.wait_message(m.Hello, start, probe.timeouts.reply_s) is not None, "no HELLO in answer")
    after = probe.counters()
    lost = (after.rx_lost - before.rx_lost) & 0xFFFFFFFF
    expect(lost == 0, f"a HELLO 1000 seqs ahead made rx_lost grow by {lost}")
    return "a HELLO 1000 seqs ahead counted no loss"
