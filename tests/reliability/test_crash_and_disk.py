"""Crash and disk faults: kill -9 while recording, an unwritable or full disk, truncated and corrupted MCAP files
given to `dive log info` and `dive log export` (one clear line, never a traceback)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.reliability.recordings import DIVE_MAIN, dive, read
from tests.simulator.agent_client import ROOT, running


@pytest.fixture
def agent_url() -> Iterator[str]:
    with running("--tcp", "127.0.0.1:0", "--preset", "hardware", "--speed", "20", "--seed", "9") as agent:
        yield agent.address


def _one_clear_line(done: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in done.stderr
    if done.returncode != 0:
        # the error is one line (the progress bar above it is what the run showed before)
        errors = [line for line in done.stderr.splitlines() if line.startswith("dive:")]
        assert len(errors) == 1, done.stderr


@pytest.mark.slow
def test_kill_9_while_recording_leaves_a_readable_file_that_recover_indexes(agent_url: str, tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "run", agent_url, "--out", str(tmp_path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    try:
        deadline = time.monotonic() + 60  # a loaded machine can take seconds to start dive and connect
        while not any(p.stat().st_size > 20_000 for p in tmp_path.glob("*.mcap")) and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(2)
        killed_ns = time.time_ns()
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(10)
    (path,) = tmp_path.glob("*.mcap")
    info = dive("log", "info", str(path))
    assert info.returncode == 0 and "Traceback" not in info.stderr
    fixed = tmp_path / "fixed.mcap"
    done = dive("log", "recover", str(path), "--out", str(fixed))
    assert done.returncode == 0, done.stderr
    with fixed.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None and summary.statistics.message_count > 0
    rec = read(fixed)
    last_ns = max(m.log_time for m in _messages(fixed))
    assert killed_ns - last_ns < 2e9, "at most the last 2 s are lost"
    missing, duplicated = rec.missing_and_duplicated()
    assert not duplicated and rec.live_in_order()


def _messages(path: Path) -> list:  # type: ignore[type-arg]
    with path.open("rb") as f:
        return [message for _, _, message in make_reader(f).iter_messages()]


@pytest.fixture
def recording(agent_url: str, tmp_path: Path) -> Path:
    out = tmp_path / "rec"
    done = dive("run", agent_url, "--episodes", "1", "--out", str(out))
    assert done.returncode == 0, done.stderr
    (path,) = out.glob("*.mcap")
    return path


def _damaged(recording: Path, tmp_path: Path) -> dict[str, Path]:
    data = recording.read_bytes()
    cases = {"truncated": data[: len(data) // 2], "cut in the header": data[:5], "empty": b"",
             "not mcap": b"hello world\n" * 100}
    middle = bytearray(data)
    middle[len(data) // 3 : len(data) // 3 + 64] = os.urandom(64)
    cases["corrupted"] = bytes(middle)
    paths = {}
    for name, content in cases.items():
        paths[name] = tmp_path / f"{name.replace(' ', '_')}.mcap"
        paths[name].write_bytes(content)
    return paths


def test_damaged_recordings_give_one_clear_line_in_log_info_export_and_replay(recording: Path, tmp_path: Path) -> None:
    for name, path in _damaged(recording, tmp_path).items():
        for args in (
            ["log", "info", str(path)],
            ["log", "export", str(path), "--out", str(tmp_path / "x.csv")],
            ["replay", str(path), "--rrd", str(tmp_path / "x.rrd")],
        ):
            done = dive(*args)
            _one_clear_line(done)
            if name in ("empty", "not mcap", "cut in the header"):
                assert done.returncode == 1, (name, args, done.stderr)


def test_an_unwritable_recording_folder_is_one_clear_line_and_the_link_is_closed(agent_url: str,
                                                                                  tmp_path: Path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    done = dive("run", agent_url, "--episodes", "1", "--out", str(blocker / "rec"))
    assert done.returncode == 1
    _one_clear_line(done)
    # the link was closed: the agent takes the next connection (a raw client gets its HELLO)
    from protocol import messages
    from tests.simulator.agent_client import AgentClient

    client = AgentClient.tcp(agent_url)
    try:
        assert client.wait_message(messages.Hello)
    finally:
        client.close()


@pytest.mark.slow
def test_a_full_disk_is_one_clear_line_and_what_was_recorded_stays_readable(agent_url: str, tmp_path: Path) -> None:
    disk = tmp_path / "tiny"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=100k", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tiny tmpfs (needs root): {mounted.stderr.decode().strip()}")
    try:
        done = dive("run", agent_url, "--episodes", "2", "--out", str(disk), timeout_s=120)
        _one_clear_line(done)
        assert done.returncode == 1 and "space" in done.stderr.lower(), done.stderr
        (path,) = disk.glob("*.mcap")
        info = dive("log", "info", str(path))
        assert info.returncode == 0 and "Traceback" not in info.stderr
        assert "samples" in info.stdout
    finally:
        subprocess.run(["umount", str(disk)], check=False)
