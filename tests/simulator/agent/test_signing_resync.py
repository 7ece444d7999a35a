"""Issue 25 L5 on the Python agent and the C firmware's host build: a ground whose clock is an hour ahead signs first
and locks out a ground with the right time; that ground's Session re-syncs the agent by itself once (SPEC.md s. 12,
"Re-sync") and gets in, and the re-sync cannot be replayed."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import AckResult, FrameEncoder, Signer, messages
from protocol.signing import RESYNC_NAME, resync_nonce
from tests.firmware.core_build import use_firmware_cache
from tests.simulator.agent_client import AgentClient, running

KEY = bytes(range(32))
HOUR_NS = 3600 * 10**9


class Heard:
    """The session's notices and the re-sync frames it sent."""

    def __init__(self) -> None:
        self.notices: list[str] = []
        self.resyncs: list[bytes] = []

    def on_received(self, received: Received) -> None:
        pass

    def on_sent(self, sent: Sent) -> None:
        if isinstance(sent.message, messages.ParamSet) and sent.message.name == RESYNC_NAME:
            self.resyncs.append(sent.wire)

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.ERROR:
            self.notices.append(event.detail)


@pytest.mark.parametrize("agent", ["python", "c"])
def test_a_ground_locked_out_by_a_clock_an_hour_ahead_re_syncs_once_and_the_re_sync_cannot_be_replayed(
        agent: str, tmp_path: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(KEY.hex() + "\n")
    key_file.chmod(0o600)
    firmware = ("--firmware", "c") if agent == "c" else ()
    if firmware:
        use_firmware_cache(tmp_path_factory)
    args = ("--tcp", "127.0.0.1:0", "--speed", "20", "--seed", "5", "--key-file", str(key_file), "--state-dir",
            str(tmp_path / "state"), *firmware)
    with running(*args) as server:
        ahead = AgentClient.tcp(server.address)
        ahead.wait_program()  # commands meet the program, not the starting agent's BUSY
        ahead.encoder = FrameEncoder(100, signer=Signer(KEY, 5, clock_ns=lambda: time.time_ns() + HOUR_NS))
        assert ahead.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED  # first: sets the estimate
        right = AgentClient.tcp(server.address)  # another ground with the right time (a fresh link id)
        right.encoder = FrameEncoder(200, signer=Signer(KEY, 6))
        refused = right.command(messages.ParamGet(index=0))
        assert refused.result == AckResult.UNAUTHORIZED and "too old" in refused.reason, refused
        assert resync_nonce(refused.reason) is not None
        right.close()

        heard = Heard()
        session = Session(make_link(server.address), SessionConfig(key=KEY, reconnect=False, backfill=False),
                          [heard])
        with session:  # its first command (the parameter list) is refused, it re-syncs, and the list comes
            assert len(session.params) > 10
            assert session.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED
        assert len(heard.notices) == 1 and "re-synced" in heard.notices[0], heard.notices
        [resync_wire] = heard.resyncs

        replay = AgentClient.tcp(server.address)  # the re-sync recorded off the link and sent again
        try:
            replay.send_raw(b"\x00" + resync_wire)
            ack = replay.wait_message(messages.Ack, cmd_msg_id=messages.ParamSet.MSG_ID)
            assert ack.result == AckResult.UNAUTHORIZED and "stale re-sync nonce" in ack.reason, ack
            replay.encoder = FrameEncoder(300, signer=Signer(KEY, 5, clock_ns=lambda: time.time_ns() + HOUR_NS))
            late = replay.command(messages.ParamGet(index=0))  # the clock an hour ahead: now too new
            assert late.result == AckResult.UNAUTHORIZED and "too new" in late.reason, late
        finally:
            replay.close()
    if firmware:
        return  # a reboot costs one more start (~5 s): the Python agent's here, the C agent's in test_core_signing
    with running(*args) as server:  # rebooted: the mark stored by the re-sync, not the hour-ahead one, holds
        right = AgentClient.tcp(server.address)
        right.wait_program()
        try:  # the mark is 10 s past the last accepted frame (s. 12): a ground past it gets in, not one an hour on
            right.encoder = FrameEncoder(400, signer=Signer(KEY, 8, clock_ns=lambda: time.time_ns() + 15 * 10**9))
            after = right.command(messages.ParamGet(index=0))
            assert after.result == AckResult.ACCEPTED, after
        finally:
            right.close()
