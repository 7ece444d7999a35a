"""The virtual agent over real transports (TCP loopback, a pty opened by pyserial), as a ground station sees it."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from protocol import AckResult, DumpKind, FrameFlag, Mode, definitions_hash, messages
from protocol.parameters import PARAMS as PARAM_DEFS
from tests.simulator.agent_client import ROOT, AgentClient, connected

FAST = ("--speed", "max", "--seed", "5")


@pytest.mark.parametrize("transport", ["tcp", "pty"])
def test_handshake_timesync_and_clean_shutdown(transport: str) -> None:
    args = ("--tcp", "127.0.0.1:0", *FAST) if transport == "tcp" else ("--pty", *FAST)
    with connected(*args) as (server, client):
        assert server.address.startswith("tcp://127.0.0.1:" if transport == "tcp" else "/dev/")
        client.hello()
        hello = client.wait_message(messages.Hello)
        assert (hello.protocol_version, hello.node_kind, hello.definitions_hash) == (1, 1, definitions_hash())
        client.send(messages.Timesync(origin_us=123))
        reply = client.wait_message(messages.Timesync, origin_us=123)
        assert reply.receive_us > 0 and reply.transmit_us >= reply.receive_us
        beat = client.wait_message(messages.Heartbeat)
        assert beat.mode == Mode.IDLE and 3300 < beat.battery_mv <= 4200
    assert server.proc.returncode == 0


def _param(client: AgentClient, name: str) -> messages.ParamValue:
    assert client.command(messages.ParamGet(index=-1, name=name)).result == AckResult.ACCEPTED
    return client.wait_message(messages.ParamValue, name=name)


def test_every_command_is_answered_with_ack_or_the_right_nack() -> None:
    with connected("--tcp", "127.0.0.1:0", "--speed", "50", "--seed", "1") as (_, c):
        # Parameters: the whole table, by name, set with echo, bad values refused.
        assert c.command(messages.ParamListRequest()).result == AckResult.ACCEPTED
        listed = [c.wait_message(messages.ParamValue, index=i) for i in range(len(PARAM_DEFS))]
        assert [p.name for p in listed] == [d.name for d in PARAM_DEFS]
        assert all(len(p.name.encode()) <= 24 and p.minimum <= p.value <= p.maximum for p in listed)
        assert _param(c, "gamma").value == pytest.approx(0.99)
        assert c.command(messages.ParamSet(index=-1, name="max_episodes", value=7.9)).result == AckResult.BAD_VALUE
        assert c.command(messages.ParamSet(index=-1, name="max_episodes", value=7)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.ParamValue, name="max_episodes").value == 7
        assert c.command(messages.ParamSet(index=-1, name="gamma", value=1.5)).result == AckResult.BAD_VALUE
        assert c.command(messages.ParamSet(index=-1, name="nonsense", value=1)).result == AckResult.BAD_VALUE
        assert c.command(messages.ParamGet(index=999)).result == AckResult.BAD_VALUE
        assert c.command(messages.SetTarget(target_depth_m=9.0)).result == AckResult.BAD_VALUE
        assert c.command(messages.SetTarget(target_depth_m=0.5)).result == AckResult.ACCEPTED
        assert _param(c, "target_depth_m").value == pytest.approx(0.5)
        # Modes: what IDLE refuses, hover, start, and what learning refuses.
        assert c.command(messages.Pause()).result == AckResult.NOT_ALLOWED_IN_MODE
        assert c.command(messages.Stop()).result == AckResult.ACCEPTED  # SPEC 1.1: stays IDLE
        assert c.command(messages.ResetModel()).result == AckResult.ACCEPTED
        assert c.command(messages.Hover(depth_m=7.0)).result == AckResult.BAD_VALUE
        assert c.command(messages.Hover(depth_m=0.3)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.Sample, mode=int(Mode.HOVER)).mode == Mode.HOVER
        start_seq = c.send(messages.StartLearning(max_episodes=0))
        assert c.wait_message(messages.Ack, cmd_seq=start_seq).result == AckResult.ACCEPTED
        # A retry (same frame, same seq) is answered again but not executed again (that would be NOT_ALLOWED).
        c.send_raw(c.encoder.encode_payload(0x80, messages.StartLearning().pack(), FrameFlag.ACK_REQUESTED).wire)
        assert c.command(messages.StartLearning()).result == AckResult.NOT_ALLOWED_IN_MODE
        c.encoder._seq = start_seq  # re-send the very same command frame
        c.send(messages.StartLearning(max_episodes=0))
        assert c.wait_message(messages.Ack, cmd_seq=start_seq).result == AckResult.ACCEPTED
        assert c.command(messages.ParamSet(index=-1, name="gamma", value=0.9)).result == AckResult.NOT_ALLOWED_IN_MODE
        assert c.command(messages.Pause()).result == AckResult.ACCEPTED
        assert c.wait_message(messages.Sample, mode=int(Mode.PAUSED)).mode == Mode.PAUSED
        assert c.command(messages.Stop()).result == AckResult.ACCEPTED
        assert c.command(messages.Surface()).result == AckResult.ACCEPTED
        # Dumps: a new snapshot in <= 224-byte chunks, a range of it again by id, STALE for one not held.
        assert c.command(messages.DumpRequest(kind=DumpKind.Q_VALUES)).result == AckResult.ACCEPTED
        first = c.wait_message(messages.DumpChunk)
        chunks = [first] + [c.wait_message(messages.DumpChunk, dump_id=first.dump_id) for _ in range(3)]
        assert first.total_bytes == 808 and [ch.offset for ch in chunks] == [0, 224, 448, 672]
        assert all(len(ch.data) <= 224 for ch in chunks) and sum(len(ch.data) for ch in chunks) == 808
        again = messages.DumpRequest(kind=DumpKind.Q_VALUES, dump_id=first.dump_id, offset=224, length=10)
        assert c.command(again).result == AckResult.ACCEPTED
        piece = c.wait_message(messages.DumpChunk, dump_id=first.dump_id, offset=224)
        assert piece.data == chunks[1].data[:10]
        stale = messages.DumpRequest(kind=DumpKind.Q_VALUES, dump_id=4242)
        assert c.command(stale).result == AckResult.STALE
        assert c.command(messages.DumpRequest(kind=9)).result == AckResult.BAD_VALUE
        assert c.command(messages.LogRequest(first_sample=0, end_sample=0)).result == AckResult.ACCEPTED
        assert c.wait_message(messages.LogRange).replayed == 0


def test_a_full_learning_episode_is_observed_from_outside_at_max_speed() -> None:
    with connected("--tcp", "127.0.0.1:0", *FAST) as (_, c):
        assert c.command(messages.StartLearning(max_episodes=2)).result == AckResult.ACCEPTED
        start = c.wait_message(messages.EpisodeStart, timeout_s=30)
        end = c.wait_message(messages.EpisodeEnd, timeout_s=30, episode=start.episode)
        samples = [s for s in c.of(messages.Sample) if start.sample <= s.sample <= end.sample]
        assert [s.sample for s in samples] == list(range(start.sample, end.sample + 1))  # none lost on loopback
        assert all(s.episode == start.episode and s.mode == Mode.LEARNING for s in samples)
        assert [s.step for s in samples[: end.steps + 1]] == list(range(end.steps + 1))
        assert end.reason in (1, 2) and end.episode_return == pytest.approx(sum(s.reward for s in samples), abs=1e-3)
        assert abs(samples[0].depth_m - start.target_depth_m) < start.z_tol_m
        times = [s.t_us for s in samples]
        assert all(b - a == 100_000 for a, b in zip(times, times[1:], strict=False))  # 0.1 s in agent time
        c.wait_message(messages.EpisodeEnd, timeout_s=30, episode=start.episode + 1)
        c.wait_message(messages.Sample, timeout_s=30, mode=int(Mode.IDLE))  # episode limit: surfaced, idle


def test_the_on_board_log_refills_a_gap_after_a_disconnect() -> None:
    # The hardware preset recovers at 40 Hz between episodes, so the gap fills with many samples.
    with connected("--tcp", "127.0.0.1:0", "--speed", "300", "--seed", "2", "--preset", "hardware") as (server, c):
        assert c.command(messages.StartLearning()).result == AckResult.ACCEPTED
        last = c.wait_message(messages.Sample, mode=int(Mode.RECOVERING)).sample
        c.close()
        time.sleep(0.3)  # about 90 s of agent time without a client
        c2 = AgentClient.tcp(server.address)
        try:
            c2.wait_message(messages.Hello)
            beat = c2.wait_message(messages.Heartbeat)
            assert beat.log_first_sample <= last + 1 and beat.log_next_sample > last + 1000
            # SPEC s. 7: one request replays at most 512 samples; the ground asks again from the next one.
            wanted, start, ranges = beat.log_next_sample, last + 1, []
            while start < wanted:
                assert c2.command(messages.LogRequest(first_sample=start, end_sample=wanted)).result == 0
                ranges.append(c2.wait_message(messages.LogRange, timeout_s=20))
                got = [f.message.sample for f in c2.frames
                       if f.flags & FrameFlag.REPLAYED and isinstance(f.message, messages.Sample)]
                start = max(got) + 1
            replayed = [f for f in c2.frames if f.flags & FrameFlag.REPLAYED]
            samples = [f.message.sample for f in replayed if isinstance(f.message, messages.Sample)]
            assert samples == list(range(last + 1, wanted))
            assert len(ranges) == -(-(wanted - last - 1) // 512)
            assert sum(r.replayed for r in ranges) == len(replayed) and ranges[0].capacity_bytes == 512 * 1024
            assert not [f for f in c2.frames if isinstance(f.message, messages.Heartbeat) and f.flags]
        finally:
            c2.close()


def test_bad_arguments_give_one_line_and_a_non_zero_exit() -> None:
    for args in (["--tcp", "nonsense"], ["--speed", "-3"], ["--drop", "2"], ["--preset", "moon"]):
        done = subprocess.run(
            [sys.executable, "-m", "simulator", "serve", *args], capture_output=True, text=True, cwd=ROOT, timeout=60
        )
        assert done.returncode == 2 and done.stdout == ""
        assert len(done.stderr.strip().splitlines()) == 1 and done.stderr.startswith("python -m simulator: ")
