"""A real live run against the virtual agent: the view's .rrd and the replay of the recorder's MCAP agree."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from mcap.reader import make_reader
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.links import make_link
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.agent_session import Session
from groundstation.session.events import Received
from groundstation.view.rerun_sink import RerunView, ViewConfig
from protocol import DumpKind
from protocol import messages as m
from tests.groundstation.rrd_readback import rows_per_entity

EPISODES = 3


def _learn(directory: Path) -> tuple[Path, Path]:
    """`dive run --rrd` in miniature: recorder and view on one session while the agent learns a few episodes."""
    ended = threading.Event()
    episodes: list[int] = []
    policies: list[int] = []  # the POLICY dump follows VALUES after each EPISODE_END: wait for the last one too

    def watch(received: Received) -> None:
        message = received.message
        if isinstance(message, m.EpisodeEnd):
            episodes.append(message.episode)
        elif (isinstance(message, m.DumpChunk) and message.kind == DumpKind.POLICY
              and message.offset + len(message.data) >= message.total_bytes):
            policies.append(message.episode)
        if len(episodes) >= EPISODES and len(policies) >= EPISODES:
            ended.set()

    recorder = Recorder(RecorderConfig(path=directory / "run.mcap"))
    try:
        with RerunView.open(ViewConfig(rrd=directory / "live.rrd")) as view:
            with Session(make_link("sim://?speed=max&seed=3"), listeners=[recorder, view]) as session:
                session.add_listener(session.rx_listener(watch))
                session.set_param("dump_each_episode", 1)
                session.command(m.StartLearning(max_episodes=EPISODES))
                assert ended.wait(120), f"only {len(episodes)} episodes, {len(policies)} policies"
    finally:
        recorder.close()
    return directory / "run.mcap", directory / "live.rrd"


@pytest.mark.slow
def test_a_live_run_and_its_replay_show_the_same_rows(tmp_path: Path) -> None:
    recording, live_rrd = _learn(tmp_path)
    result = CliRunner().invoke(app, ["replay", str(recording), "--rrd", str(tmp_path / "replay.rrd")])
    assert result.exit_code == 0, result.output

    with recording.open("rb") as stream:
        samples = sum(1 for _s, _c, msg in make_reader(stream).iter_messages(topics=["/raw/rx"]) if msg.data[4] == 0x20)
    live, replayed = rows_per_entity(live_rrd), rows_per_entity(tmp_path / "replay.rrd")
    assert set(live) == set(replayed)
    assert replayed["/depth/z_up_m"] == samples > 0
    assert live["/depth/z_up_m"] == samples
    assert replayed["/learning_curve/duration_s"] >= EPISODES
    assert replayed["/value_function/image"] >= EPISODES and replayed["/policy/image"] >= EPISODES
