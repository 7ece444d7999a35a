"""The virtual agent does what SPEC.md 1.1 says, rule by rule, over a real TCP connection."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from learning import LearnerConfig
from protocol import AckResult, DumpKind, FrameEncoder, FrameFlag, Mode, Signer, StreamDecoder, messages
from protocol.cobs import cobs_decode
from protocol.crc import crc16_ccitt_false
from protocol.errors import CobsError
from protocol.parameters import f32
from protocol.signing import timestamp_from_unix_ns
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.link import AgentLink
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset
from tests.simulator.agent_client import AgentClient, connected
from tests.vectors.generate_receive import RECEIVE_VECTORS_PATH

FAST = ("--tcp", "127.0.0.1:0", "--speed", "50", "--seed", "11")
KEY = bytes(range(32))
T0_NS = 1_735_689_600 * 10**9


def _counters(c: AgentClient) -> messages.Heartbeat:
    """A HEARTBEAT sent after everything before it was handled: a HELLO (which resets the agent's sequence
    tracking before it is counted, so nothing before it counts as lost), a command's ACK, then the next HEARTBEAT."""
    c.hello()
    assert c.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED
    return c.wait_message(messages.Heartbeat)


def _first_tracked_seq(wire: bytes) -> int | None:
    """The seq of the first frame in `wire` that passes the CRC and version checks (sequence tracking starts there)."""
    for chunk in wire.split(b"\x00"):
        try:
            inner = cobs_decode(chunk)
        except CobsError:
            continue
        if 7 <= len(inner) <= 254 and crc16_ccitt_false(inner) == 0 and inner[0] == 1 and not inner[1] & 0xE0:
            return int.from_bytes(inner[2:4], "little")
    return None


def test_each_receive_vector_over_tcp_adds_its_counters_and_acks() -> None:
    vectors: list[dict[str, Any]] = [json.loads(x) for x in RECEIVE_VECTORS_PATH.read_text().splitlines()]
    with connected(*FAST) as (_, c):
        for vector in vectors:
            wire = bytes.fromhex(vector["wire_hex"])
            before = _counters(c)
            start = len(c.frames)
            first = _first_tracked_seq(wire)
            if first is not None:  # a HELLO just before it, so the vector's first frame follows in sequence
                c.send_raw(FrameEncoder((first - 1) & 0xFFFF).encode(messages.Hello()).wire)
            c.send_raw(wire)
            after = _counters(c)
            extra = 2 + (first is not None)  # our HELLOs and the PARAM_GET of _counters
            assert after.rx_frames - before.rx_frames == vector["rx_frames"] + extra, vector["name"]
            assert after.rx_rejects - before.rx_rejects == vector["rx_rejects"], vector["name"]
            assert after.rx_lost - before.rx_lost == vector["rx_lost"], vector["name"]
            acks = [f.message for f in c.frames[start:] if isinstance(f.message, messages.Ack)
                    and f.message.cmd_msg_id != messages.ParamGet.MSG_ID]
            assert [AckResult(a.result).name for a in acks] == vector["ack"], vector["name"]
            unauthorized = vector["ack"].count("UNAUTHORIZED")
            assert after.signing_rejects - before.signing_rejects == unauthorized, vector["name"]


@pytest.mark.slow  # two wall seconds or two agent starts
@pytest.mark.parametrize("link", [FAST, ("--pty", *FAST[2:])], ids=["tcp", "pty"])
def test_hello_is_repeated_until_the_ground_is_heard_and_every_ground_hello_is_answered(link: tuple[str, ...]) -> None:
    with connected(*link) as (_, c):
        deadline = time.monotonic() + 2.6
        while time.monotonic() < deadline:
            c.pump()
        assert len(c.of(messages.Hello)) >= 3  # on connect, then once per wall second (50x real time)
        c.send(messages.Heartbeat())
        time.sleep(0.3)
        c.pump()
        heard = len(c.of(messages.Hello))
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            c.pump()
        assert len(c.of(messages.Hello)) == heard  # the ground was heard: no more repeats
        c.hello()
        c.hello()
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline and len(c.of(messages.Hello)) < heard + 2:
            c.pump()
        assert len(c.of(messages.Hello)) == heard + 2


