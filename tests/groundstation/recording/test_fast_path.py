"""The recorder's fast paths write what the slow ones wrote: the same MCAP bytes, the same JSON values."""

from __future__ import annotations

import json
import math
import random
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from groundstation.mcap_io import McapFileWriter, read_recording
from groundstation.recording.analyst_columns import float32_fields
from groundstation.recording.bodies import message_json
from groundstation.recording.environments import wire_float32
from protocol import Message, messages
from tests.protocol.strategies import any_message


def _write(path: Path, fast: bool) -> bytes:
    rng = random.Random(7)
    with McapFileWriter(path, flush_period_s=3600) as w:
        if not fast:  # what every write did before: the mcap library's own add_message
            writer = w._writer
            def add(messages: tuple[tuple[int, bytes], ...], log_time: int, publish_time: int) -> None:
                for channel, data in messages:
                    writer.add_message(channel, log_time=log_time, data=data, publish_time=publish_time)

            def add_pair(first: int, data: bytes, second: int, raw: bytes, log_time: int, publish_time: int) -> None:
                add(((first, data), (second, raw)), log_time, publish_time)
            w._add, w._add_pair = add, add_pair
        channels = [w.channel(f"/topic/{i}", "json", f"schema{i}", {"type": "object"}) for i in range(3)]
        channels.append(w.channel("/raw/rx", "diving-agent-frame-v1"))
        for i in range(30_000):  # several 256 KiB chunks; times out of order now and then
            log_time = 1_000_000 * i + rng.randrange(-5_000_000, 5_000_000)
            data = rng.randbytes(rng.randrange(0, 90))
            if i % 2:
                w.write(rng.choice(channels), data, log_time, None if i % 3 else log_time + 7)
            elif i % 4:
                w.write_many(((rng.choice(channels), data), (channels[-1], data[:9])), log_time, log_time + 3)
            else:  # the recorder's path for every frame
                w.write_frame(rng.choice(channels), data, channels[-1], data[:9], log_time, log_time + 3)
    return path.read_bytes()


def test_the_fast_message_writer_writes_the_bytes_of_mcaps_add_message(tmp_path: Path) -> None:
    fast, slow = _write(tmp_path / "fast.mcap", True), _write(tmp_path / "slow.mcap", False)
    assert fast == slow
    assert len(read_recording(tmp_path / "fast.mcap").messages) == 45_000


def _reference_json(message: Message, seq: int, flags: int, backfilled: bool) -> bytes:
    """The recorder's JSON before orjson: the standard library, NaN and infinities as null; a float32 field as the
    shortest number that is the same float32 (issue 40)."""
    body = message.to_dict()
    single = float32_fields(f"/agent/{message.DEFINITION.name}")
    for key, value in body.items():
        if key in single and isinstance(value, float):
            value = body[key] = wire_float32(value)
        if isinstance(value, float) and not math.isfinite(value):
            body[key] = None
    body["_seq"], body["_flags"], body["_backfilled"] = seq, flags, backfilled
    return json.dumps(body, separators=(",", ":")).encode()


@settings(max_examples=400, deadline=None)
@given(message=any_message, seq=st.integers(0, 0xFFFF), flags=st.integers(0, 255), backfilled=st.booleans())
def test_orjson_bodies_read_back_as_the_values_of_the_standard_library_bodies(
        message: Message, seq: int, flags: int, backfilled: bool) -> None:
    ours = json.loads(message_json(message, seq, flags, backfilled))
    assert ours == json.loads(_reference_json(message, seq, flags, backfilled))
    assert list(ours) == list(json.loads(_reference_json(message, seq, flags, backfilled)))  # same key order


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.floats(width=32), min_size=6, max_size=6))
def test_nan_and_infinities_become_null_and_every_float_reads_back_exactly(values: list[float]) -> None:
    sample = messages.Sample(t_us=1, sample=2, pressure_pa=values[0], depth_m=values[1], velocity_mps=values[2],
                             actuator_deg=values[3], actuator_cmd_deg=values[4], reward=values[5])
    body = json.loads(message_json(messages.Sample.unpack(sample.pack()), 1, 0, False))
    for name, value in zip(("pressure_pa", "depth_m", "velocity_mps", "actuator_deg", "actuator_cmd_deg", "reward"),
                           values, strict=True):
        expected = messages.Sample.unpack(sample.pack()).to_dict()[name]
        # the same float32, as its shortest text (116085810.0 for 116085808.0)
        assert body[name] == (wire_float32(expected) if math.isfinite(value) else None)
        assert body[name] is None or np.float32(body[name]) == np.float32(expected)
