"""Each fault flag of `serve` has the effect a ground station would measure, and garbage never crashes the agent."""

from __future__ import annotations

import statistics
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import FrameEncoder, Mode, messages
from tests.simulator.agent_client import AgentClient, connected
from tests.simulator.agent_trace import in_process_agent

TCP = ("--tcp", "127.0.0.1:0")


def _collect(client: AgentClient, wall_s: float) -> None:
    deadline = time.monotonic() + wall_s
    while time.monotonic() < deadline:
        client.pump()


def test_drop_loses_about_that_fraction_of_frames() -> None:
    with connected(*TCP, "--speed", "max", "--seed", "4", "--drop", "0.2") as (_, c):
        # --speed max runs at the reader's pace (flow control, issue 14): read long enough for 2000 frames
        _collect(c, 3.0)
        stats = c.decoder.stats
        assert stats.frames > 2000
        assert stats.lost / (stats.lost + stats.frames) == pytest.approx(0.2, abs=0.04)
        assert stats.rejects == 0


def test_corrupt_shows_up_as_rejected_frames() -> None:
    with connected(*TCP, "--speed", "max", "--seed", "4", "--corrupt", "0.1") as (_, c):
        _collect(c, 1.0)
        stats = c.decoder.stats
        assert stats.crc_errors + stats.cobs_errors + stats.runts > 0.05 * stats.frames


def _round_trips_ms(client: AgentClient, n: int) -> list[float]:
    out = []
    for i in range(n):
        t1 = time.monotonic()
        client.send(messages.Timesync(origin_us=1000 + i))
        client.wait_message(messages.Timesync, origin_us=1000 + i)
        out.append((time.monotonic() - t1) * 1000)
    return out


def test_delay_shifts_the_timesync_round_trip() -> None:
    with connected(*TCP, "--speed", "10") as (_, fast):
        base = statistics.median(_round_trips_ms(fast, 5))
    with connected(*TCP, "--speed", "10", "--delay", "60") as (_, slow):
        delayed = statistics.median(_round_trips_ms(slow, 5))
    assert delayed - base == pytest.approx(120, abs=40)  # 60 ms each way


def test_disconnect_every_closes_the_connection() -> None:
    with connected(*TCP, "--speed", "100", "--disconnect-every", "20") as (server, c):
        c.wait_message(messages.Hello)
        with pytest.raises(ConnectionError):
            _collect(c, 5.0)  # 20 s of agent time is 0.2 s of wall time
        again = AgentClient.tcp(server.address)
        try:
            assert again.wait_message(messages.Hello).node_kind == 1  # a new connection gets a new HELLO
        finally:
            again.close()


def test_blackout_below_silences_the_link_while_deep(tmp_path) -> None:
    params = tmp_path / "p.toml"
    params.write_text("max_dive_s = 40.0\n")
    with connected(*TCP, "--speed", "100", "--blackout-below", "0.15", "--params", str(params)) as (_, c):
        assert c.command(messages.Hover(depth_m=0.5)).result == 0
        # The agent dives, goes silent, surfaces after max_dive_s and is heard again.
        c.wait_message(messages.Sample, timeout_s=20, mode=int(Mode.IDLE))
        samples = c.of(messages.Sample)
        assert max(s.depth_m for s in samples) < 0.17
        indices = [s.sample for s in samples]
        gaps = [b - a for a, b in zip(indices, indices[1:], strict=False)]
        assert max(gaps) > 400  # over 10 s at 40 Hz never reached the ground


# ---------------------------------------------------------------- fuzzing the receive path in-process


_VALID = [
    messages.StartLearning(max_episodes=3), messages.Stop(), messages.Pause(), messages.SetTarget(target_depth_m=0.3),
    messages.Hover(depth_m=0.2), messages.DumpRequest(kind=4), messages.ResetModel(), messages.ParamListRequest(),
    messages.ParamGet(index=-1, name="gamma"), messages.ParamSet(index=3, value=7), messages.Timesync(origin_us=5),
    messages.LogRequest(first_sample=0, end_sample=0xFFFFFFFF), messages.Surface(),
]


@settings(max_examples=150, deadline=None)
@given(
    chunks=st.lists(
        st.one_of(
            st.binary(max_size=300),
            st.tuples(st.sampled_from(range(len(_VALID))), st.integers(0, 300), st.integers(0, 255)),
        ),
        max_size=12,
    )
)
def test_garbage_and_mutated_frames_never_crash_the_agent(chunks: list) -> None:
    link, program, out = in_process_agent()
    encoder = FrameEncoder()
    for chunk in chunks:
        if isinstance(chunk, bytes):
            link.receive(chunk)
        else:
            index, position, value = chunk
            wire = bytearray(encoder.encode(_VALID[index]).wire)
            wire[position % len(wire)] = value
            link.receive(bytes(wire))
        for _ in range(3):
            program.step()
            link.tick()
    # Still alive and still talking protocol.
    link.receive(encoder.encode(messages.Timesync(origin_us=99)).wire)
    assert out.endswith(b"\x00") and program.mode in set(Mode)
