"""Recordings: the main job writes an MCAP the mcap library reads, every message valid against its schema."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from groundstation.links.runs import find_run
from groundstation.mcap_io import is_complete, read_recording, recover
from groundstation.recording.export import export_csv, export_npz
from groundstation.recording.held_frames import RAW_RX_UNUSED_TOPIC
from groundstation.recording.info import summarize
from groundstation.recording.recorder import RecorderConfig
from groundstation.run.job import RunConfig, run
from groundstation.run.marker import send_marker
from protocol import FrameFlag
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.mcap_validation import validate_with_mcap_library


def test_main_job_records_a_complete_valid_mcap(tmp_path: Path) -> None:
    agent = FakeAgent(drop_every=9)
    try:
        config = RunConfig(url=agent.url, episodes=4, params={"target_depth_m": "0.6"},
                           recorder=RecorderConfig(directory=tmp_path))
        marked = []

        def progress(status: object) -> None:
            if not marked:  # `dive mark` as a second process would: find the run, send through its hub
                send_marker(find_run(), "first progress")
                marked.append(True)

        result = run(config, progress)
    finally:
        agent.close()
    assert result.status.episodes >= 4 and result.still_missing == 0
    [path] = result.paths
    assert path.parent == tmp_path and "agent000a6e47" in path.name
    counts = validate_with_mcap_library(path)
    for topic in ("/agent/SAMPLE", "/agent/EPISODE_END", "/agent/ACK", "/ground/CMD_START", "/ground/PARAM_SET",
                  "/raw/rx", "/raw/tx", "/event", "/marker"):
        assert counts.get(topic), topic
    contents = read_recording(path, {"/marker", "/agent/PARAM_VALUE"})
    assert [m.json()["text"] for m in contents.messages if m.topic == "/marker"] == ["first progress"]
    # the LOG_REQUEST ranges replayed samples (and episode frames) already held between their holes: unused by the
    # session, but their raw frames kept, so /raw/rx and /raw/rx_unused hold every frame whose seq was counted
    with path.open("rb") as f:
        unused = [message.data for _, _, message in make_reader(f).iter_messages(topics=[RAW_RX_UNUSED_TOPIC])]
    replays = {m.Sample.MSG_ID, m.EpisodeStart.MSG_ID, m.EpisodeEnd.MSG_ID}
    assert unused and all(d[4] in replays and d[1] & FrameFlag.REPLAYED for d in unused), {(d[4], d[1]) for d in unused}
    assert contents.metadata["parameters"][-1]["target_depth_m"] == "0.6"
    summary = summarize(path)
    assert summary.complete and summary.samples_missing == 0 and summary.samples_backfilled > 0
    assert len(summary.episodes) >= 4 and {e.outcome for e in summary.episodes} == {"success", "failure"}

    rows = export_csv(path, tmp_path / "s.csv")
    assert rows == summary.samples
    transitions = export_npz(path, tmp_path / "d.npz")
    data = np.load(tmp_path / "d.npz")
    assert len(data["state"]) == transitions > 0
    assert set(data.files) >= {"state", "action", "reward", "next_state", "terminated", "truncated", "episode"}
    assert data["terminated"].sum() + data["truncated"].sum() == len(set(data["episode"].tolist()))


def test_truncated_recording_is_readable_and_recoverable(tmp_path: Path, fake_agent: FakeAgent) -> None:
    result = run(RunConfig(url=fake_agent.url, episodes=2, recorder=RecorderConfig(directory=tmp_path)))
    whole = result.paths[0]
    cut = tmp_path / "cut.mcap"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    assert not is_complete(cut)
    partial = summarize(cut)
    assert not partial.complete and partial.samples > 0
    fixed = tmp_path / "fixed.mcap"
    count, truncated = recover(cut, fixed)
    assert truncated and count == partial.messages
    assert is_complete(fixed)
    counts = validate_with_mcap_library(fixed)
    assert counts["/agent/SAMPLE"] == partial.samples
    shutil.copy(whole, tmp_path / "copy.mcap")
    assert recover(tmp_path / "copy.mcap", tmp_path / "again.mcap")[1] is False
