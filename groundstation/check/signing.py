"""Signing: an agent with a key refuses every command not validly signed, once, and counts it (SPEC.md 12)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable

from groundstation.check.probe import Exchange, Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult, FrameFlag, Signer
from protocol import messages as m
from protocol.crc import crc16_ccitt_false

SECTION = "12 Signing"
_REFUSED = "refused (UNAUTHORIZED)"


def _get() -> m.ParamGet:
    return m.ParamGet(index=0, name="")


def _signer_at(probe: Probe, offset_s: float, link_id: int | None = None) -> Signer:
    """A signer with the probe's key whose clock is `offset_s` from now (a new link id unless one is given)."""
    assert probe.key is not None
    own = probe.signer.link_id if probe.signer else 0
    chosen = link_id if link_id is not None else (own + 1 + os.urandom(1)[0] % 254) % 256
    return Signer(probe.key, chosen, clock_ns=lambda: time.time_ns() + int(offset_s * 1e9))


def refused_once(probe: Probe, send: Callable[[], Exchange], what: str) -> str:
    """`send` gets exactly one ACK UNAUTHORIZED, is not executed, and signing_rejects grows by 1."""
    before = probe.counters()
    ex = send()
    probe.barrier()
    acks = probe.acks_for(ex)
    expect(len(acks) == 1, f"{what}: {len(acks)} ACKs, wanted exactly 1 (UNAUTHORIZED)")
    expect(acks[0].result == AckResult.UNAUTHORIZED,
           f"{what}: {result_name(acks[0].result)}, wanted UNAUTHORIZED")
    executed = probe.messages(m.ParamValue, ex.sent_at)
    expect(not executed, f"{what} was executed (PARAM_VALUE sent)")
    after = probe.counters()
    grew = (after.signing_rejects - before.signing_rejects) & 0xFFFFFFFF
    expect(grew == 1, f"{what}: signing_rejects +{grew}, wanted +1")
    return f"{what}: one ACK UNAUTHORIZED, signing_rejects +1 ({acks[0].reason or 'no reason'})"


@check("signing.unsigned_refused", SECTION, """SIGNED clear → refuse (unsigned). A refused command is not executed;
       the agent answers it with ACK result 6 UNAUTHORIZED and adds 1 to HEARTBEAT's signing_rejects.""", key=True)
def unsigned_refused(probe: Probe) -> str:
    return refused_once(probe, lambda: probe.command(_get(), signer=False), "an unsigned PARAM_GET")


@check("signing.bad_signature", SECTION, """Compute HMAC-SHA256(key, ...) and compare its first 6 bytes with the
       signature; different → refuse (bad signature).""", key=True)
def bad_signature(probe: Probe) -> str:
    def send() -> Exchange:
        inner = bytearray(probe.inner(m.ParamGet.MSG_ID, _get().pack(), int(FrameFlag.ACK_REQUESTED)))
        inner[-3] ^= 0x01  # last signature byte
        inner[-2:] = crc16_ccitt_false(bytes(inner[:-2])).to_bytes(2, "big")
        return probe.command_inner(bytes(inner))
    return refused_once(probe, send, "a PARAM_GET with one signature bit flipped")


@check("signing.wrong_key", SECTION, "different → refuse (bad signature).", key=True)
def wrong_key(probe: Probe) -> str:
    other = Signer(os.urandom(32), probe.signer.link_id if probe.signer else 0)
    return refused_once(probe, lambda: probe.command(_get(), signer=other), "a PARAM_GET signed with another key")


@check("signing.truncated", SECTION, """SIGNED set but the frame too short for a trailer → UNAUTHORIZED
       ("truncated signature"), whether or not the agent holds a key. Refusals of steps 1, 2 and 4 add 1 to
       signing_rejects.""")
