"""`dive log info` through the chunk and message indexes (issue 28 item 1): the same summary as reading every message,
in bounded memory, a folder summarised file by file (in worker processes too) with a line per split recording and
per boot that spans files. Real recordings by the real recorder, read back from disk."""

from __future__ import annotations

import json
import struct
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.mcap_io import McapFileWriter
from groundstation.mcap_io.indexed import IndexedChunk, open_indexed
from groundstation.recording import summaries
from groundstation.recording.info import summarize, summarize_stream
from groundstation.recording.info_indexed import IndexedTotals, chunk_samples
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import Received
from protocol import Frame, FrameFlag, Message
from protocol import messages as m
from protocol.frame import build_inner
from tests.groundstation.recording_fixtures import hello, make_recording, sample
from tests.groundstation.synthetic_agent import generate, play_session


def _received(message: Message, seq: int, flags: int = 0) -> Received:
    inner = build_inner(flags, seq, message.DEFINITION.msg_id, message.pack())
    return Received(Frame(flags, seq, message.DEFINITION.msg_id, message, inner),
                    1_700_000_000_000_000_000 + seq * 1000, None, bool(flags & FrameFlag.REPLAYED))


def _backfilled(path: Path) -> Path:
    """Samples 0-99 with 40-59 lost live and backfilled later, 10 received twice, a heartbeat, a reboot, an
    impossible index: everything the summary counts in one file, across several chunks."""
    recorder = Recorder(RecorderConfig(path=path, flush_period_s=3600))
    seq = 0

    def send(message: Message, flags: int = 0) -> None:
        nonlocal seq
        seq += 1
        recorder.on_received(_received(message, seq, flags))

    send(hello(5))
    send(m.Heartbeat(uptime_ms=1000, mode=1, battery_mv=4000, log_next_sample=0))
    for i in [*range(40), 10, *range(60, 100)]:
        send(sample(i))
        if i % 25 == 0:
            assert recorder._writer is not None
            recorder._writer.flush()  # several chunks
    for i in range(40, 60):
        send(sample(i), int(FrameFlag.REPLAYED))
    send(sample(2**31, t_us=3_000_000))
    send(hello(6))
    for i in range(30):
        send(sample(i))
    recorder.close()
    return path


def _shapes(path: Path) -> Path:
    """JSON samples of every wrong shape, and one right one, with no raw frame beside them (another tool's file)."""
    with McapFileWriter(path) as w:
        samples = w.channel("/agent/SAMPLE")
        for data in (b"{}", b"[1, 2]", b"not json", b'{"sample": "7", "t_us": 1}', b"\xff\xfe"):
            w.write(samples, data, 1)
        w.write(w.channel("/link"), b"[]", 3)
        w.write(samples, json.dumps({**sample(3).to_dict(), "_backfilled": True}).encode(), 5)
    return path


def _synthetic(path: Path) -> Path:
    recorder = Recorder(RecorderConfig(path=path, flush_period_s=3600))
    recorder.set_parameters({"z_cells": 10.0, "zdot_cells": 10.0})
    try:
        play_session(generate(duration_s=300.0, backfill_every=7), [recorder])
    finally:
        recorder.close()
    return path


def _damaged(path: Path) -> Path:
    make_recording(path, samples=1000, flush_every=100)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))
    return path


@pytest.mark.parametrize("make", [_backfilled, _shapes, _synthetic, _damaged,
                                  lambda p: make_recording(p, boots=(5, 6), samples=200)],
                         ids=["backfill-reboot-impossible", "wrong-shapes", "synthetic-run", "damaged-chunk", "reboot"])
def test_the_indexed_summary_is_the_streamed_one(make: object, tmp_path: Path) -> None:
    path = make(tmp_path / "r.mcap")  # type: ignore[operator]
    assert open_indexed(path) is not None  # the fast path is the one taken
    indexed, streamed = summarize(path), summarize_stream(path)
    assert indexed == streamed
    assert [b.held for b in indexed.boots] == [b.held for b in streamed.boots]  # the ranges combine() unites
    assert indexed.samples > 0


