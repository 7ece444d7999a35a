"""Issue 13 on files: no command destroys a recording (item 2), sizes read from a file are bounded (item 1), a damaged
chunk or a reboot inside a recording is handled exactly (item 5). Real MCAP files, the real `dive` process."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest
import zstandard

from groundstation.errors import RecordingExistsError
from groundstation.mcap_io import MAGIC, McapFileWriter, iter_messages, recover
from groundstation.recording.export import export_csv
from groundstation.recording.info import summarize
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.run.job import RunConfig, run
from groundstation.view.replay_convert import convert
from groundstation.view.replay_items import read_items
from protocol import DumpKind
from protocol import messages as m
from tests.groundstation.recording_fixtures import hello, make_recording, received, sample
from tests.reliability.recordings import DIVE_MAIN, dive
from tests.simulator.agent_client import ROOT


def one_error_line(result: object, pattern: str) -> None:
    assert result.returncode == 1, result.stderr  # type: ignore[attr-defined]
    lines = result.stderr.strip().splitlines()  # type: ignore[attr-defined]
    assert len(lines) == 1 and lines[0].startswith("dive: ") and pattern in lines[0], result.stderr  # type: ignore[attr-defined]


# ---------------------------------------------------------------------- item 2: no command destroys a recording
def test_recover_export_and_run_never_write_over_a_recording(tmp_path: Path) -> None:
    original = make_recording(tmp_path / "a.mcap")
    other = make_recording(tmp_path / "b.mcap")
    before = {p: p.read_bytes() for p in (original, other)}
    one_error_line(dive("log", "recover", str(original), "--out", str(original)), "is the input file")  # was 315 B
    one_error_line(dive("log", "export", str(original), "--out", str(original)), "is the input file")  # was CSV
    one_error_line(dive("log", "export", str(original), "--out", str(other)), "is an existing recording")
    # `run --out existing.mcap` silently overwrote it; now refused before connecting (port 9: nobody there)
    with pytest.raises(RecordingExistsError, match="a recording is never overwritten"):
        run(RunConfig(url="tcp://127.0.0.1:9", recorder=RecorderConfig(directory=tmp_path, path=original)))
    assert {p: p.read_bytes() for p in (original, other)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap", "b.mcap"]  # no temporary file left


def test_an_output_folder_takes_the_usual_names_and_a_missing_one_is_one_line(tmp_path: Path) -> None:
    recordings = [make_recording(tmp_path / "a.mcap"), make_recording(tmp_path / "b.mcap")]
    folder = tmp_path / "csv"
    folder.mkdir()
    done = dive("log", "export", *map(str, recordings), "--out", str(folder))  # as cp does: one file each, inside
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in folder.iterdir()) == ["a.csv", "b.csv"]
    one_error_line(dive("log", "export", str(recordings[0]), "--out", str(tmp_path / "nowhere" / "a.csv")),
                   "there is no folder")
    one_error_line(dive("log", "recover", str(recordings[0]), "--out", str(folder)), "is a folder: give a file name")


def test_recover_picks_a_new_name_and_export_replaces_its_target_atomically(tmp_path: Path) -> None:
    original = make_recording(tmp_path / "a.mcap")
    first, second = dive("log", "recover", str(original)), dive("log", "recover", str(original))
    assert first.returncode == second.returncode == 0, second.stderr
    assert (tmp_path / "a-recovered.mcap").is_file() and (tmp_path / "a-recovered-2.mcap").is_file()
    csv = tmp_path / "a.csv"
    csv.write_text("old")
    assert dive("log", "export", str(original), "--out", str(csv)).returncode == 0
    assert csv.read_text().startswith("boot,")


def test_two_recorders_of_one_agent_in_the_same_second_get_two_files(tmp_path: Path) -> None:
    recorders = [Recorder(RecorderConfig(directory=tmp_path)) for _ in range(2)]
    recorders[1]._stamp = recorders[0]._stamp  # the same second
    for recorder in recorders:
        recorder.on_received(received(hello(), 0))
        recorder.on_received(received(sample(0), 1))
        # the header is on disk at once: a kill now leaves a readable file, not 0 bytes
        assert recorder.path is not None and recorder.path.read_bytes().startswith(MAGIC)
    for recorder in recorders:
        recorder.close()
    paths = [r.path for r in recorders]
    assert paths[0] != paths[1] and paths[1] is not None and paths[1].name.endswith("-2.mcap")
    assert all(summarize(p).samples == 1 for p in paths if p is not None)


# ---------------------------------------------------------------------- item 1: untrusted sizes in files
def _record(opcode: int, body: bytes) -> bytes:
    return bytes([opcode]) + struct.pack("<Q", len(body)) + body


def _string(text: str) -> bytes:
    return struct.pack("<I", len(text)) + text.encode()


def _chunk(data: bytes, uncompressed_size: int, compression: str = "zstd") -> bytes:
    body = struct.pack("<QQQI", 0, 0, uncompressed_size, 0) + _string(compression) + struct.pack("<Q", len(data)) + data
    return _record(0x06, body)


def _file_with(*records: bytes) -> bytes:
    return MAGIC + _record(0x01, _string("diving-agent") + _string("test")) + b"".join(records)


def _zeros_compressed(megabytes: int) -> bytes:
    compressor = zstandard.ZstdCompressor(level=3).compressobj()
    block = bytes(1 << 20)
    return b"".join(compressor.compress(block) for _ in range(megabytes)) + compressor.flush()


def test_a_compression_bomb_is_refused_with_one_line(tmp_path: Path) -> None:
    """A 34 KB zstd MCAP took `log info` to 1.2 GB and 8 minutes; chunks now decompress to at most 64x the file."""
    bomb = tmp_path / "bomb.mcap"
    bomb.write_bytes(_file_with(_chunk(_zeros_compressed(512), 512 << 20)))
    assert bomb.stat().st_size < 64 * 1024
    result = dive("log", "info", str(bomb))
    one_error_line(result, "claim more than 64 times the file's size")
    # The peak of that one process, measured by a parent of its own (this test process's RUSAGE_CHILDREN would
    # also count every earlier child of the suite).
    peak = subprocess.run(
        [sys.executable, "-c", _PEAK_OF_CHILD, sys.executable, "-c", DIVE_MAIN, "log", "info", str(bomb)],
        capture_output=True, text=True, timeout=240, cwd=ROOT,
    )
    assert int(peak.stdout.split()[-1]) < 400 * 1024  # kB: the child never grew past 400 MB


_PEAK_OF_CHILD = (
    "import resource, subprocess, sys; subprocess.run(sys.argv[1:], capture_output=True); "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def test_lying_chunk_sizes_and_record_lengths_read_nothing_large(tmp_path: Path) -> None:
    liar = tmp_path / "liar.mcap"  # declares 100 bytes, decompresses to 64 MiB: read as damaged, 101 bytes taken
    liar.write_bytes(_file_with(_chunk(_zeros_compressed(64), 100)))
    huge = tmp_path / "huge.mcap"  # a record that claims 2**40 bytes
    huge.write_bytes(_file_with(bytes([0x06]) + struct.pack("<Q", 1 << 40) + bytes(64)))
    tracemalloc.start()
    try:
        assert summarize(liar).damaged_chunks == 1
        assert not summarize(huge).complete
        assert tracemalloc.get_traced_memory()[1] < 32 << 20
    finally:
        tracemalloc.stop()


def test_wrong_shaped_json_is_reported_never_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "shapes.mcap"
    with McapFileWriter(path) as w:
        samples = w.channel("/agent/SAMPLE")
        for data in (b"{}", b"[1, 2]", b"not json", b'{"sample": "7", "t_us": 1}', b"\xff\xfe"):
            w.write(samples, data, 1)
        w.write(w.channel("/agent/EPISODE_END"), b'{"episode": 1}', 2)
        w.write(w.channel("/link"), b"[]", 3)
        w.write(w.channel("/event"), b'"link_lost"', 4)
        w.write(samples, json.dumps({**sample(3).to_dict(), "_backfilled": False}).encode(), 5)
    summary = summarize(path)
    assert (summary.malformed, summary.samples) == (8, 1)
    result = dive("log", "info", str(path))
    assert result.returncode == 0 and "8 messages of the wrong shape (skipped)" in result.stdout, result.stderr
    exported = dive("log", "export", str(path), "--out", str(tmp_path / "s.csv"))
    assert exported.returncode == 0 and "Traceback" not in exported.stderr
    assert "(1 rows)" in exported.stdout


def test_a_recorded_dump_announcing_256_mib_replays_in_bounded_memory(tmp_path: Path) -> None:
    """A 21 KB recording of such chunks took `dive replay` past 4 GiB."""
    path = tmp_path / "dumps.mcap"
    recorder = Recorder(RecorderConfig(path=path))
    recorder.on_received(received(hello(), 0))
    for i in range(1, 200):
        recorder.on_received(received(m.DumpChunk(dump_id=i, kind=int(DumpKind.COUNTS), episode=1,
                                                  total_bytes=256 << 20, offset=0, data=bytes(100)), i))
    recorder.close()
    tracemalloc.start()
    try:
        _, count = convert(read_items(path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert count == 200 and peak < 32 << 20


# ---------------------------------------------------------------------- item 5: exact recordings
def test_a_damaged_chunk_loses_only_that_chunk(tmp_path: Path) -> None:
    """One flipped bit kept 3 187 of 6 293 messages and called the complete file truncated."""
    path = make_recording(tmp_path / "flip.mcap", samples=1000, flush_every=100)
    intact = summarize(path)
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle] ^= 0x10
    path.write_bytes(bytes(data))
    damaged = summarize(path)
    assert damaged.complete and damaged.damaged_chunks == 1
    assert intact.messages - 250 <= damaged.messages < intact.messages  # one chunk: ~100 samples, their raw frames
    count, truncated = recover(path, tmp_path / "kept.mcap")
    assert count == damaged.messages and not truncated
    assert summarize(tmp_path / "kept.mcap").samples == damaged.samples


def test_a_recording_across_a_reboot_is_summarised_and_exported_per_boot(tmp_path: Path) -> None:
    path = make_recording(tmp_path / "reboot.mcap", boots=(5, 6), samples=200)
    summary = summarize(path)
    assert [(b.boot, b.samples, b.samples_missing) for b in summary.boots] == [(1, 200, 0), (2, 200, 0)]
    assert summary.samples == 400 and summary.samples_missing == 0
    rows = export_csv(path, tmp_path / "reboot.csv")
    lines = (tmp_path / "reboot.csv").read_text().splitlines()
    assert rows == 400 and lines[0].startswith("boot,") and lines[201].startswith("2,")


def test_an_impossible_index_in_a_file_is_not_missing_samples(tmp_path: Path) -> None:
    path = tmp_path / "impossible.mcap"
    recorder = Recorder(RecorderConfig(path=path))
    recorder.on_received(received(hello(), 0))
    recorder.on_received(received(m.Heartbeat(uptime_ms=1000, mode=1, battery_mv=4000, log_next_sample=0), 1))
    for i in range(50):
        recorder.on_received(received(sample(i), 2 + i))
    recorder.on_received(received(sample(2**31, t_us=2_000_000), 60))
    recorder.close()
    summary = summarize(path)
    assert (summary.samples, summary.samples_missing, summary.boots[0].samples_impossible) == (50, 0, 1)
    assert len(list(iter_messages(path, {"/agent/SAMPLE"}))) == 51


def test_minari_missing_is_one_line_that_says_how_to_install_it(tmp_path: Path) -> None:
    recording = make_recording(tmp_path / "a.mcap")
    minari_hidden = "import sys; sys.modules['minari'] = None; " + DIVE_MAIN
    done = subprocess.run([sys.executable, "-c", minari_hidden, "log", "export", str(recording), "--format", "minari",
                           "--out", str(tmp_path / "datasets")], capture_output=True, text=True, timeout=120)
    one_error_line(done, "needs minari: pip install -e '.[minari]' in the checkout (or pip install minari)")