def truncated(probe: Probe) -> str:
    def send() -> Exchange:
        flags = int(FrameFlag.ACK_REQUESTED | FrameFlag.SIGNED)
        seq = probe.next_seq()
        body = bytes([1, flags]) + seq.to_bytes(2, "little") + bytes([m.ParamGet.MSG_ID]) + b"\x00\x00\x00"
        return probe.command_inner(body + crc16_ccitt_false(body).to_bytes(2, "big"))
    return refused_once(probe, send, "a 10-byte PARAM_GET with the SIGNED bit")


@check("signing.replayed_timestamp", SECTION, """Keep, per link_id, the last accepted timestamp. A timestamp not
       greater than it, or not greater than the mark stored before this boot → refuse (replayed).""", key=True)
def replayed_timestamp(probe: Probe) -> str:
    probe.accepted(_get())  # the probe's link id has a fresh accepted timestamp
    assert probe.signer is not None
    old = _signer_at(probe, -5.0, probe.signer.link_id)
    return refused_once(probe, lambda: probe.command(_get(), signer=old),
                        "a new PARAM_GET stamped 5 s before the last accepted one")


@check("signing.too_old", SECTION, """a link_id not in the table whose timestamp is more than 60 s behind the
       estimate → refuse (too old).""", key=True)
def too_old(probe: Probe) -> str:
    probe.accepted(_get())
    return refused_once(probe, lambda: probe.command(_get(), signer=_signer_at(probe, -180.0)),
                        "a PARAM_GET from a new link id stamped 180 s ago")


@check("signing.too_new", SECTION, """Once the agent has an estimate of the current timestamp: [...] any timestamp
       more than 60 s ahead of it → refuse (too new).""", key=True)
def too_new(probe: Probe) -> str:
    probe.accepted(_get())
    return refused_once(probe, lambda: probe.command(_get(), signer=_signer_at(probe, 180.0)),
                        "a PARAM_GET from a new link id stamped 180 s ahead")


@check("signing.exact_replay", SECTION, """An exact replay of an already accepted signed command (valid HMAC, same
       msg_id and seq) gets ACCEPTED again and is not executed again; it is never answered UNAUTHORIZED.""",
       key=True)
def exact_replay(probe: Probe) -> str:
    first = probe.accepted(_get())
    before = probe.counters()
    again = probe.command_inner(first.inner)
    probe.barrier()
    acks = probe.acks_for(again)
    expect(len(acks) == 1, f"the replay got {len(acks)} ACKs, wanted 1")
    expect(acks[0].result == AckResult.ACCEPTED, f"the replay got {result_name(acks[0].result)}, wanted ACCEPTED")
    expect(not probe.messages(m.ParamValue, again.sent_at), "the replay was executed again (PARAM_VALUE)")
    after = probe.counters()
    grew = (after.signing_rejects - before.signing_rejects) & 0xFFFFFFFF
    expect(grew == 0, f"signing_rejects +{grew} for the replay, wanted +0")
    return "same bytes again: ACCEPTED from memory, not executed, not counted"


@check("signing.retry_new_trailer", SECTION, """A retry keeps its seq and payload but gets a new trailer (a new
       timestamp and signature). The agent recognises the retry by (msg_id, seq) and only re-sends the ACK.""",
       key=True)
def retry_new_trailer(probe: Probe) -> str:
    first = probe.accepted(_get())
    retry = probe.command_inner(probe.retry_inner(first.inner))
    after = probe.barrier()
    expect(retry.result == AckResult.ACCEPTED, f"the re-signed retry got {result_name(retry.result)}")
    # Counted from the first try: on a paced link the first try's own PARAM_VALUE may still be on its way when
    # the retry leaves (it queues behind SAMPLEs); the barrier's answer comes after both tries' replies.
    replies = len(probe.messages(m.ParamValue, first.sent_at, after))
    expect(replies == 1, f"the PARAM_GET and its re-signed retry got {replies} PARAM_VALUEs, wanted 1"
           + (": the retry was executed again" if replies > 1 else ""))
    return "ACCEPTED, not executed again"


