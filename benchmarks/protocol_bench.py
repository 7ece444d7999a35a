"""Throughput of our SAMPLE frames against pymavlink's MAVLink v2 ATTITUDE, measured in the same run.

Run: `.venv/bin/pip install -e '.[bench]' && .venv/bin/python benchmarks/protocol_bench.py [--frames N]`.
Not a test: it prints figures and ratios.
Goals (issues 2 and 16): decode >= 3x pymavlink (with fastcrc), encode >= 2x.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

try:
    from pymavlink.dialects.v20 import common as mavlink2
except ImportError:  # the anchor lives in the `bench` extra, not in the test install
    sys.exit("protocol_bench needs pymavlink, the anchor it measures against: pip install -e '.[bench]'")

from groundstation.recording.columns import message_array
from protocol import FrameEncoder, StreamDecoder, compiled
from protocol.columns import columns, payload_records
from protocol.messages import Sample

CHUNK = 4096  # bytes per read, as a serial or TCP link delivers them
REPEATS = 5  # best of five, the tasks taking turns: the machine is shared, and load drifts alike for all


def _best_rates(count: int, runs: dict[str, Callable[[], object]]) -> dict[str, float]:
    """Frames per second of the fastest of REPEATS runs of each task (each handles `count` frames).

    The tasks run in turn, round after round, so that a change of load on a shared machine falls on
    every task alike instead of on whichever ran during it.
    """
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(REPEATS):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            best[name] = min(best[name], time.perf_counter() - start)
    return {name: count / seconds for name, seconds in best.items()}


def _chunks(stream: bytes) -> list[bytes]:
    return [stream[i : i + CHUNK] for i in range(0, len(stream), CHUNK)]


def _samples(n: int) -> list[Sample]:
    return [
        Sample(t_us=1_000_000 + 100_000 * i, sample=i, episode=i // 300, step=i % 300, pressure_pa=101325.0 + i,
               depth_m=0.5 + 0.001 * (i % 97), velocity_mps=-0.01 * (i % 13), actuator_deg=65.0 + (i % 7),
               actuator_cmd_deg=66.0, reward=-1.0 if i % 5 else 0.0, state=i % 101, action=i % 2, mode=1)
        for i in range(n)
    ]


def _attitudes(n: int) -> list[mavlink2.MAVLink_attitude_message]:
    return [
        mavlink2.MAVLink_attitude_message(100 * i, 0.01 * (i % 50), -0.02 * (i % 30), 0.5, 0.001 * i, 0.002, -0.003)
        for i in range(n)
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=20_000)
    n = parser.parse_args().frames

    samples = _samples(n)

    def encode_ours(compiled: bool = True) -> list[bytes]:
        encoder = FrameEncoder(compiled=compiled)
        return [encoder.encode(s).wire for s in samples]

    ours_stream = b"".join(encode_ours())
    ours_chunks = _chunks(ours_stream)

    def decode_ours(compiled: bool = True) -> int:
        decoder = StreamDecoder(compiled=compiled)
        count = sum(len(decoder.feed(c)) for c in ours_chunks)
        assert count == n and decoder.stats.rejects == 0, (count, decoder.stats)
        return count

    attitudes = _attitudes(n)
    sender = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)

    def encode_mav() -> list[bytes]:
        return [m.pack(sender) for m in attitudes]

    mav_stream = b"".join(encode_mav())
    mav_chunks = _chunks(mav_stream)

    def decode_mav() -> int:
        receiver = mavlink2.MAVLink(None)
        count = 0
        for c in mav_chunks:
            count += len(receiver.parse_buffer(c) or ())
        assert count == n, count
        return count

    inners = [f.inner for f in StreamDecoder().feed(ours_stream)]
    definition = Sample.DEFINITION

    def columns_stdlib() -> None:
        cols = columns(payload_records(inners, definition), definition)
        assert len(cols["depth_m"]) == n

    def columns_numpy() -> None:
        array = message_array(inners, definition)
        assert array["depth_m"].shape == (n,)

    fast_crc = mavlink2.x25crc

    def without_fastcrc(run: Callable[[], object]) -> Callable[[], object]:
        """Second anchor: pymavlink as it runs without its optional `fastcrc` (Rust) CRC, i.e. pure Python."""
        def slow() -> object:
            mavlink2.x25crc = mavlink2._x25crc_slow
            try:
                return run()
            finally:
                mavlink2.x25crc = fast_crc
        return slow

    compiled.wait()  # the compiled path loads in the background: measure it loaded
    encode_ours(), decode_ours()
    rates = _best_rates(n, {
        "encode ours": encode_ours,
        "encode pymavlink": encode_mav,
        "encode ours-stdlib": lambda: encode_ours(compiled=False),
        "encode pymavlink-purepy": without_fastcrc(encode_mav),
        "decode ours": decode_ours,
        "decode pymavlink": decode_mav,
        "decode ours-stdlib": lambda: decode_ours(compiled=False),
        "decode pymavlink-purepy": without_fastcrc(decode_mav),
        "columns stdlib": columns_stdlib,
        "columns numpy": columns_numpy,
    })
    print(f"protocol benchmark: {n} frames, best of {REPEATS} (tasks in turn); "
          f"SAMPLE {len(ours_stream) // n} B/frame on the wire, ATTITUDE {len(mav_stream) // n} B/frame")
    print(f"{'task':<44} {'ours frames/s':>14} {'pymavlink frames/s':>19} {'ratio':>7} {'goal':>6}")
    for task, goal in (("encode", 2.0), ("decode", 3.0)):
        for anchor, note in (("pymavlink", "with fastcrc"), ("pymavlink-purepy", "pure-Python CRC")):
            ours, theirs = rates[f"{task} ours"], rates[f"{task} {anchor}"]
            ratio = ours / theirs
            verdict = "met" if ratio >= goal else "MISSED"
            label = f"{task} SAMPLE vs ATTITUDE ({note})"
            print(f"{label:<44} {ours:>14,.0f} {theirs:>19,.0f} {ratio:>6.2f}x {goal:>4.0f}x {verdict}")
        ours, theirs = rates[f"{task} ours-stdlib"], rates[f"{task} pymavlink"]
        label = f"{task}, stdlib codec only (no numba)"
        print(f"{label:<44} {ours:>14,.0f} {theirs:>19,.0f} {ours / theirs:>6.2f}x")
    for label, key in (("columnar decode, inner frames -> stdlib tuples", "columns stdlib"),
                       ("columnar decode, inner frames -> numpy array", "columns numpy")):
        ratio = rates[key] / rates["decode pymavlink"]
        print(f"{label:<44} {rates[key]:>14,.0f} {rates['decode pymavlink']:>19,.0f} {ratio:>6.2f}x")
    print("decode uses 4 KiB chunks of the wire stream; columnar decode starts from recorded inner frames (/raw/rx).")


if __name__ == "__main__":
    main()
