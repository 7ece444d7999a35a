"""`serve --baud N`: bytes to the ground leave at a UART's rate (10 bits a byte), per-mode SAMPLE rates still met."""

from __future__ import annotations

import time

import pytest

from protocol import AckResult, DumpKind, FrameEncoder, Mode, messages
from simulator.serve.transport import FIFO_BYTES, Pacer
from tests.simulator.agent_client import connected

BAUD = 115_200


class FakeClock:
    def __init__(self) -> None:
        self.s = 0.0

    def __call__(self) -> float:
        return self.s


def test_a_pacer_lets_baud_over_10_bytes_a_second_after_its_fifo() -> None:
    clock = FakeClock()
    pacer = Pacer(BAUD, clock)
    assert pacer.allowed() == FIFO_BYTES  # the FIFO's burst
    pacer.spent(FIFO_BYTES)
    assert pacer.allowed() == 0
    clock.s += 0.01
    assert pacer.allowed() == FIFO_BYTES  # 115.2 bytes earned, at most a FIFO held
    pacer.spent(FIFO_BYTES)
    clock.s += 0.002
    assert pacer.allowed() == int(0.002 * BAUD / 10)
    assert pacer.wait_s(1000) == pytest.approx((FIFO_BYTES - int(0.002 * BAUD / 10) - 0.04) / (BAUD / 10), abs=1e-3)


@pytest.mark.slow  # a few wall seconds at --speed 1
def test_at_115200_baud_a_dump_takes_its_bytes_time_and_hover_samples_keep_their_rate() -> None:
    with connected("--tcp", "127.0.0.1:0", "--speed", "1", "--seed", "5", "--baud", str(BAUD)) as (_, c):
        c.encoder = FrameEncoder(10)
        assert c.command(messages.Hover(depth_m=0.3)).result == AckResult.ACCEPTED
        c.wait_message(messages.Sample, mode=int(Mode.HOVER))
        # HOVER sends a SAMPLE every 25 ms of agent time: 2 wall seconds at --speed 1 bring about 80, none lost.
        start = time.monotonic()
        first = len(c.of(messages.Sample))
        while time.monotonic() - start < 2.0:
            c.pump()
        hover = [s for s in c.of(messages.Sample)[first:] if s.mode == Mode.HOVER]
        rate = len(hover) / (time.monotonic() - start)
        assert 0.85 * 40 <= rate <= 1.15 * 40, rate
        indices = [s.sample for s in hover]
        assert indices == list(range(indices[0], indices[0] + len(indices)))  # none dropped
        # 8 S bytes of Q_VALUES and a COUNTS of 4 S^2 = 40 804 bytes (S = 101): at 11 520 B/s at least 3.5 s.
        asked = time.monotonic()
        ack = c.command(messages.DumpRequest(kind=int(DumpKind.COUNTS), dump_id=0, offset=0, length=0))
        assert ack.result == AckResult.ACCEPTED
        total = 0
        while total < 4 * 101 * 101:
            total += len(c.wait_message(messages.DumpChunk, timeout_s=15).data)
        took = time.monotonic() - asked
        assert took >= 0.9 * total * 10 / BAUD, took
        # The SAMPLEs produced meanwhile waited behind the dump, none lost: their sample indices run on.
        after = [s.sample for s in c.of(messages.Sample) if s.mode == Mode.HOVER]
        c.wait_message(messages.Sample, mode=int(Mode.HOVER))
        tail = [s.sample for s in c.of(messages.Sample) if s.mode == Mode.HOVER]
        assert tail[: len(after)] == after and tail == list(range(tail[0], tail[0] + len(tail)))
