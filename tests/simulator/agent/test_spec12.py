"""SPEC.md 1.2 on the virtual agent, over TCP: an unsigned CMD_SURFACE runs on a keyed agent and says so; a ground
HELLO or a new connection empties the ACK memory."""

from __future__ import annotations

from pathlib import Path

from protocol import AckResult, FrameEncoder, FrameFlag, Mode, Signer, messages
from simulator.agent.link_signing import UNVERIFIED_SURFACE
from tests.simulator.agent_client import connected

FAST = ("--tcp", "127.0.0.1:0", "--speed", "50", "--seed", "12")
KEY = bytes(range(32))
ACK = FrameFlag.ACK_REQUESTED


def test_a_keyed_agent_surfaces_on_an_unsigned_or_wrongly_signed_cmd_surface(tmp_path: Path) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(KEY.hex() + "\n")
    key_file.chmod(0o600)  # the agent refuses a key file others can read
    with connected(*FAST, "--key-file", str(key_file), "--state-dir", str(tmp_path)) as (_, c):
        c.encoder = FrameEncoder(100, signer=Signer(KEY, 4))
        assert c.command(messages.Hover(depth_m=0.5)).result == AckResult.ACCEPTED
        c.wait_message(messages.Sample, mode=int(Mode.HOVER))
        c.encoder = FrameEncoder(200)  # unsigned: refused for anything but CMD_SURFACE
        assert c.command(messages.Hover(depth_m=0.3)).result == AckResult.UNAUTHORIZED
        plain = c.encoder.encode(messages.Surface(), ACK)
        c.send_raw(plain.wire)
        ack = c.wait_message(messages.Ack, cmd_seq=plain.seq)
        assert ack.result == AckResult.ACCEPTED and ack.reason.startswith(UNVERIFIED_SURFACE), ack
        c.wait_message(messages.Sample, mode=int(Mode.SURFACING))
        c.send_raw(plain.wire)  # a retry: answered from the ACK memory, not run again
        assert c.wait_message(messages.Ack, cmd_seq=plain.seq).result == AckResult.ACCEPTED
        c.encoder = FrameEncoder(300, signer=Signer(bytes(32), 4))  # another key: still surfaces
        assert c.command(messages.Surface()).result == AckResult.ACCEPTED
        beat = c.wait_message(messages.Heartbeat)
        assert beat.signing_rejects == 1  # the unsigned CMD_HOVER only: a surface run unverified is not refused


def test_a_ground_hello_empties_the_ack_memory() -> None:
    """G1: a new session's seq must not meet the last session's remembered ACK (a stale ACK, nothing executed)."""
    with connected(*FAST) as (_, c):
        c.encoder = FrameEncoder(500)
        get = c.encoder.encode(messages.ParamGet(index=3, name=""), ACK)
        c.send_raw(get.wire)
        assert c.wait_message(messages.Ack, cmd_seq=get.seq).result == AckResult.ACCEPTED
        c.wait_message(messages.ParamValue, index=3)
        c.hello()  # a new session starts
        c.send_raw(get.wire)  # the same (msg_id, seq) in the new session: executed, a PARAM_VALUE follows
        assert c.wait_message(messages.Ack, cmd_seq=get.seq).result == AckResult.ACCEPTED
        c.wait_message(messages.ParamValue, index=3)


def test_setting_the_current_value_restarts_nothing_and_a_refused_dump_takes_no_snapshot() -> None:
    """G13: a change is a different stored value; G10: CMD_DUMP refused for its offset uses no id and no place."""
    with connected(*FAST) as (_, c):
        c.encoder = FrameEncoder(600)
        assert c.command(messages.ParamGet(index=-1, name="gamma")).result == AckResult.ACCEPTED
        gamma = c.wait_message(messages.ParamValue, name="gamma").value
        assert c.command(messages.ParamSet(index=-1, value=gamma, name="gamma")).result == AckResult.ACCEPTED
        c.wait_message(messages.ParamValue, name="gamma")
        refused = c.command(messages.DumpRequest(kind=2, dump_id=0, offset=10**6, length=0))
        assert refused.result == AckResult.BAD_VALUE
        assert c.command(messages.DumpRequest(kind=2, dump_id=0, offset=0, length=0)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.DumpChunk).dump_id == 1  # the refused request took no id
        assert not [t for t in c.of(messages.Text) if "restarted" in t.text]
        assert c.command(messages.ParamSet(index=-1, value=0.95, name="gamma")).result == AckResult.ACCEPTED
        c.wait_for(lambda f: isinstance(f.message, messages.Text) and "restarted" in f.message.text)