def test_counts_of_the_crafted_recording(tmp_path: Path) -> None:
    s = summarize(_backfilled(tmp_path / "r.mcap"))
    assert [(b.boot, b.boot_id, b.samples, b.samples_backfilled, b.samples_missing, b.samples_impossible)
            for b in s.boots] == [(1, 5, 100, 20, 0, 1), (2, 6, 30, 0, 0, 0)]


def test_a_file_cut_short_is_read_as_a_stream(tmp_path: Path) -> None:
    path = make_recording(tmp_path / "r.mcap", samples=500, flush_every=100)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size * 2 // 3])
    assert open_indexed(cut) is None
    summary = summarize(cut)
    assert not summary.complete and 0 < summary.samples < 500


def test_memory_does_not_grow_with_the_recording(tmp_path: Path) -> None:
    small, large = _synthetic(tmp_path / "small.mcap"), tmp_path / "large.mcap"
    recorder = Recorder(RecorderConfig(path=large, flush_period_s=3600))
    try:
        play_session(generate(duration_s=2400.0), [recorder])
    finally:
        recorder.close()
    peaks = []
    for path in (small, large):
        summarize(path)  # imports and caches first
        tracemalloc.start()
        try:
            summarize(path)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    assert large.stat().st_size > 6 * small.stat().st_size
    assert peaks[1] < 2 * peaks[0] + (1 << 20), peaks  # one chunk at a time, held indices as ranges


def test_a_folder_of_split_parts_gets_a_combined_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    recorder = Recorder(RecorderConfig(directory=tmp_path / "split", split_bytes=40_000))
    recorder.on_received(_received(hello(11), 0))
    for i in range(4000):
        if i % 50 == 0:
            recorder.on_received(_received(m.Heartbeat(uptime_ms=1000 + 20 * i, mode=1, battery_mv=4000,
                                                       log_next_sample=i), 2 * i + 1))
        if i not in (1500, 1501):  # two samples lost for good
            recorder.on_received(_received(sample(i), 2 * i + 2))
    recorder.close()
    parts = recorder.paths
    assert len(parts) >= 3
    text = " ".join(CliRunner().invoke(app, ["log", "info", str(tmp_path / "split")]).stdout.split())
    assert f"and {len(parts) - 1} more part(s): {len(parts)} files" in text
    assert "samples 3998 (0 backfilled, 2 still missing)" in text  # a hole only the parts together show
    assert f"agent 00000007 boot 0000000b: {len(parts)} files" in text
    # The same summaries from worker processes as from this one.
    serial = summaries.summarize_files(parts)
    monkeypatch.setattr(summaries, "PARALLEL_FROM_BYTES", 0)
    monkeypatch.setattr(summaries, "workers", lambda: 2)
    assert summaries.summarize_files(parts) == serial


def test_two_recorders_of_one_boot_count_each_sample_once(tmp_path: Path) -> None:
    """dive run and a dive record beside it hold the same samples: the boot's line counts them once."""
    for name, indices in (("run", range(0, 300)), ("record", range(100, 400))):
        recorder = Recorder(RecorderConfig(path=tmp_path / f"{name}.mcap"))
        recorder.on_received(_received(hello(9), 0))
        for i in indices:
            recorder.on_received(_received(sample(i), i + 1))
        recorder.close()
    text = " ".join(CliRunner().invoke(app, ["log", "info", str(tmp_path)]).stdout.split())
    assert "agent 00000007 boot 00000009: 2 files" in text
    assert "samples 400 (0 backfilled, 0 still missing)" in text


def test_a_hostile_message_length_in_a_chunk_is_a_malformed_message() -> None:
    """A chunk whose CRC holds but whose SAMPLE record claims 2**63 bytes: counted as malformed, nothing read."""
    record = struct.pack("<BQHIQQ", 0x05, 2**63 + 5, 1, 0, 5, 5) + b"{}"
    chunk = IndexedChunk(record, {1: np.array([[5, 0]], dtype=np.uint64)}, len(record))
    totals = IndexedTotals()
    offsets, *_ = chunk_samples(chunk, 1, 2, totals)
    assert len(offsets) == 0 and totals.malformed == 1
