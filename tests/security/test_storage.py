"""Storage faults (issue 25 M2, M3): a 0-byte part after kill -9 at a split rollover, a disk that fills up."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.errors import RecordingError
from groundstation.mcap_io import iter_messages
from groundstation.recording.recorder import Recorder, RecorderConfig
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.synthetic_agent import generate, play_session
from tests.security.attack import RunInThread


def test_a_0_byte_part_left_by_kill_9_at_a_rollover_does_not_refuse_the_folder(tmp_path: Path) -> None:
    recorder = Recorder(RecorderConfig(directory=tmp_path, split_bytes=40_000))
    try:
        play_session(generate(duration_s=200.0), [recorder])
    finally:
        recorder.close()
    parts = recorder.paths
    assert len(parts) >= 2
    # what kill -9 between creating the next part and its header's write leaves (3 of 6 aimed kills did)
    empty = parts[-1].with_name(parts[-1].name.replace(f"part{len(parts):03d}", f"part{len(parts) + 1:03d}"))
    empty.touch()
    runner = CliRunner()
    info = runner.invoke(app, ["log", "info", str(tmp_path), "--json"])
    assert info.exit_code == 0, info.output
    export = runner.invoke(app, ["log", "export", str(tmp_path), "--format", "csv", "--out", str(tmp_path / "x.csv")])
    assert export.exit_code == 0, export.output
    replay = runner.invoke(app, ["replay", str(tmp_path), "--rrd", str(tmp_path / "r.rrd")])
    assert replay.exit_code == 0, replay.output
    assert (tmp_path / "x.csv").stat().st_size > 1000 and (tmp_path / "r.rrd").stat().st_size > 1000


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 600 KiB tmpfs (root only): the disk that fills up during a run."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("needs root to mount a small tmpfs")
    where = tmp_path / f"disk-{uuid.uuid4().hex[:6]}"
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=600k", "tmpfs", str(where)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def test_a_full_disk_stops_the_run_and_the_agent_and_keeps_what_was_written(small_disk: Path) -> None:
    agent = FakeAgent(period_s=0.001)
    try:
        job = RunInThread(agent.url, small_disk)
        job.join(60)  # by itself: the disk fills up
    finally:
        agent.close()
    assert isinstance(job.error, RecordingError) and "No space left" in str(job.error), job.error
    assert "CMD_STOP" in agent.executed and not agent.learning  # stopped as on Ctrl-C, not left learning
    # the file ends inside a chunk (no room for the rest): the project's reader keeps every whole chunk before it
    held = sorted(json.loads(msg.data)["sample"] for path in small_disk.glob("*.mcap")
                  for msg in iter_messages(path, {"/agent/SAMPLE"}))
    assert len(held) > 500 and held == list(range(len(held)))  # what was written reads back, in order, no holes
