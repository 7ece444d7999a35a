"""Commands, ACK and ACK memory: exactly one ACK per command frame, retries answered from memory (SPEC.md 5)."""

from __future__ import annotations

from groundstation.check.probe import Exchange, Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult
from protocol import messages as m

SECTION = "5 Commands, ACK and retries"
ACK_MEMORY = 16


def _get(probe: Probe, index: int = 0, flags: int | None = None) -> Exchange:
    return probe.command(m.ParamGet(index=index, name=""), flags)


def _one_ack(probe: Probe, ex: Exchange, wanted: AckResult, what: str) -> m.Ack:
    probe.barrier()
    acks = probe.acks_for(ex)
    expect(len(acks) == 1, f"{what}: {len(acks)} ACKs for one frame, wanted exactly 1")
    ack = acks[0]
    expect(ack.result == wanted, f"{what}: {result_name(ack.result)} ({ack.reason}), wanted {wanted.name}")
    return ack


def _param_values_after(probe: Probe, ex: Exchange) -> int:
    return len(probe.messages(m.ParamValue, ex.sent_at))


@check("ack.echo", SECTION, """Every command frame that passes the CRC and version checks gets exactly one ACK per
       received frame. cmd_msg_id and cmd_seq echo the command's msg_id and frame seq. The ACK is sent before
       anything the command causes (replies, TEXT, EPISODE frames).""")
def echo(probe: Probe) -> str:
    ex = _get(probe)
    expect(ex.ack is not None, f"PARAM_GET: no ACK within {probe.timeouts.reply_s:g} s")
    _one_ack(probe, ex, AckResult.ACCEPTED, "PARAM_GET index 0")
    first_value = next((i for i in range(ex.sent_at, probe.end)
                        if isinstance(probe.frame(i).message, m.ParamValue)), None)
    expect(first_value is not None and first_value > ex.ack_at, "the PARAM_VALUE came before the ACK")
    return f"ACK echoes 0x{ex.msg_id:02X} seq {ex.seq}, before its PARAM_VALUE"


@check("ack.without_ack_requested", SECTION, """Every command frame [...] gets exactly one ACK per received frame,
       whether ACK_REQUESTED is set or not.""")
def without_ack_requested(probe: Probe) -> str:
    ex = _get(probe, flags=0)
    expect(ex.ack is not None, "a PARAM_GET without ACK_REQUESTED got no ACK")
    _one_ack(probe, ex, AckResult.ACCEPTED, "PARAM_GET without ACK_REQUESTED")
    return "ACKed"


@check("ack.unknown_command", SECTION, """[exactly one ACK] whether or not the agent knows its id. Unknown command
       id → UNSUPPORTED. rx_frames [counts] unknown command ids (UNSUPPORTED).""")
def unknown_command(probe: Probe) -> str:
    before = probe.counters()
    sent = probe.sent_valid
    exchanges = []
    for msg_id in (0x8C, 0xC0, 0xFF):
        start = probe.end
        inner = probe.inner(msg_id, b"\x01\x02", 0x01)
        exchanges.append(probe.command_inner(inner))
        exchanges[-1].sent_at = start
    for ex in exchanges:
        expect(ex.ack is not None, f"unknown command 0x{ex.msg_id:02X}: no ACK")
        _one_ack(probe, ex, AckResult.UNSUPPORTED, f"unknown command 0x{ex.msg_id:02X}")
    after = probe.counters()
    frames = (after.rx_frames - before.rx_frames) & 0xFFFFFFFF
    rejects = (after.rx_rejects - before.rx_rejects) & 0xFFFFFFFF
    wanted = probe.sent_valid - sent
    expect(frames == wanted and rejects == 0,
           f"rx_frames +{frames} (wanted +{wanted}), rx_rejects +{rejects} (wanted +0)")
    return "0x8C, 0xC0, 0xFF: one ACK UNSUPPORTED each, counted in rx_frames"


@check("ack.retry_not_executed", SECTION, """ACK memory: a frame whose (msg_id, seq) matches a remembered one is
       not executed; the remembered result is sent again.""")
def retry_not_executed(probe: Probe) -> str:
    ex = _get(probe)
    expect(ex.ack is not None, "PARAM_GET: no ACK")
    probe.barrier()
    values = _param_values_after(probe, ex)
    expect(values == 1, f"PARAM_GET answered with {values} PARAM_VALUEs")
    _retry_not_run(probe, ex, "the retry")
    return "the retry got the same ACK and no second PARAM_VALUE"


def _retry_not_run(probe: Probe, first: Exchange, what: str) -> None:
    """A retry of an accepted PARAM_GET: one ACK ACCEPTED and no PARAM_VALUE (it is not executed again)."""
    retry = probe.command_inner(probe.retry_inner(first.inner))
    expect(retry.ack is not None, f"{what} got no ACK")
    _one_ack(probe, retry, AckResult.ACCEPTED, what)
    again = _param_values_after(probe, retry)
    expect(again == 0, f"{what} was executed again ({again} PARAM_VALUE)")


@check("ack.retry_nack", SECTION, """The agent remembers the last 16 (msg_id, seq, result) it answered at steps 5-7
       (executed, or refused on the command's merits).""")
def retry_nack(probe: Probe) -> str:
    ex = _get(probe, index=30000)
    expect(ex.result == AckResult.BAD_VALUE, f"PARAM_GET index 30000: {result_name(ex.result)}, wanted BAD_VALUE")
    retry = probe.command_inner(probe.retry_inner(ex.inner))
    _one_ack(probe, retry, AckResult.BAD_VALUE, "the retry of a refused PARAM_GET")
    return "BAD_VALUE again"


@check("ack.memory_16", SECTION, """The agent remembers the last 16 (msg_id, seq, result) it answered. A ground
       must not reuse a seq for a different command within 16 commands.""")
def memory_16(probe: Probe) -> str:
    first = _get(probe)
    expect(first.ack is not None, "PARAM_GET: no ACK")
    for _ in range(ACK_MEMORY - 1):
        other = probe.command(m.LogRequest(first_sample=1, end_sample=0))
        expect(other.ack is not None, "LOG_REQUEST: no ACK")
    _retry_not_run(probe, first, "the retry after 15 other commands")
    return "a retry 15 commands later: same ACK, not executed"


@check("ack.memory_per_session", SECTION, """(1.2) The memory is emptied at the start of every session (a new
       connection, or a HELLO from the ground), so a new session's seq never gets an old session's ACK with nothing
       executed.""")
def memory_per_session(probe: Probe) -> str:
    from protocol import NodeKind, definitions_hash

    first = probe.accepted(m.ParamGet(index=1, name=""), "PARAM_GET index 1")
    expect(probe.wait_message(m.ParamValue, first.ack_at, probe.timeouts.reply_s) is not None,
           "PARAM_GET index 1: no PARAM_VALUE")
    probe.send(m.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND), definitions_hash=definitions_hash(),
                       node_id=0, boot_id=1))  # a new session starts
    again = probe.command_inner(probe.retry_inner(first.inner))  # the same (msg_id, seq), a fresh signature
    expect(again.result == AckResult.ACCEPTED, f"the same seq in a new session: {result_name(again.result)}")
    found = probe.wait_message(m.ParamValue, again.ack_at, probe.timeouts.reply_s)
    expect(found is not None, "the same (msg_id, seq) after a ground HELLO was answered from the ACK memory "
           "(no PARAM_VALUE): a new session's command got an old session's ACK")
    return "after a ground HELLO the same (msg_id, seq) was executed again"