@check("signing.refusal_not_remembered", SECTION, """Refusals of steps 1, 2 and 4 add 1 to signing_rejects and are
       not remembered.""", key=True)
def refusal_not_remembered(probe: Probe) -> str:
    unsigned = probe.command(_get(), signer=False)
    expect(unsigned.result == AckResult.UNAUTHORIZED, f"unsigned PARAM_GET: {result_name(unsigned.result)}")
    signed = probe.command_inner(probe.retry_inner(unsigned.inner))
    expect(signed.result == AckResult.ACCEPTED,
           f"the same seq, now signed: {result_name(signed.result)}, wanted ACCEPTED")
    found = probe.wait_message(m.ParamValue, signed.ack_at, probe.timeouts.reply_s)
    expect(found is not None, "the same seq, now signed, was not executed (no PARAM_VALUE)")
    return "a signature refusal is not remembered: the signed retry ran"


@check("signing.keyless_strips_trailer", SECTION, """The last 13 bytes before the CRC are the trailer and are removed
       before the payload is decoded. This holds for every message [...] and whether or not the receiver checks
       signatures.""")
def keyless_strips_trailer(probe: Probe) -> str:
    if probe.key is not None:
        signer: Signer | bool = True
    else:
        signer = Signer(os.urandom(32), os.urandom(1)[0])
    ex = probe.command(m.ParamGet(index=1, name=""), signer=signer)
    expect(ex.result == AckResult.ACCEPTED, f"a signed PARAM_GET index 1: {result_name(ex.result)}")
    found = probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s)
    expect(found is not None and found[1].index == 1,
           "no PARAM_VALUE for index 1 (was the trailer read as part of the payload?)")
    return "signed command decoded without its trailer" + ("" if probe.key else " (agent without a key)")


@check("signing.surface_always", SECTION, """Exception: CMD_SURFACE with a valid HMAC (it passed steps 1-2) is
       executed whatever its timestamp (replayed, too old or too new), ACCEPTED and not counted.""", key=True,
       motion=True)
def surface_always(probe: Probe) -> str:
    probe.accepted(_get())
    ex = probe.command(m.Surface(), signer=_signer_at(probe, -180.0))
    expect(ex.result == AckResult.ACCEPTED, f"CMD_SURFACE stamped 180 s ago: {result_name(ex.result)}, wanted "
           "ACCEPTED")
    return "CMD_SURFACE stamped 180 s ago was ACCEPTED"


@check("signing.surface_unsigned", SECTION, """Emergencies (1.2): an agent with a key executes a CMD_SURFACE that is
       unsigned or whose signature does not verify: surfacing is the fail-safe state (anyone may make the agent
       surface, nobody may make it dive). It is ACCEPTED with a reason that says so, not counted in
       signing_rejects, and no sign of life.""", key=True, motion=True)
def surface_unsigned(probe: Probe) -> str:
    from groundstation.check.agent import go_idle

    probe.accepted(_get())
    before = probe.counters()
    ex = probe.command(m.Surface(), signer=False)
    expect(ex.result == AckResult.ACCEPTED, f"an unsigned CMD_SURFACE: {result_name(ex.result)}, wanted ACCEPTED")
    assert ex.ack is not None
    expect(bool(ex.ack.reason), "the ACK of an unsigned CMD_SURFACE does not say it ran unverified (empty reason)")
    other = Signer(os.urandom(32), probe.signer.link_id if probe.signer else 0)
    wrong = probe.command(m.Surface(), signer=other)
    expect(wrong.result == AckResult.ACCEPTED,
           f"a CMD_SURFACE signed with another key: {result_name(wrong.result)}, wanted ACCEPTED")
    after = probe.counters()
    grew = (after.signing_rejects - before.signing_rejects) & 0xFFFFFFFF
    expect(grew == 0, f"signing_rejects +{grew} for CMD_SURFACEs that ran, wanted +0")
    go_idle(probe)
    return f"unsigned and wrongly signed CMD_SURFACE ACCEPTED ({ex.ack.reason})"