def test_parameters_modes_dumps_and_the_ram_budget() -> None:
    with connected(*FAST) as (_, c):
        target = c.command(messages.ParamGet(index=-1, name="target_depth_m"))
        assert target.result == AckResult.ACCEPTED
        value = c.wait_message(messages.ParamValue, name="target_depth_m")
        assert value.value == f32(0.4) == 0.4000000059604645 and value.minimum == f32(0.05)
        at_rest = c.command(messages.ParamGet(index=-1, name="start_at_rest"))
        assert at_rest.result == AckResult.ACCEPTED
        assert c.wait_message(messages.ParamValue, name="start_at_rest").value == 1.0  # the paper preset
        assert c.command(messages.ParamGet(index=-2)).result == AckResult.BAD_VALUE
        assert c.command(messages.ParamSet(index=-1, name="gamma", value=0.9565)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.ParamValue, name="gamma").value == f32(0.9565)
        assert c.command(messages.ParamSet(index=-1, name="dump_each_episode", value=0.5)).result == (
            AckResult.BAD_VALUE)
        # S = z_cells x zdot_cells x act_bins + 1 against the 44 KiB budget: 301 fits, 401 and 501 do not
        nack = c.command(messages.ParamSet(index=-1, name="z_cells", value=50))
        assert nack.result == AckResult.BAD_VALUE and "bytes" in nack.reason
        assert c.command(messages.ParamSet(index=-1, name="act_bins", value=3)).result == AckResult.ACCEPTED
        assert c.command(messages.ParamSet(index=-1, name="act_bins", value=4)).result == AckResult.BAD_VALUE
        assert not [p for p in c.of(messages.ParamValue) if p.name in ("z_cells",)]  # none after a NACK
        # Snapshots: the newest 4 are held; COUNTS goes STALE when the model changes.
        ids = []
        for _ in range(5):
            assert c.command(messages.DumpRequest(kind=DumpKind.VALUES)).result == AckResult.ACCEPTED
            ids.append(c.wait_message(messages.DumpChunk).dump_id)
        assert c.command(messages.DumpRequest(kind=DumpKind.VALUES, dump_id=ids[0])).result == AckResult.STALE
        assert c.command(messages.DumpRequest(kind=DumpKind.VALUES, dump_id=ids[1])).result == AckResult.ACCEPTED
        assert c.command(messages.DumpRequest(kind=DumpKind.POLICY, dump_id=ids[1])).result == AckResult.STALE
        total = next(ch.total_bytes for ch in c.of(messages.DumpChunk) if ch.dump_id == ids[1])
        assert total == 4 * 301  # VALUES of S = 10 x 10 x 3 + 1 states
        at_end = messages.DumpRequest(kind=DumpKind.VALUES, dump_id=ids[1], offset=total)
        chunks = len(c.of(messages.DumpChunk))
        assert c.command(at_end).result == AckResult.ACCEPTED
        assert c.command(messages.ParamGet(index=0)).result == AckResult.ACCEPTED
        assert len(c.of(messages.DumpChunk)) == chunks  # offset = size: no chunk
        assert c.command(messages.DumpRequest(kind=DumpKind.COUNTS)).result == AckResult.ACCEPTED
        counts_id = next(ch.dump_id for ch in c.of(messages.DumpChunk) if ch.kind == DumpKind.COUNTS)
        again = messages.DumpRequest(kind=DumpKind.COUNTS, dump_id=counts_id, length=16)
        assert c.command(again).result == AckResult.ACCEPTED
        assert c.command(messages.StartLearning(max_episodes=1)).result == AckResult.ACCEPTED
        c.wait_message(messages.Sample, timeout_s=20, mode=int(Mode.LEARNING), step=3)
        # Learning: value checks before mode checks; CMD_HOVER and CMD_SET_TARGET refused in LEARNING.
        assert c.command(messages.ParamSet(index=-1, name="gamma", value=1.5)).result == AckResult.BAD_VALUE
        assert c.command(messages.ParamSet(index=-1, name="gamma", value=0.9)).result == (
            AckResult.NOT_ALLOWED_IN_MODE)
        assert c.command(messages.Hover(depth_m=7.0)).result == AckResult.BAD_VALUE
        assert c.command(messages.Hover(depth_m=0.5)).result == AckResult.NOT_ALLOWED_IN_MODE
        assert c.command(messages.SetTarget(target_depth_m=0.5)).result == AckResult.NOT_ALLOWED_IN_MODE
        assert c.command(again).result == AckResult.STALE  # transitions observed since the COUNTS snapshot
        assert c.command(messages.Stop()).result == AckResult.ACCEPTED
        assert c.command(messages.Stop()).result == AckResult.ACCEPTED  # in SURFACING: stays
        assert c.command(messages.LogRequest(first_sample=9, end_sample=3)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.LogRange).replayed == 0


@pytest.mark.slow  # two wall seconds or two agent starts
def test_link_silence_is_measured_in_wall_seconds_faster_than_real_time() -> None:
    with connected(*FAST) as (_, c):
        for name, value in (("link_timeout_s", 1.0), ("surface_on_link_loss", 1)):
            assert c.command(messages.ParamSet(index=-1, name=name, value=value)).result == AckResult.ACCEPTED
        assert c.command(messages.Hover(depth_m=0.3)).result == AckResult.ACCEPTED
        # The ground's heartbeat every 0.4 wall seconds (20 agent seconds) keeps the link: no surfacing.
        silent_from = time.monotonic()
        for _ in range(5):
            c.send(messages.Heartbeat())
            silent_from = time.monotonic()
            time.sleep(0.4)
            c.pump()
        assert not [s for s in c.of(messages.Sample) if s.mode == Mode.SURFACING]
        c.wait_message(messages.Sample, timeout_s=5, mode=int(Mode.SURFACING))
        assert time.monotonic() - silent_from > 0.9  # one wall second of silence, not one agent second


@pytest.mark.slow  # two wall seconds or two agent starts
def test_signed_replays_truncation_surface_and_the_mark_across_a_restart(tmp_path: Path) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(KEY.hex() + "\n")
    key_file.chmod(0o600)  # the agent refuses a key file others can read
    args = (*FAST, "--key-file", str(key_file), "--state-dir", str(tmp_path / "state"))
    clock_ns = [T0_NS + 10**15]  # well after 2025, so it is never below a mark of an earlier run
    signer = Signer(KEY, 5, clock_ns=lambda: clock_ns[0])
    with connected(*args) as (_, c):
        c.encoder = FrameEncoder(100, signer=signer)
        start = c.encoder.encode(messages.StartLearning(max_episodes=1), FrameFlag.ACK_REQUESTED)
        c.send_raw(start.wire)
        assert c.wait_message(messages.Ack, cmd_seq=start.seq).result == AckResult.ACCEPTED
        c.send_raw(start.wire)  # the exact bytes again: the first ACK again, not executed, never UNAUTHORIZED
        assert c.wait_message(messages.Ack, cmd_seq=start.seq).result == AckResult.ACCEPTED
        flags = FrameFlag.ACK_REQUESTED | FrameFlag.SIGNED
        truncated = FrameEncoder(7).encode_payload(messages.Stop.MSG_ID, b"", flags)
        c.send_raw(truncated.wire)
        assert c.wait_message(messages.Ack, cmd_seq=7).result == AckResult.UNAUTHORIZED
        clock_ns[0] += 120 * 10**9  # two minutes ahead of the agent's estimate: too new ...
        assert c.command(messages.Stop()).result == AckResult.UNAUTHORIZED
        surface = c.send(messages.Surface())  # ... but CMD_SURFACE runs whatever its timestamp
        assert c.wait_message(messages.Ack, cmd_seq=surface).result == AckResult.ACCEPTED
        c.wait_message(messages.Sample, timeout_s=10, mode=int(Mode.SURFACING))
        beat = c.wait_message(messages.Heartbeat)
        assert beat.signing_rejects == 2
    mark = int((tmp_path / "state" / "agent.key.mark").read_text())
    assert mark == timestamp_from_unix_ns(T0_NS + 10**15) + 10 * 100_000  # the accepted CMD_START + 10 s
    with connected(*args) as (_, c):  # restarted: the RAM state is gone, the mark is not
        c.send_raw(start.wire)
        assert c.wait_message(messages.Ack, cmd_seq=start.seq).result == AckResult.UNAUTHORIZED


def test_timesync_reply_at_agent_time_zero_is_not_mistaken_for_a_request() -> None:
    sent: list[bytes] = []
    params = preset("paper")
    rng = np.random.default_rng(1)
    link = AgentLink(sent.append, node_id=1)
    program = OnboardProgram(params, LearnerConfig(), MissionConfig(), SimulatedHardware(params, rng), rng, link)
    link.attach(program)
    assert program.t_us == 0
    link.receive(FrameEncoder().encode(messages.Timesync(origin_us=123)).wire)
    replies = [f.message for f in StreamDecoder().feed(b"".join(sent))]
    assert replies == [messages.Timesync(origin_us=123, receive_us=0, transmit_us=1)]
